"""Independent numpy re-implementation of the 3DGS forward pass (graphdeco-inria
diff-gaussian-rasterization, cuda_rasterizer/forward.cu + auxiliary.h), with a full pinhole K.

Written from the CUDA code's steps, not from rephoto's C++: float32 throughout as on the GPU,
every Gaussian of a tile evaluated at every pixel of that tile (no work-saving shortcuts), tiles
of 16x16, getRect's truncating integer conversion, a stable depth sort per tile.

Conventions: pixel x's centre is at x + 0.5 in rephoto's corner convention; the CUDA code uses
integer pixel coordinates (centre at x), so the projected mean in its coordinates is
fx * X / Z + cx - 0.5. The Jacobian clamp is gsplat's generalisation of the reference's
1.3 * tan(half fov) to an off-centre principal point (identical when cx = width / 2).

Gaussians are given activated: positions (N,3), scales (N,3) standard deviations, rotations
(N,4) unit quaternions (w,x,y,z), opacities (N,), sh (N,K,3) coefficient-major.
"""
import numpy as np

F = np.float32
SH_C0 = F(0.28209479177387814)
SH_C1 = F(0.4886025119029199)
SH_C2 = [F(1.0925484305920792), F(-1.0925484305920792), F(0.31539156525252005),
         F(-1.0925484305920792), F(0.5462742152960396)]
SH_C3 = [F(-0.5900435899266435), F(2.890611442640554), F(-0.4570457994644658),
         F(0.3731763325901154), F(-0.4570457994644658), F(1.445305721320277),
         F(-0.5900435899266435)]
BLOCK = 16


def sh_to_color(sh, degree, dirs):
    """computeColorFromSH: sh (N,K,3), dirs (N,3) unit vectors camera centre -> mean."""
    result = SH_C0 * sh[:, 0]
    if degree > 0:
        x, y, z = dirs[:, 0:1], dirs[:, 1:2], dirs[:, 2:3]
        result = result - SH_C1 * y * sh[:, 1] + SH_C1 * z * sh[:, 2] - SH_C1 * x * sh[:, 3]
        if degree > 1:
            xx, yy, zz = x * x, y * y, z * z
            xy, yz, xz = x * y, y * z, x * z
            result = (result + SH_C2[0] * xy * sh[:, 4] + SH_C2[1] * yz * sh[:, 5] +
                      SH_C2[2] * (F(2) * zz - xx - yy) * sh[:, 6] + SH_C2[3] * xz * sh[:, 7] +
                      SH_C2[4] * (xx - yy) * sh[:, 8])
            if degree > 2:
                result = (result + SH_C3[0] * y * (F(3) * xx - yy) * sh[:, 9] +
                          SH_C3[1] * xy * z * sh[:, 10] +
                          SH_C3[2] * y * (F(4) * zz - xx - yy) * sh[:, 11] +
                          SH_C3[3] * z * (F(2) * zz - F(3) * xx - F(3) * yy) * sh[:, 12] +
                          SH_C3[4] * x * (F(4) * zz - xx - yy) * sh[:, 13] +
                          SH_C3[5] * z * (xx - yy) * sh[:, 14] +
                          SH_C3[6] * x * (xx - F(3) * yy) * sh[:, 15])
    return np.maximum(result + F(0.5), F(0))


def quaternion_to_matrix(q):
    r, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    m = np.empty((q.shape[0], 3, 3), F)
    m[:, 0, 0] = F(1) - F(2) * (y * y + z * z)
    m[:, 0, 1] = F(2) * (x * y - r * z)
    m[:, 0, 2] = F(2) * (x * z + r * y)
    m[:, 1, 0] = F(2) * (x * y + r * z)
    m[:, 1, 1] = F(1) - F(2) * (x * x + z * z)
    m[:, 1, 2] = F(2) * (y * z - r * x)
    m[:, 2, 0] = F(2) * (x * z - r * y)
    m[:, 2, 1] = F(2) * (y * z + r * x)
    m[:, 2, 2] = F(1) - F(2) * (x * x + y * y)
    return m


def render(g, cam, background=(0, 0, 0), antialiased=False):
    """Returns (rgba (H,W,4) float32 with RGB composited over background and A = 1 - T,
    depth (H,W) expected view z, NaN where nothing was blended)."""
    W, H = cam["width"], cam["height"]
    fx, fy, cx, cy = (F(cam[k]) for k in ("fx", "fy", "cx", "cy"))
    R = np.asarray(cam["R"], F).reshape(3, 3)
    t = np.asarray(cam["t"], F)
    pos = g["positions"].astype(F)
    n = pos.shape[0]
    p_view = pos @ R.T + t
    in_frustum = p_view[:, 2] > F(0.2)

    rot = quaternion_to_matrix(g["rotations"].astype(F))
    s = g["scales"].astype(F)
    m = rot * s[:, None, :]
    sigma = m @ np.transpose(m, (0, 2, 1))

    tz = p_view[:, 2]
    tan_x, tan_y = F(0.5) * F(W) / fx, F(0.5) * F(H) / fy
    lim_x_pos, lim_x_neg = (F(W) - cx) / fx + F(0.3) * tan_x, cx / fx + F(0.3) * tan_x
    lim_y_pos, lim_y_neg = (F(H) - cy) / fy + F(0.3) * tan_y, cy / fy + F(0.3) * tan_y
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        tx = np.minimum(lim_x_pos, np.maximum(-lim_x_neg, p_view[:, 0] / tz)) * tz
        ty = np.minimum(lim_y_pos, np.maximum(-lim_y_neg, p_view[:, 1] / tz)) * tz
        J = np.zeros((n, 2, 3), F)
        J[:, 0, 0] = fx / tz
        J[:, 0, 2] = -(fx * tx) / (tz * tz)
        J[:, 1, 1] = fy / tz
        J[:, 1, 2] = -(fy * ty) / (tz * tz)
        T = J @ R
        cov = T @ sigma @ np.transpose(T, (0, 2, 1))
        a0, b, c0 = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
        a, c = a0 + F(0.3), c0 + F(0.3)
        det = a * c - b * b
        opacity = g["opacities"].astype(F).copy()
        if antialiased:
            det_orig = a0 * c0 - b * b
            opacity = opacity * np.sqrt(np.maximum(F(0), det_orig / det))
        det_inv = F(1) / det
        conic = np.stack([c * det_inv, -b * det_inv, a * det_inv], 1)
        mid = F(0.5) * (a + c)
        l1 = mid + np.sqrt(np.maximum(F(0.1), mid * mid - det))
        l2 = mid - np.sqrt(np.maximum(F(0.1), mid * mid - det))
        radius = np.ceil(F(3) * np.sqrt(np.maximum(l1, l2)))
        px = fx * p_view[:, 0] / tz + cx - F(0.5)
        py = fy * p_view[:, 1] / tz + cy - F(0.5)
    grid_x, grid_y = (W + BLOCK - 1) // BLOCK, (H + BLOCK - 1) // BLOCK

    def bound(v, grid):  # min(grid, max(0, (int)v))
        v = np.where(np.isfinite(v), v, 0)
        return np.clip(np.trunc(np.clip(v, -1, grid + 1)), 0, grid).astype(np.int64)

    rx0, ry0 = bound((px - radius) / F(BLOCK), grid_x), bound((py - radius) / F(BLOCK), grid_y)
    rx1 = bound((px + radius + F(BLOCK - 1)) / F(BLOCK), grid_x)
    ry1 = bound((py + radius + F(BLOCK - 1)) / F(BLOCK), grid_y)
    keep = in_frustum & (det != 0) & ((rx1 - rx0) * (ry1 - ry0) != 0)

    cam_center = -R.T @ t
    dirs = pos - cam_center
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    colors = sh_to_color(g["sh"].astype(F), g["sh_degree"], dirs)

    rgba = np.zeros((H, W, 4), F)
    depth = np.full((H, W), np.nan, F)
    bg = np.asarray(background, F)
    idx = np.nonzero(keep)[0]
    order = idx[np.lexsort((idx, tz[idx]))]  # by depth, ties by index (stable radix sort)
    for ty_ in range(grid_y):
        for tx_ in range(grid_x):
            sel = order[(rx0[order] <= tx_) & (tx_ < rx1[order]) & (ry0[order] <= ty_) &
                        (ty_ < ry1[order])]
            xs = np.arange(tx_ * BLOCK, min(W, (tx_ + 1) * BLOCK))
            ys = np.arange(ty_ * BLOCK, min(H, (ty_ + 1) * BLOCK))
            pix_x, pix_y = np.meshgrid(xs.astype(F), ys.astype(F))
            pix_x, pix_y = pix_x.ravel(), pix_y.ravel()
            Tm = np.ones(pix_x.size, F)
            C = np.zeros((pix_x.size, 3), F)
            D = np.zeros(pix_x.size, F)
            done = np.zeros(pix_x.size, bool)
            for gi in sel:
                dx, dy = px[gi] - pix_x, py[gi] - pix_y
                A, B, Cc = conic[gi]
                power = F(-0.5) * (A * dx * dx + Cc * dy * dy) - B * dx * dy
                with np.errstate(over="ignore"):
                    alpha = np.minimum(F(0.99), opacity[gi] * np.exp(power))
                valid = (~done) & (power <= 0) & (alpha >= F(1) / F(255))
                test_T = Tm * (F(1) - alpha)
                stop = valid & (test_T < F(0.0001))
                done |= stop
                upd = valid & ~stop
                w = alpha * Tm
                C[upd] += colors[gi][None, :] * w[upd, None]
                D[upd] += tz[gi] * w[upd]
                Tm = np.where(upd, test_T, Tm)
            out = np.concatenate([C + Tm[:, None] * bg[None, :], (F(1) - Tm)[:, None]], 1)
            rgba[ys[0]:ys[-1] + 1, xs[0]:xs[-1] + 1] = out.reshape(len(ys), len(xs), 4)
            with np.errstate(divide="ignore", invalid="ignore"):
                d = np.where(Tm < 1, D / (F(1) - Tm), np.nan).astype(F)
            depth[ys[0]:ys[-1] + 1, xs[0]:xs[-1] + 1] = d.reshape(len(ys), len(xs))
    return rgba, depth
