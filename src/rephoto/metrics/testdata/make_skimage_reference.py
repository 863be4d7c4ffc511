#!/usr/bin/python3
"""Writes skimage_reference.json: SSIM, DSSIM and PSNR from scikit-image for metrics_skimage_test.

Run with Debian's interpreter (python3-skimage, python3-pil):
    /usr/bin/python3 src/rephoto/metrics/testdata/make_skimage_reference.py

Cases
  synthetic_*: closed-form images (formula below, evaluated in double, rounded to float32),
               regenerated identically by the C++ test, so nothing large is committed.
  kermit_jpeg: two real JPEG photos (Bundler kermit000.jpg vs kermit001.jpg), cropped.
  temple_png:  a real PNG photo (Middlebury templeSR0001.png) vs a closed-form perturbation.
For each case: SSIM in rephoto's default mode (gaussian_weights=True, sigma=1.5,
use_sample_covariance=False, data_range=1, channel_axis=2) and in scikit-image's default mode
(win_size 7, uniform, sample covariance; data_range=1, channel_axis=2), PSNR
(peak_signal_noise_ratio, data_range=1), and the same three restricted to a closed-form
validity mask: SSIM as the mean of skimage's full SSIM map (full=True, channels averaged) over
the windows that lie inside the image and contain no invalid pixel, PSNR from the MSE over
valid pixels. Photos are decoded with PIL (Debian's libjpeg-turbo / libpng); a checksum of the
decoded 8-bit values lets the C++ test verify that its decoder produced the same pixels.
Also the CIELAB values of a few colours (skimage.color.rgb2lab) for the iCID colour space.
"""
import json
import math
import os

import numpy as np
from PIL import Image
from scipy.ndimage import minimum_filter
from skimage.color import rgb2lab
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.normpath(os.path.join(HERE, "..", "..", "..", "..", "..", "shared", "data"))


def synthetic(width, height, variant):
    """photo/rephoto in [0,1]; the C++ test has the same formula (SyntheticPair)."""
    y, x, c = np.meshgrid(np.arange(height, dtype=np.float64), np.arange(width, dtype=np.float64),
                          np.arange(3, dtype=np.float64), indexing="ij")
    v = float(variant)
    photo = 0.5 + 0.35 * np.sin(0.21 * x + 0.13 * y + 1.1 * c + v) * np.cos(0.07 * x - 0.19 * y + 0.3 * c)
    rephoto = 0.8 * photo + 0.1 + 0.08 * np.sin(0.9 * x + 0.5 * y + 2.0 * c + 0.7 * v)
    photo = np.clip(photo, 0.0, 1.0).astype(np.float32)
    rephoto = np.clip(rephoto, 0.0, 1.0).astype(np.float32)
    return photo.astype(np.float64), rephoto.astype(np.float64)


def perturb(photo):
    """Closed-form perturbation of a real photo (the C++ test has the same formula)."""
    height, width, _ = photo.shape
    y, x, c = np.meshgrid(np.arange(height, dtype=np.float64), np.arange(width, dtype=np.float64),
                          np.arange(3, dtype=np.float64), indexing="ij")
    out = 0.85 * photo.astype(np.float64) + 0.05 + 0.04 * np.sin(0.37 * x + 0.23 * y + c)
    return np.clip(out, 0.0, 1.0).astype(np.float32).astype(np.float64)


def mask_for(width, height):
    """Validity mask (1 valid); the C++ test has the same formula (ReferenceMask)."""
    y, x = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    invalid = ((x - width // 3) ** 2 + (y - height // 2) ** 2 < (height // 5) ** 2) | \
              ((x * 7 + y * 3) % 389 == 0)
    return (~invalid).astype(np.uint8)


def masked_ssim(photo, rephoto, valid, window, **kwargs):
    _, smap = structural_similarity(photo, rephoto, data_range=1.0, channel_axis=2, full=True,
                                    **kwargs)
    smap = smap.mean(axis=2)
    r = window // 2
    ok = minimum_filter(valid, size=window, mode="constant", cval=0) > 0
    ok[:r, :] = False
    ok[-r:, :] = False
    ok[:, :r] = False
    ok[:, -r:] = False
    return float(smap[ok].mean()), int(ok.sum())


def evaluate(photo, rephoto):
    gaussian = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False)
    out = {
        "ssim_gaussian": float(structural_similarity(photo, rephoto, data_range=1.0,
                                                     channel_axis=2, **gaussian)),
        "ssim_skimage_default": float(structural_similarity(photo, rephoto, data_range=1.0,
                                                            channel_axis=2)),
        "psnr": float(peak_signal_noise_ratio(photo, rephoto, data_range=1.0)),
    }
    out["dssim_gaussian"] = (1.0 - out["ssim_gaussian"]) / 2.0
    valid = mask_for(photo.shape[1], photo.shape[0])
    out["masked_ssim_gaussian"], out["masked_count_gaussian"] = masked_ssim(
        photo, rephoto, valid, 11, **gaussian)
    out["masked_ssim_skimage_default"], out["masked_count_skimage_default"] = masked_ssim(
        photo, rephoto, valid, 7)
    sel = valid > 0
    mse = float(np.mean((photo[sel] - rephoto[sel]) ** 2))
    out["masked_psnr"] = 10.0 * math.log10(1.0 / mse)
    return out


def checksum(u8):
    """Sum of values and sum of value * (index % 251 + 1) over the whole decoded image."""
    flat = u8.reshape(-1).astype(np.int64)
    weights = np.arange(flat.size, dtype=np.int64) % 251 + 1
    return {"sum": int(flat.sum()), "weighted_sum": int((flat * weights).sum())}


def load(path):
    u8 = np.asarray(Image.open(path).convert("RGB"))
    return u8, u8.astype(np.float32) / np.float32(255.0)


def main():
    cases = {}
    for name, (w, h, variant) in {"synthetic_64x48": (64, 48, 0),
                                  "synthetic_97x61": (97, 61, 1)}.items():
        photo, rephoto = synthetic(w, h, variant)
        cases[name] = {"width": w, "height": h, "variant": variant, **evaluate(photo, rephoto)}

    crop = {"x": 180, "y": 120, "width": 200, "height": 160}

    def cut(img):
        return img[crop["y"]:crop["y"] + crop["height"], crop["x"]:crop["x"] + crop["width"]]

    a_u8, a = load(os.path.join(DATA, "bundler_kermit", "kermit000.jpg"))
    b_u8, b = load(os.path.join(DATA, "bundler_kermit", "kermit001.jpg"))
    cases["kermit_jpeg"] = {
        "photo": "bundler_kermit/kermit000.jpg", "rephoto": "bundler_kermit/kermit001.jpg",
        "crop": crop, "photo_checksum": checksum(a_u8), "rephoto_checksum": checksum(b_u8),
        **evaluate(cut(a).astype(np.float64), cut(b).astype(np.float64))}

    t_u8, t = load(os.path.join(DATA, "middlebury_temple_dino", "templeSparseRing",
                                "templeSR0001.png"))
    t = cut(t).astype(np.float64)
    cases["temple_png"] = {
        "photo": "middlebury_temple_dino/templeSparseRing/templeSR0001.png",
        "crop": crop, "photo_checksum": checksum(t_u8), **evaluate(t, perturb(t))}

    colours = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [1.0, 0.0, 0.0], [0.2, 0.6, 0.9],
               [0.03, 0.02, 0.01], [0.5, 0.5, 0.5], [0.9, 0.8, 0.1]]
    lab = rgb2lab(np.array([colours], dtype=np.float64))[0]
    result = {
        "generator": "make_skimage_reference.py (scikit-image %s)" % __import__("skimage").__version__,
        "cases": cases,
        "lab": [{"rgb": c, "lab": [float(v) for v in l]} for c, l in zip(colours, lab)],
    }
    with open(os.path.join(HERE, "skimage_reference.json"), "w") as f:
        json.dump(result, f, indent=1, sort_keys=True)
        f.write("\n")


if __name__ == "__main__":
    main()
