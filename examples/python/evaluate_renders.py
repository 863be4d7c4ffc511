#!/usr/bin/env python3
"""Evaluate a folder of renderings against their photos with rephoto, notebook style.

Usage: python evaluate_renders.py PHOTOS RENDERS [--compat 3dgs|nerfstudio] [--plot errors.png]

Pairs files by stem (a.jpg <-> a.png), compares each pair with rephoto.compare (the same
numbers as `rephoto compare`), prints a table and, when matplotlib is installed, plots the
per-image 1-NCC error and PSNR (or the compat preset's PSNR/SSIM).
"""
# %% Setup
import argparse
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from skimage import io

import rephoto

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("photos", type=Path)
parser.add_argument("renders", type=Path)
parser.add_argument("--compat", choices=["3dgs", "nerfstudio"])
parser.add_argument("--plot", type=Path, default=Path("per_image_error.png"))
args = parser.parse_args()

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".tif", ".tiff"}

# %% Pair photos and renderings by file stem
photos = {p.stem: p for p in sorted(args.photos.iterdir()) if p.suffix.lower() in IMAGE_SUFFIXES}
renders = {p.stem: p for p in sorted(args.renders.iterdir()) if p.suffix.lower() in IMAGE_SUFFIXES}
names = sorted(photos.keys() & renders.keys())
for missing in sorted(photos.keys() ^ renders.keys()):
    print(f"no counterpart for {missing}")
if not names:
    raise SystemExit("no pairs")

# %% Compare (threads overlap decoding with rephoto's work: the GIL is released inside)
def compare(name):
    photo, render = io.imread(photos[name]), io.imread(renders[name])
    return rephoto.compare(photo, render, compat=args.compat)

with ThreadPoolExecutor(2) as pool:
    results = dict(zip(names, pool.map(compare, names)))

# %% Table
columns = ["psnr", "ssim"] if args.compat else ["1-ncc", "psnr", "ssim"]
print(f"{'name':<24}{'completeness':>14}" + "".join(f"{c:>10}" for c in columns))
for name, r in results.items():
    print(f"{name:<24}{r['completeness']:>14.4f}" + "".join(f"{r[c]:>10.4f}" for c in columns))
print(f"{'mean':<24}{np.nanmean([r['completeness'] for r in results.values()]):>14.4f}" +
      "".join(f"{np.nanmean([r[c] for r in results.values()]):>10.4f}" for c in columns))

# %% Plot the per-image error (optional: matplotlib)
try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib is not installed: no plot")
else:
    fig, axes = plt.subplots(len(columns), 1, figsize=(max(6, len(names) * 0.4), 2.5 * len(columns)),
                             sharex=True)
    for ax, column in zip(np.atleast_1d(axes), columns):
        ax.bar(range(len(names)), [results[n][column] for n in names])
        ax.set_ylabel(column)
    np.atleast_1d(axes)[-1].set_xticks(range(len(names)), names, rotation=90)
    fig.tight_layout()
    fig.savefig(args.plot, dpi=120)
    print(f"plot in {args.plot}")
