#!/usr/bin/python3
"""PyTorch's CPU time for LPIPS (the lpips package's v0.1 net-lin forward, spatial=False, the
same computation as lpips.LPIPS(net=...)(a, b, normalize=True)) on the sizes of
bench/bench_lpips.cc, with the weights of DIR (torch.load of the same files rephoto reads).

Usage: lpips_torch.py DIR NET WIDTH HEIGHT TURNS [THREADS]
Prints one line per turn: "<wall seconds> <process CPU seconds>", after one warm-up call.
The forward pass is lpips_reference.py's (torch.nn.functional conv2d/relu/max_pool2d, which
run on the same oneDNN build that torchvision's modules use)."""
import os
import sys
import time

import numpy as np
import torch

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "src",
                                "rephoto", "lpips"))
import lpips_reference as ref  # noqa: E402

directory, net, width, height, turns = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(
    sys.argv[4]), int(sys.argv[5])
torch.set_num_threads(int(sys.argv[6]) if len(sys.argv) > 6 else 2)
lin_file, backbone_file = ref.FILES[net]
sd = torch.load(os.path.join(directory, backbone_file))
lin = torch.load(os.path.join(directory, lin_file))

y, x = np.mgrid[0:height, 0:width].astype(np.float32)
a = np.stack([0.5 + 0.4 * np.sin(0.01 * (x + 2 * c) + 0.013 * y) for c in range(3)])[None]
rng = np.random.default_rng(30)
b = np.clip(a + rng.uniform(-0.05, 0.05, a.shape).astype(np.float32), 0, 1)
ta, tb = torch.from_numpy(a.astype(np.float32)), torch.from_numpy(b.astype(np.float32))


def lpips_whole(a, b):
    fa = ref.features(((2 * a - 1) - ref.SHIFT) / ref.SCALE, sd, net)
    fb = ref.features(((2 * b - 1) - ref.SHIFT) / ref.SCALE, sd, net)
    val = 0
    for k, (p, q) in enumerate(zip(fa, fb)):
        npp = p / (torch.sqrt(torch.sum(p ** 2, dim=1, keepdim=True)) + 1e-10)
        nq = q / (torch.sqrt(torch.sum(q ** 2, dim=1, keepdim=True)) + 1e-10)
        val = val + torch.nn.functional.conv2d((npp - nq) ** 2, lin[f"lin{k}.model.1.weight"]).mean(
            dim=[2, 3], keepdim=True)
    return float(val.flatten()[0])


with torch.no_grad():
    lpips_whole(ta, tb)
    for _ in range(turns):
        w0, c0 = time.perf_counter(), time.process_time()
        lpips_whole(ta, tb)
        print(f"{time.perf_counter() - w0:.4f} {time.process_time() - c0:.4f}", flush=True)
