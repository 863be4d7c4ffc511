#!/usr/bin/python3
"""Writes expected_scores.json: the scores server_test expects for its fixed test photos.

Regenerate (Debian's interpreter and python3-numpy; nothing else is needed):
    /usr/bin/python3 src/rephoto/service/testdata/make_expected_scores.py

Written from the metric definitions in SPEC.md ("Validity and completeness", "Metrics") and
docs/benchmark.md (the "filled" ranking score), not from rephoto's C++. The images are integer
formulas (8-bit values, so both languages produce exactly the same pixels);
server_test.cc (FixedPhoto, FixedRender) has the same formulas.

Images, 64 x 48, RGB, for the dataset's two test photos (stems "00" and "03", s = 0 and 3):
  photo(x, y, c)   = 40 + 2 * ((x^2 + 3 y^2 + 7 x y + 11 x + 5 y + 23 c + 37 s) mod 97)
                     with channel 0 set to 255 (saturated: an invalid photo pixel) where
                     (7 x + 3 y + s) mod 101 == 0.
Renders (RGBA, alpha 255 = rendered, 0 = not rendered):
  exact:     the photo;
  offset:    the photo + 12 in every channel (a grey offset: 1-NCC and cb+cr are 0 in closed
             form, PSNR = 20 log10(255 / 12) over the valid pixels);
  perturbed: 3 photo / 4 (integer division) + 30 + ((5 x + 9 y + 13 c + s) mod 61) - 30, with
             alpha 0 where x >= 40 for stem 00 and where y < 12 for stem 03 (partial coverage).

Metrics as the test dataset is configured (1-ncc, cb+cr, psnr; window 5; default exposure
thresholds 0 and 1), values v / 255 rounded to float32 as image readers give them:
  photo pixel valid:  every colour channel strictly between 0 and 1;
  render pixel valid: alpha > 0;
  1-ncc:  at every window of 5 x 5 pixels inside the image whose pixels are all valid in both:
          1 - sum((x - mx)(y - my)) / sqrt(sum (x - mx)^2 sum (y - my)^2), the sums over the
          window's pixels and all three channels jointly, mx/my per-channel means; a window
          whose sum of squared deviations is <= 1e-6 is flat (both flat 0, one flat 1);
          per-image mean over those windows;
  cb+cr:  |dCb| + |dCr| (full-range BT.601) at every valid pixel, per-image mean;
  psnr:   10 log10(1 / MSE), MSE over the valid pixels and the three channels;
  completeness: windows (5 x 5, inside the image) valid in photo and render / windows valid in
          the photo.
Summary (compare's summary.json): per metric the mean of the per-image values and "pooled"
(every evaluated position of both images together; psnr from the pooled MSE), completeness
averaged over the images. Scores (the leaderboard's, docs/benchmark.md): "means" as the
summary's means; "filled" = mean over the test photos of c * value + (1 - c) * worst, worst 2 for
1-ncc and cb+cr; psnr filled in its MSE (worst 1) and turned back into dB.
"""
import json
import math
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
WIDTH, HEIGHT, WINDOW = 64, 48, 5
STEMS = {"00": 0, "03": 3}
FLAT = 1e-6


def grids():
    y, x, c = np.meshgrid(np.arange(HEIGHT, dtype=np.int64), np.arange(WIDTH, dtype=np.int64),
                          np.arange(3, dtype=np.int64), indexing="ij")
    return x, y, c


def photo_u8(s):
    x, y, c = grids()
    p = 40 + 2 * ((x * x + 3 * y * y + 7 * x * y + 11 * x + 5 * y + 23 * c + 37 * s) % 97)
    saturated = ((7 * x[..., 0] + 3 * y[..., 0] + s) % 101) == 0
    p[..., 0][saturated] = 255
    return p


def render_u8(kind, s):
    """RGB and alpha (0 or 255)."""
    x, y, c = grids()
    p = photo_u8(s)
    alpha = np.full((HEIGHT, WIDTH), 255, dtype=np.int64)
    if kind == "exact":
        rgb = p.copy()
    elif kind == "offset":
        rgb = np.minimum(p + 12, 255)  # the saturated (invalid) pixels stay 255
    elif kind == "perturbed":
        rgb = p * 3 // 4 + 30 + (5 * x + 9 * y + 13 * c + s) % 61 - 30
        if s == 0:
            alpha[:, 40:] = 0
        else:
            alpha[:12, :] = 0
    else:
        raise ValueError(kind)
    assert rgb.min() >= 0 and rgb.max() <= 255
    return rgb, alpha


def to_float(u8):
    return (u8.astype(np.float32) / np.float32(255.0)).astype(np.float64)


def windows(a):
    """All WINDOW x WINDOW windows inside the image: array [H-4, W-4, 5, 5, ...]."""
    return np.lib.stride_tricks.sliding_window_view(a, (WINDOW, WINDOW), axis=(0, 1))


def window_valid(valid):
    w = windows(valid.astype(np.int64))
    return w.reshape(w.shape[0], w.shape[1], -1).min(axis=2) > 0


def one_minus_ncc(photo, render, valid):
    ok = window_valid(valid)
    # [h, w, 3, 5, 5] -> [h, w, 75] (pixels and channels jointly, per-channel means)
    pw = windows(photo)
    rw = windows(render)
    dp = pw - pw.mean(axis=(3, 4), keepdims=True)
    dr = rw - rw.mean(axis=(3, 4), keepdims=True)
    num = (dp * dr).sum(axis=(2, 3, 4))
    vp = (dp * dp).sum(axis=(2, 3, 4))
    vr = (dr * dr).sum(axis=(2, 3, 4))
    flat_p, flat_r = vp <= FLAT, vr <= FLAT
    with np.errstate(invalid="ignore", divide="ignore"):
        err = 1.0 - num / np.sqrt(vp * vr)
    err = np.where(flat_p & flat_r, 0.0, np.where(flat_p | flat_r, 1.0, err))
    return err[ok]


def cb_cr(rgb):
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return (-0.168736 * r - 0.331264 * g + 0.5 * b, 0.5 * r - 0.418688 * g - 0.081312 * b)


def evaluate(kind, s):
    p_u8 = photo_u8(s)
    r_u8, alpha = render_u8(kind, s)
    photo, render = to_float(p_u8), to_float(r_u8)
    photo_valid = ((p_u8 > 0) & (p_u8 < 255)).all(axis=2)
    render_valid = alpha > 0
    valid = photo_valid & render_valid
    ncc = one_minus_ncc(photo, render, valid)
    cbp, crp = cb_cr(photo)
    cbr, crr = cb_cr(render)
    chroma = (np.abs(cbp - cbr) + np.abs(crp - crr))[valid]
    se = ((photo - render) ** 2).mean(axis=2)[valid]
    photo_windows = int(window_valid(photo_valid).sum())
    both_windows = int(window_valid(valid).sum())
    return {
        "values": {"1-ncc": ncc, "cb+cr": chroma, "psnr": se},
        "completeness": both_windows / photo_windows,
        "photo_windows": photo_windows,
        "both_windows": both_windows,
    }


def psnr(mse):
    return math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse)


def number(v):
    return "inf" if v == math.inf else float(v)


WORST = {"1-ncc": 2.0, "cb+cr": 2.0}


def main():
    out = {"generator": "make_expected_scores.py (numpy %s)" % np.__version__,
           "width": WIDTH, "height": HEIGHT, "window": WINDOW, "submissions": {}}
    for kind in ("exact", "offset", "perturbed"):
        per_image = {}
        results = {stem: evaluate(kind, s) for stem, s in STEMS.items()}
        for stem, r in results.items():
            image = {"completeness": r["completeness"]}
            for name, values in r["values"].items():
                mean = psnr(values.mean()) if name == "psnr" else values.mean()
                image[name] = number(mean)
                image[name + "_evaluated"] = int(values.size)
            per_image[stem] = image
        summary = {"completeness": float(np.mean([r["completeness"] for r in results.values()])),
                   "metrics": {}}
        filled = {}
        for name in ("1-ncc", "cb+cr", "psnr"):
            pooled = np.concatenate([r["values"][name] for r in results.values()])
            means = [per_image[stem][name] for stem in STEMS]
            if name == "psnr":
                finite = [m for m in means if m != "inf"]
                mean = float(np.mean(finite)) if len(finite) == len(means) else math.inf
                summary["metrics"][name] = {"mean": number(mean), "pooled": number(psnr(pooled.mean()))}
                mses = [r["values"][name].mean() for r in results.values()]
                cs = [r["completeness"] for r in results.values()]
                filled[name] = number(psnr(np.mean([c * m + (1 - c) * 1.0 for c, m in zip(cs, mses)])))
            else:
                summary["metrics"][name] = {"mean": float(np.mean(means)),
                                            "pooled": float(pooled.mean())}
                filled[name] = float(np.mean([r["completeness"] * per_image[stem][name] +
                                              (1 - r["completeness"]) * WORST[name]
                                              for stem, r in results.items()]))
        out["submissions"][kind] = {"images": per_image, "summary": summary, "filled": filled}
    with open(os.path.join(HERE, "expected_scores.json"), "w") as f:
        json.dump(out, f, indent=1, sort_keys=True)
        f.write("\n")


if __name__ == "__main__":
    main()
