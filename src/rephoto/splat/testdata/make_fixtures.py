#!/usr/bin/env python3
"""Makes the Gaussian-splatting test fixtures of src/rephoto/splat (run by rasterize_test and
gaussians_test at test time; numpy only).

    python3 make_fixtures.py --out DIR [--seed S]

Writes to DIR, for each scene k (see SCENES below: SH degree 0-3, normals present and absent,
an extra property, unnormalised quaternions, off-centre principal points, a background colour,
the antialiased mode, Mip-Splatting's filter_3D, splatfacto's colour-only export):
  scene_k.ply          the Gaussians in the Inria layout (binary little endian)
  scene_k.json         camera (width, height, fx, fy, cx, cy, R, t = cam_from_world, row-major),
                       background, antialiased
  scene_k.rgba.f32     reference image of reference_rasterizer.render: H x W x 4 float32 little
                       endian (RGB composited over the background, A = 1 - T)
  scene_k.depth.f32    reference expected depth: H x W float32 (NaN = empty)
and, made from scene_3.ply's Gaussians (SH degree 3, 600 Gaussians = 3 chunks):
  scene_3.compressed.ply  SuperSplat/PlayCanvas compressed PLY, encoded as splat-transform does
                          (chunks of 256 in file order, 11-10-11 positions and log scales in the
                          chunk box, 2-10-10-10 quaternion, 8-8-8-8 colour in the chunk colour
                          range and opacity, uchar SH trunc((f / 8 + 0.5) * 256))
  scene_3.splat           antimatter15 .splat (32 bytes per Gaussian)
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import reference_rasterizer as ref  # noqa: E402

C0 = 0.28209479177387814

# (sh_degree, count, normals, extra property, off-centre pp, unnormalised quaternions,
#  background, antialiased, filter_3D, colour-only)
SCENES = [
    dict(degree=0, count=300, normals=True, extra=False, offcentre=False, unnormalised=False,
         background=(0, 0, 0), antialiased=False, filter3d=False, color_only=False),
    dict(degree=1, count=400, normals=False, extra=False, offcentre=True, unnormalised=True,
         background=(1, 1, 1), antialiased=False, filter3d=False, color_only=False),
    dict(degree=2, count=400, normals=True, extra=True, offcentre=True, unnormalised=True,
         background=(0.2, 0.4, 0.6), antialiased=True, filter3d=False, color_only=False),
    dict(degree=3, count=600, normals=False, extra=False, offcentre=True, unnormalised=True,
         background=(0, 0, 0), antialiased=False, filter3d=False, color_only=False),
    dict(degree=3, count=300, normals=True, extra=False, offcentre=True, unnormalised=True,
         background=(0, 0, 0), antialiased=False, filter3d=True, color_only=False),
    dict(degree=0, count=300, normals=True, extra=False, offcentre=True, unnormalised=True,
         background=(0, 0, 0), antialiased=False, filter3d=False, color_only=True),
]


def random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def make_scene(rng, spec):
    width, height = 120, 90
    fx, fy = 110.0 * rng.uniform(0.9, 1.1), 105.0 * rng.uniform(0.9, 1.1)
    cx, cy = width / 2, height / 2
    if spec["offcentre"]:
        cx += rng.uniform(-12, 12)
        cy += rng.uniform(-9, 9)
    R = random_rotation(rng)
    t = rng.normal(size=3)
    n = spec["count"]
    z = rng.uniform(0.8, 6.0, n)
    # Mostly inside the view, some far outside it (the Jacobian clamp), some near or behind
    # the camera (the near cull).
    spread = rng.uniform(0.7, 1.8, n)
    xc = (rng.uniform(0, width, n) - cx) / fx * z * spread
    yc = (rng.uniform(0, height, n) - cy) / fy * z * spread
    z[: n // 20] = rng.uniform(-1.0, 0.4, n // 20)
    cam_points = np.stack([xc, yc, z], 1)
    positions = (cam_points - t) @ R  # R^T (p - t), row vectors
    log_scales = rng.uniform(np.log(0.004), np.log(0.25), (n, 3))
    quats = rng.normal(size=(n, 4))
    if spec["unnormalised"]:
        quats *= rng.uniform(0.2, 3.0, (n, 1))
    else:
        quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    logits = rng.uniform(-3.0, 4.0, n)
    k = (spec["degree"] + 1) ** 2
    f_dc = rng.normal(0, 1.0, (n, 3))
    f_rest = rng.normal(0, 0.3, (n, 3, k - 1))  # channel-major, as the Inria layout
    camera = dict(width=width, height=height, fx=fx, fy=fy, cx=cx, cy=cy,
                  R=R.ravel().tolist(), t=t.tolist(),
                  background=list(spec["background"]), antialiased=spec["antialiased"])
    data = dict(positions=positions, log_scales=log_scales, quats=quats, logits=logits,
                f_dc=f_dc, f_rest=f_rest, degree=spec["degree"])
    if spec["filter3d"]:
        data["filter_3D"] = rng.uniform(0.0, 0.05, n)
    if spec["color_only"]:
        data["rgb8"] = rng.integers(0, 256, (n, 3)).astype(np.uint8)
    return camera, data


def activated(data, spec):
    """The Gaussians as the rasterizer takes them (float32), from the file's values."""
    f32 = np.float32
    scales = np.exp(data["log_scales"])
    opac = 1.0 / (1.0 + np.exp(-data["logits"]))
    if "filter_3D" in data:  # Mip-Splatting get_scaling/opacity_with_3D_filter
        sq = scales ** 2
        filt = sq + data["filter_3D"][:, None] ** 2
        opac = opac * np.sqrt(np.prod(sq, 1) / np.prod(filt, 1))
        scales = np.sqrt(filt)
    q = data["quats"].astype(f32)
    q = q / np.maximum(np.linalg.norm(q, axis=1, keepdims=True), f32(1e-12))
    n = q.shape[0]
    k = (data["degree"] + 1) ** 2
    sh = np.zeros((n, k, 3))
    if "rgb8" in data:
        sh[:, 0, :] = (data["rgb8"] / 255.0 - 0.5) / C0
    else:
        sh[:, 0, :] = data["f_dc"]
        sh[:, 1:, :] = np.transpose(data["f_rest"], (0, 2, 1))
    return dict(positions=data["positions"].astype(f32), scales=scales.astype(f32),
                rotations=q, opacities=opac.astype(f32), sh=sh.astype(f32),
                sh_degree=data["degree"])


def write_ply(path, columns, n):
    """columns: list of (name, numpy dtype string, values (n,))."""
    header = ["ply", "format binary_little_endian 1.0", "comment made by make_fixtures.py",
              f"element vertex {n}"]
    names = {"f4": "float", "u1": "uchar", "u4": "uint", "f8": "double"}
    for name, dtype, _ in columns:
        header.append(f"property {names[dtype]} {name}")
    header.append("end_header")
    record = np.zeros(n, dtype=[(name, "<" + dtype) for name, dtype, _ in columns])
    for name, _, values in columns:
        record[name] = values
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode())
        f.write(record.tobytes())


def inria_columns(data, spec):
    n = data["positions"].shape[0]
    cols = [(a, "f4", data["positions"][:, i]) for i, a in enumerate("xyz")]
    if spec["normals"]:
        cols += [(a, "f4", np.zeros(n)) for a in ("nx", "ny", "nz")]
    if spec["color_only"]:
        cols += [(a, "u1", data["rgb8"][:, i]) for i, a in enumerate(("red", "green", "blue"))]
    else:
        cols += [(f"f_dc_{i}", "f4", data["f_dc"][:, i]) for i in range(3)]
        rest = data["f_rest"].reshape(n, -1)
        cols += [(f"f_rest_{i}", "f4", rest[:, i]) for i in range(rest.shape[1])]
    cols.append(("opacity", "f4", data["logits"]))
    cols += [(f"scale_{i}", "f4", data["log_scales"][:, i]) for i in range(3)]
    cols += [(f"rot_{i}", "f4", data["quats"][:, i]) for i in range(4)]
    if "filter_3D" in data:
        cols.append(("filter_3D", "f4", data["filter_3D"]))
    if spec["extra"]:
        cols.append(("semantic_id", "f4", np.arange(n, dtype=np.float32)))
    return cols


def pack_unorm(v, bits):
    t = (1 << bits) - 1
    return np.clip(np.floor(np.clip(v, 0, 1) * t + 0.5), 0, t).astype(np.uint32)


def write_compressed(path, data):
    """splat-transform's compressed PLY (chunks of 256 in file order)."""
    pos = data["positions"].astype(np.float32)
    ls = np.clip(data["log_scales"].astype(np.float32), -20, 20)
    q = data["quats"] / np.linalg.norm(data["quats"], axis=1, keepdims=True)
    color = (data["f_dc"] * C0 + 0.5).astype(np.float32)
    opac = 1.0 / (1.0 + np.exp(-data["logits"]))
    n = pos.shape[0]
    chunks = (n + 255) // 256
    chunk_rows = []
    packed = np.zeros((n, 4), np.uint32)
    for c in range(chunks):
        s = slice(c * 256, min(n, (c + 1) * 256))
        lo_p, hi_p = pos[s].min(0), pos[s].max(0)
        lo_s, hi_s = ls[s].min(0), ls[s].max(0)
        lo_c, hi_c = color[s].min(0), color[s].max(0)
        chunk_rows.append(np.concatenate([lo_p, hi_p, lo_s, hi_s, lo_c, hi_c]))

        def norm(v, lo, hi):
            return np.where(hi - lo > 0, (v - lo) / np.where(hi - lo > 0, hi - lo, 1), 0)

        p = norm(pos[s], lo_p, hi_p)
        packed[s, 0] = (pack_unorm(p[:, 0], 11) << 21) | (pack_unorm(p[:, 1], 10) << 11) | \
            pack_unorm(p[:, 2], 11)
        sc = norm(ls[s], lo_s, hi_s)
        packed[s, 2] = (pack_unorm(sc[:, 0], 11) << 21) | (pack_unorm(sc[:, 1], 10) << 11) | \
            pack_unorm(sc[:, 2], 11)
        col = norm(color[s], lo_c, hi_c)
        packed[s, 3] = (pack_unorm(col[:, 0], 8) << 24) | (pack_unorm(col[:, 1], 8) << 16) | \
            (pack_unorm(col[:, 2], 8) << 8) | pack_unorm(opac[s], 8)
        qs = q[s].copy()
        largest = np.argmax(np.abs(qs), 1)
        sign = np.sign(qs[np.arange(qs.shape[0]), largest])
        qs *= sign[:, None]
        word = largest.astype(np.uint32)
        others = np.array([[j for j in range(4) if j != l] for l in largest])
        for j in range(3):
            comp = qs[np.arange(qs.shape[0]), others[:, j]]
            word = (word << 10) | pack_unorm(comp * (np.sqrt(2) * 0.5) + 0.5, 10)
        packed[s, 1] = word
    chunk_names = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x",
                   "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z",
                   "min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
    rest = data["f_rest"].reshape(n, -1)
    sh_bytes = np.clip(np.trunc((rest / 8 + 0.5) * 256), 0, 255).astype(np.uint8)
    header = ["ply", "format binary_little_endian 1.0", "comment made by make_fixtures.py",
              f"element chunk {chunks}"]
    header += [f"property float {name}" for name in chunk_names]
    header += [f"element vertex {n}", "property uint packed_position",
               "property uint packed_rotation", "property uint packed_scale",
               "property uint packed_color", f"element sh {n}"]
    header += [f"property uchar f_rest_{i}" for i in range(rest.shape[1])]
    header.append("end_header")
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode())
        f.write(np.asarray(chunk_rows, "<f4").tobytes())
        f.write(packed.astype("<u4").tobytes())
        f.write(sh_bytes.tobytes())


def write_splat(path, data):
    """antimatter15's .splat: position, scale (linear), RGBA bytes, rotation bytes."""
    n = data["positions"].shape[0]
    rec = np.zeros(n, dtype=[("p", "<f4", 3), ("s", "<f4", 3), ("c", "u1", 4), ("r", "u1", 4)])
    rec["p"] = data["positions"]
    rec["s"] = np.exp(data["log_scales"])
    color = np.clip((0.5 + C0 * data["f_dc"]) * 255, 0, 255)
    alpha = np.clip(255 / (1 + np.exp(-data["logits"])), 0, 255)
    rec["c"] = np.concatenate([color, alpha[:, None]], 1).astype(np.uint8)
    q = data["quats"] / np.linalg.norm(data["quats"], axis=1, keepdims=True)
    rec["r"] = np.clip(q * 128 + 128, 0, 255).astype(np.uint8)
    with open(path, "wb") as f:
        f.write(rec.tobytes())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--seed", type=int, default=16)
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    for k, spec in enumerate(SCENES):
        camera, data = make_scene(rng, spec)
        n = data["positions"].shape[0]
        write_ply(os.path.join(args.out, f"scene_{k}.ply"), inria_columns(data, spec), n)
        with open(os.path.join(args.out, f"scene_{k}.json"), "w") as f:
            json.dump(camera, f, indent=1)
        rgba, depth = ref.render(activated(data, spec), camera, camera["background"],
                                 camera["antialiased"])
        rgba.astype("<f4").tofile(os.path.join(args.out, f"scene_{k}.rgba.f32"))
        depth.astype("<f4").tofile(os.path.join(args.out, f"scene_{k}.depth.f32"))
        if k == 3:
            write_compressed(os.path.join(args.out, f"scene_{k}.compressed.ply"), data)
            write_splat(os.path.join(args.out, f"scene_{k}.splat"), data)


if __name__ == "__main__":
    main()
