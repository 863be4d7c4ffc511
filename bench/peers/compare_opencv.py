#!/usr/bin/python3
"""OpenCV-composed peer of `rephoto compare` for one photo/rendering pair (benchmark only).

Does the same work as `rephoto compare --metrics 1-ncc,cb+cr,zssd,dssim,census,psnr
--no-error-images` on one pair, the way one would compose it from OpenCV and numpy: decode both
files, validity (rendering alpha > 0, photo not clipped), window validity by erosion, 1-NCC and
ZSSD from box filters (float64), Cb+Cr, DSSIM from 11x11 Gaussian filters (sigma 1.5, float32),
9x9 census on luma (numpy shifts), PSNR; masked means. Values agree with rephoto's to about
1e-5 (float32 filters), which is enough for a timing peer; it is not a reference.

Needs Debian's python3-opencv (apt-get install python3-opencv; not a test dependency).
Usage: /usr/bin/python3 bench/peers/compare_opencv.py PHOTO RENDER [--threads N]
"""
import sys
import time

import cv2
import numpy as np


def main():
    args = sys.argv[1:]
    threads = 1
    if "--threads" in args:
        i = args.index("--threads")
        threads = int(args[i + 1])
        del args[i:i + 2]
    cv2.setNumThreads(threads)
    photo_path, render_path = args
    t0 = time.perf_counter()
    photo = cv2.imread(photo_path, cv2.IMREAD_UNCHANGED)
    render = cv2.imread(render_path, cv2.IMREAD_UNCHANGED)
    photo_valid = np.ones(photo.shape[:2], np.uint8)
    if photo.shape[2] == 4:
        photo_valid &= photo[:, :, 3] > 0
    if render.shape[2] == 4:
        render_valid = (render[:, :, 3] > 0).astype(np.uint8)
    else:
        render_valid = (render.max(axis=2) > 0).astype(np.uint8)
    p = cv2.cvtColor(photo[:, :, :3], cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
    q = cv2.cvtColor(render[:, :, :3], cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
    # Photo exposure: invalid where any channel is 0 or 1.
    photo_valid &= ((p > 0.0) & (p < 1.0)).all(axis=2)
    valid = photo_valid & render_valid
    r = 4
    kernel = np.ones((9, 9), np.uint8)
    # Window validity: erosion with border = invalid.
    win_photo = cv2.erode(photo_valid, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    win_both = cv2.erode(valid, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    completeness = win_both.sum() / max(1, win_photo.sum())
    ok = win_both.astype(bool)
    results = {"completeness": completeness}

    # 1-NCC and ZSSD (RGB jointly, float64 box sums).
    pd = p.astype(np.float64)
    qd = q.astype(np.float64)
    n = 81.0
    box = lambda a: cv2.boxFilter(a, -1, (9, 9), normalize=False, borderType=cv2.BORDER_REFLECT)
    sx = box(pd)
    sy = box(qd)
    sxx = box((pd * pd).sum(axis=2))
    syy = box((qd * qd).sum(axis=2))
    sxy = box((pd * qd).sum(axis=2))
    dx = sxx - (sx * sx).sum(axis=2) / n
    dy = syy - (sy * sy).sum(axis=2) / n
    dxy = sxy - (sx * sy).sum(axis=2) / n
    with np.errstate(invalid="ignore", divide="ignore"):
        ncc = np.clip(1.0 - dxy / np.sqrt(dx * dy), 0.0, 2.0)
    flat_x, flat_y = dx <= 1e-6, dy <= 1e-6
    ncc = np.where(flat_x & flat_y, 0.0, np.where(flat_x | flat_y, 1.0, ncc))
    results["1-ncc"] = ncc[ok].mean()
    zssd = np.maximum(dx + dy - 2 * dxy, 0.0) / (3 * n)
    results["zssd"] = zssd[ok].mean()

    # Cb+Cr (full-range BT.601) at valid pixels.
    d = p - q
    dcb = -0.168736 * d[:, :, 0] - 0.331264 * d[:, :, 1] + 0.5 * d[:, :, 2]
    dcr = 0.5 * d[:, :, 0] - 0.418688 * d[:, :, 1] - 0.081312 * d[:, :, 2]
    vb = valid.astype(bool)
    results["cb+cr"] = (np.abs(dcb) + np.abs(dcr))[vb].mean()
    # PSNR of the masked MSE.
    mse = (d * d).mean(axis=2)[vb].astype(np.float64).mean()
    results["psnr"] = 10 * np.log10(1.0 / mse) if mse > 0 else float("inf")

    # DSSIM: 11x11 Gaussian, sigma 1.5, per channel.
    g = lambda a: cv2.GaussianBlur(a, (11, 11), 1.5, borderType=cv2.BORDER_REFLECT)
    ux, uy = g(p), g(q)
    vx = g(p * p) - ux * ux
    vy = g(q * q) - uy * uy
    vxy = g(p * q) - ux * uy
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    ssim = ((2 * ux * uy + c1) * (2 * vxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))
    dssim = (1 - ssim.mean(axis=2)) / 2
    ok11 = cv2.erode(valid, np.ones((11, 11), np.uint8), borderType=cv2.BORDER_CONSTANT,
                     borderValue=0).astype(bool)
    results["dssim"] = dssim[ok11].astype(np.float64).mean()

    # Census 9x9 on luma.
    yp = 0.299 * p[:, :, 0] + 0.587 * p[:, :, 1] + 0.114 * p[:, :, 2]
    yq = 0.299 * q[:, :, 0] + 0.587 * q[:, :, 1] + 0.114 * q[:, :, 2]
    h, w = yp.shape
    counts = np.zeros((h - 2 * r, w - 2 * r), np.uint8)
    cp, cq = yp[r:h - r, r:w - r], yq[r:h - r, r:w - r]
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            if dy == 0 and dx == 0:
                continue
            np_ = yp[r + dy:h - r + dy, r + dx:w - r + dx]
            nq = yq[r + dy:h - r + dy, r + dx:w - r + dx]
            counts += (np_ < cp) != (nq < cq)
    census = counts.astype(np.float32) / 80.0
    results["census"] = census[ok[r:h - r, r:w - r]].astype(np.float64).mean()
    elapsed = time.perf_counter() - t0
    print(" ".join(f"{k}={v:.6g}" for k, v in results.items()), f"wall={elapsed:.3f}s")


if __name__ == "__main__":
    main()
