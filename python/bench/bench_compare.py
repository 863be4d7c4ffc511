#!/usr/bin/env python3
"""Times rephoto.compare on 4000x3000 arrays against the CLI's per-pair function.

Usage: PYTHONPATH=build/python /usr/bin/python3 python/bench/bench_compare.py [repeats] [rounds]

What is measured, in one process, threads = the library's default (all cores):
- "CLI": compare::CompareInMemory, the function `rephoto compare` runs per pair
  (ComparePhotoAndRender is it with file paths), on the arrays as the CLI's decoder holds them
  (uint8 as 8-bit samples, as JPEG / 8-bit PNG are kept; float32 as floats, as EXR/PFM), no
  error images, workspace reused as between pairs; timed in C++ by
  rephoto._rephoto._cli_pair_seconds (median of `repeats` calls, decoding outside the timing).
- "Python": rephoto.compare(photo, render, metrics=...) on the same numpy arrays, median of
  `repeats` calls timed with perf_counter around the Python call: argument checks, the one copy
  into the library's image type (the only copy), the same C++ function, the result dict.
- "copy": that copy alone for both arrays (rephoto._rephoto._decode_seconds, median, into a
  reused buffer as rephoto.compare does), a figure that the machine's load blurs less.
Both are repeated in `rounds` alternating blocks (others use the CPUs too); the overhead is
the ratio of the medians over all calls of each. Arrays: C-contiguous H x W x 3, a smooth
pattern plus noise (no ill-exposed pixel), the render a noisy copy.
"""
import statistics
import sys
import time

import numpy as np

import rephoto
from rephoto import _rephoto

repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 5
rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 2
rng = np.random.default_rng(0)
h, w = 3000, 4000
y, x = np.mgrid[0:h, 0:w].astype(np.float32)
base = np.stack([np.sin(x / 37), np.cos(y / 23), np.sin((x + y) / 51)], axis=2)
photo = np.clip(127 + 100 * base + rng.normal(0, 8, base.shape), 1, 254).astype(np.uint8)
render = np.clip(photo + rng.normal(0, 10, base.shape), 0, 255).astype(np.uint8)
del x, y, base
inputs = {
    "uint8 RGB": (photo, render),
    "float32 RGB": (photo.astype(np.float32) / 255, render.astype(np.float32) / 255),
}
print(f"{h}x{w}, repeats {repeats} x rounds {rounds}, rephoto {rephoto.__version__}", flush=True)
for metrics in (None, ["psnr", "ssim"]):
    label = "all metrics" if metrics is None else ",".join(metrics)
    for kind, (p, r) in inputs.items():
        rephoto.compare(p, r, metrics=metrics)  # warm the thread's buffers
        cli, python = [], []
        for _ in range(rounds):
            # _cli_pair_seconds returns the median of its repeats; weight it as `repeats` calls.
            cli += [_rephoto._cli_pair_seconds(p, r, metrics, repeats)] * repeats
            for _ in range(repeats):
                start = time.perf_counter()
                rephoto.compare(p, r, metrics=metrics)
                python.append(time.perf_counter() - start)
        c, py = statistics.median(cli), statistics.median(python)
        copy = _rephoto._decode_seconds(p, repeats) + _rephoto._decode_seconds(r, repeats)
        print(f"{label:<14} {kind:<12} CLI in-memory {c:7.3f} s   Python {py:7.3f} s   "
              f"overhead {100 * (py / c - 1):+5.1f} %   (the copy of both arrays "
              f"{1000 * copy:5.1f} ms = {100 * copy / c:4.1f} % of the CLI time)", flush=True)
