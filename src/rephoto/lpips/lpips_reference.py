#!/usr/bin/python3
"""Fixtures and reference values for rephoto's LPIPS tests (lpips_torch_test.cc, python tests).

Usage: lpips_reference.py DIR
  Writes into DIR, with Debian's python3-torch / python3-torchvision:
    - random-weight torchvision AlexNet and VGG16 state_dicts under torchvision's checkpoint
      names (alexnet-owt-7be5be79.pth, vgg16-397923af.pth) and random non-negative linear
      layers in the lpips package's layout (lin0.model.1.weight ... lin4) as alex.pth, vgg.pth;
      two of the four files in torch's legacy (non-zip) format, two in the zip format, so that
      both readers are exercised;
    - image pairs a_<i>.f32, b_<i>.f32 (raw float32, height x width x 3, values in [0, 1]) and
      masks m_<i>.u8 (raw uint8, height x width) of several sizes, odd ones included;
    - reference.json: per pair and net, the whole-image LPIPS and the mean of the spatial map
      over the mask, computed by the independent implementation below.
Exit status 77 when torch or torchvision cannot be imported (the test then skips).

The reference implementation is written from the lpips package's description of version 0.1
(lpips/lpips.py, pretrained_networks.py): normalize=True maps [0,1] to [-1,1] (2x - 1); the
ScalingLayer subtracts shift (-.030, -.088, -.188) and divides by scale (.458, .448, .450); the
torchvision "features" are cut into five slices ending at a ReLU; each tapped feature map is
unit-normalised over channels (x / (sqrt(sum x^2) + 1e-10)), the squared difference goes
through a 1x1 convolution without bias (the lin layer), and the spatial mean of each layer is
summed. spatial=True instead upsamples each layer's map bilinearly (align_corners=False) to the
input size and sums them. It uses torch.nn.functional directly, not the lpips package (which
Debian does not ship) and not torchvision's forward.
"""
import json
from collections import OrderedDict
import os
import sys

try:
    import numpy as np
    import torch
    import torch.nn.functional as F
    import torchvision
except Exception as e:  # noqa: BLE001
    print(f"python3-torch/python3-torchvision not usable: {e}", file=sys.stderr)
    sys.exit(77)

SHIFT = torch.tensor([-.030, -.088, -.188]).view(1, 3, 1, 1)
SCALE = torch.tensor([.458, .448, .450]).view(1, 3, 1, 1)

# (stage list) each stage: list of ("pool", k, s) or ("conv", features index, stride, pad)
ARCH = {
    "alex": [
        [("conv", 0, 4, 2)],
        [("pool", 3, 2), ("conv", 3, 1, 2)],
        [("pool", 3, 2), ("conv", 6, 1, 1)],
        [("conv", 8, 1, 1)],
        [("conv", 10, 1, 1)],
    ],
    "vgg": [
        [("conv", 0, 1, 1), ("conv", 2, 1, 1)],
        [("pool", 2, 2), ("conv", 5, 1, 1), ("conv", 7, 1, 1)],
        [("pool", 2, 2), ("conv", 10, 1, 1), ("conv", 12, 1, 1), ("conv", 14, 1, 1)],
        [("pool", 2, 2), ("conv", 17, 1, 1), ("conv", 19, 1, 1), ("conv", 21, 1, 1)],
        [("pool", 2, 2), ("conv", 24, 1, 1), ("conv", 26, 1, 1), ("conv", 28, 1, 1)],
    ],
}
FILES = {"alex": ("alex.pth", "alexnet-owt-7be5be79.pth"), "vgg": ("vgg.pth", "vgg16-397923af.pth")}


def features(x, sd, net):
    taps = []
    for stage in ARCH[net]:
        for op in stage:
            if op[0] == "pool":
                x = F.max_pool2d(x, kernel_size=op[1], stride=op[2])
            else:
                _, i, stride, pad = op
                x = F.relu(F.conv2d(x, sd[f"features.{i}.weight"], sd[f"features.{i}.bias"],
                                    stride=stride, padding=pad))
        taps.append(x)
    return taps


def lpips(a, b, sd, lin, net, mask=None):
    """a, b: 1x3xHxW in [0,1]. Returns (whole value, masked mean of the spatial map)."""
    h, w = a.shape[2:]
    fa = features(((2 * a - 1) - SHIFT) / SCALE, sd, net)
    fb = features(((2 * b - 1) - SHIFT) / SCALE, sd, net)
    whole = 0
    spatial = torch.zeros(1, 1, h, w)
    for k, (x, y) in enumerate(zip(fa, fb)):
        nx = x / (torch.sqrt(torch.sum(x ** 2, dim=1, keepdim=True)) + 1e-10)
        ny = y / (torch.sqrt(torch.sum(y ** 2, dim=1, keepdim=True)) + 1e-10)
        d = F.conv2d((nx - ny) ** 2, lin[f"lin{k}.model.1.weight"])
        whole = whole + d.mean(dim=[2, 3], keepdim=True)
        spatial = spatial + F.interpolate(d, size=(h, w), mode="bilinear", align_corners=False)
    m = torch.from_numpy(mask.astype(bool)) if mask is not None else torch.ones(h, w, dtype=bool)
    sel = spatial[0, 0][m]
    masked = float(sel.double().mean()) if sel.numel() > 0 else float("nan")
    return float(whole.flatten()[0]), masked


def smooth_image(rng, h, w):
    """A smooth random colour field plus fine noise, in [0, 1]."""
    coarse = rng.random((3, max(2, h // 16), max(2, w // 16))).astype(np.float32)
    img = F.interpolate(torch.from_numpy(coarse)[None], size=(h, w), mode="bicubic",
                        align_corners=False)[0].numpy()
    img += 0.05 * rng.standard_normal((3, h, w)).astype(np.float32)
    return np.clip(img.transpose(1, 2, 0), 0, 1).astype(np.float32)


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    torch.manual_seed(30)
    torch.set_num_threads(2)
    rng = np.random.default_rng(30)
    models = {}
    for net, legacy in (("alex", (True, False)), ("vgg", (False, True))):
        model = torchvision.models.alexnet() if net == "alex" else torchvision.models.vgg16()
        sd = {k: v.detach().clone() for k, v in model.state_dict().items()}
        # torchvision zero-inits the conv biases; random ones exercise the bias path.
        for k in sd:
            if k.startswith("features.") and k.endswith(".bias"):
                sd[k] = 0.05 * torch.randn_like(sd[k])
        model.load_state_dict(sd)
        channels = [sd[f"features.{st[-1][1]}.weight"].shape[0] for st in ARCH[net]]
        lin = OrderedDict((f"lin{k}.model.1.weight", torch.rand(1, c, 1, 1) * (0.5 / c ** 0.5))
                          for k, c in enumerate(channels))
        lin_file, backbone_file = FILES[net]
        torch.save(lin, os.path.join(out, lin_file), _use_new_zipfile_serialization=not legacy[0])
        # AlexNet's file keeps the classifier, as the real checkpoint (the reader must skip
        # what the network does not use); VGG16's keeps the features only (its classifier is
        # 120 M parameters, slow to write for nothing).
        state = model.state_dict()
        if net == "vgg":
            state = OrderedDict((k, v) for k, v in state.items() if k.startswith("features."))
        torch.save(state, os.path.join(out, backbone_file),
                   _use_new_zipfile_serialization=not legacy[1])
        models[net] = (sd, lin)

    sizes = [(64, 64), (97, 131), (151, 200), (33, 47)]
    pairs = []
    for i, (h, w) in enumerate(sizes):
        a = smooth_image(rng, h, w)
        if i % 2 == 0:  # a degraded copy
            b = np.clip(a + 0.08 * rng.standard_normal(a.shape).astype(np.float32), 0, 1)
        else:  # unrelated content
            b = smooth_image(rng, h, w)
        # 8-bit values (v / 255), so that the tests may also pass the pair as PNG files.
        a = (np.round(a * 255) / 255).astype(np.float32)
        b = (np.round(b * 255) / 255).astype(np.float32)
        yy, xx = np.mgrid[0:h, 0:w]
        mask = ((xx - w * 0.4) ** 2 + (yy - h * 0.6) ** 2 < (0.45 * min(h, w)) ** 2).astype(np.uint8)
        a.tofile(os.path.join(out, f"a_{i}.f32"))
        b.tofile(os.path.join(out, f"b_{i}.f32"))
        mask.tofile(os.path.join(out, f"m_{i}.u8"))
        ta = torch.from_numpy(a.transpose(2, 0, 1).copy())[None]
        tb = torch.from_numpy(b.transpose(2, 0, 1).copy())[None]
        entry = {"index": i, "height": h, "width": w}
        with torch.no_grad():
            for net, (sd, lin) in models.items():
                if net == "alex" and min(h, w) < 31:
                    continue
                whole, masked = lpips(ta, tb, sd, lin, net, mask)
                _, all_pixels = lpips(ta, tb, sd, lin, net, None)
                entry[net] = {"whole": whole, "masked": masked, "spatial_mean": all_pixels}
        pairs.append(entry)
    with open(os.path.join(out, "reference.json"), "w") as f:
        json.dump({"pairs": pairs}, f, indent=1)


if __name__ == "__main__":
    main()
