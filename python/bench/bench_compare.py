#!/usr/bin/env python3
"""Times rephoto.compare on 4000x3000 arrays against the CLI's per-pair function.

Usage: PYTHONPATH=build/python /usr/bin/python3 python/bench/bench_compare.py [repeats]
The CLI figure is compare::ComparePhotoAndRender on already decoded images (the CLI's
in-memory metric time, no file I/O, no error images), timed in C++ by
rephoto._rephoto._cli_pair_seconds; the Python figure includes converting the arrays.
Both take the minimum over `repeats` calls (workspace buffers reused in both).
"""
import sys
import time

import numpy as np

import rephoto
from rephoto import _rephoto

repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 3
rng = np.random.default_rng(0)
h, w = 3000, 4000
y, x = np.mgrid[0:h, 0:w].astype(np.float32)
base = np.stack([np.sin(x / 37), np.cos(y / 23), np.sin((x + y) / 51)], axis=2)
photo = np.clip(127 + 100 * base + rng.normal(0, 8, base.shape), 1, 254).astype(np.uint8)
render = np.clip(photo + rng.normal(0, 10, base.shape), 0, 255).astype(np.uint8)
inputs = {
    "uint8 RGB": (photo, render),
    "float32 RGB": (photo.astype(np.float32) / 255, render.astype(np.float32) / 255),
}
for metrics in (None, ["psnr", "ssim"]):
    label = "all metrics" if metrics is None else ",".join(metrics)
    for kind, (p, r) in inputs.items():
        cli = _rephoto._cli_pair_seconds(p, r, metrics, repeats)
        best = 1e300
        for _ in range(repeats):
            start = time.perf_counter()
            rephoto.compare(p, r, metrics=metrics)
            best = min(best, time.perf_counter() - start)
        print(f"{label:<14} {kind:<12} CLI in-memory {cli:7.3f} s   Python {best:7.3f} s   "
              f"overhead {100 * (best / cli - 1):+5.1f} %", flush=True)
