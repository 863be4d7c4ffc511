"""LPIPS through the Python binding and the CLI, against the independent PyTorch
implementation of the lpips package's forward pass in src/rephoto/lpips/lpips_reference.py
(random-weight AlexNet/VGG16 and lin layers saved by torch.save under the original file names).
Skipped, with the reason, when Debian's python3-torch/python3-torchvision are not installed."""
import csv
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import rephoto
from conftest import ROOT, cli_path, write_png

TOLERANCE = 1e-5


@pytest.fixture(scope="module")
def fixture(tmp_path_factory):
    out = tmp_path_factory.mktemp("lpips")
    script = ROOT / "src" / "rephoto" / "lpips" / "lpips_reference.py"
    run = subprocess.run(["/usr/bin/python3", str(script), str(out)], capture_output=True,
                         text=True)
    if run.returncode == 77:
        pytest.skip(f"python3-torch/python3-torchvision not installed: {run.stderr.strip()}")
    assert run.returncode == 0, run.stderr
    reference = json.loads((out / "reference.json").read_text())
    pairs = []
    for entry in reference["pairs"]:
        h, w, i = entry["height"], entry["width"], entry["index"]
        a = np.fromfile(out / f"a_{i}.f32", dtype=np.float32).reshape(h, w, 3)
        b = np.fromfile(out / f"b_{i}.f32", dtype=np.float32).reshape(h, w, 3)
        m = np.fromfile(out / f"m_{i}.u8", dtype=np.uint8).reshape(h, w)
        # The fixture's values are v / 255: the same pair as 8-bit samples.
        a8 = np.round(a * 255).astype(np.uint8)
        b8 = np.round(b * 255).astype(np.uint8)
        pairs.append((entry, a8, b8, m))
    return out, pairs


def test_compat_is_the_whole_image_value(fixture):
    weights, pairs = fixture
    for entry, a8, b8, _ in pairs:
        for net in ("alex", "vgg"):
            if net not in entry:
                continue
            result = rephoto.compare(a8, b8, metrics=["lpips"], compat="3dgs",
                                     lpips_weights=weights, lpips_net=net)
            assert abs(result["lpips"] - entry[net]["whole"]) <= TOLERANCE, (net, entry)
            assert result["evaluated"]["lpips"] == a8.shape[0] * a8.shape[1]


def test_masked_value_is_the_spatial_map_over_the_mask(fixture):
    weights, pairs = fixture
    for entry, a8, b8, m in pairs:
        if "alex" not in entry:
            continue
        # The mask as the rendering's alpha; exposure tests off, so the mask is the validity.
        render = np.dstack([b8, m * 255])
        result = rephoto.compare(a8, render, metrics=["psnr", "lpips"], dark=-1.0,
                                 saturated=2.0, lpips_weights=weights, error_images=True)
        assert abs(result["lpips"] - entry["alex"]["masked"]) <= TOLERANCE
        assert result["evaluated"]["lpips"] == int(m.astype(bool).sum())
        spatial = result["errors"]["lpips"]
        assert spatial.shape == m.shape
        assert np.isnan(spatial[m == 0]).all()
        assert abs(float(np.mean(spatial[m != 0], dtype=np.float64)) -
                   entry["alex"]["masked"]) <= TOLERANCE


def test_compat_default_metrics_include_lpips_only_with_weights(fixture, monkeypatch):
    weights, pairs = fixture
    entry, a8, b8, _ = pairs[1]
    monkeypatch.delenv("REPHOTO_LPIPS_WEIGHTS", raising=False)
    without = rephoto.compare(a8, b8, compat="3dgs")
    assert "lpips" not in without and "psnr" in without and "ssim" in without
    with_weights = rephoto.compare(a8, b8, compat="3dgs", lpips_weights=weights)
    assert abs(with_weights["lpips"] - entry["alex"]["whole"]) <= TOLERANCE
    assert with_weights["psnr"] == without["psnr"] and with_weights["ssim"] == without["ssim"]


def test_missing_weights_is_one_clear_error(tmp_path, monkeypatch):
    monkeypatch.delenv("REPHOTO_LPIPS_WEIGHTS", raising=False)
    a = np.full((40, 40, 3), 100, np.uint8)
    with pytest.raises(rephoto.UsageError) as error:
        rephoto.compare(a, a, metrics=["lpips"], lpips_weights=tmp_path)
    message = str(error.value)
    assert "alex.pth" in message and "alexnet-owt-7be5be79.pth" in message
    assert "pip install lpips" in message and "download.pytorch.org" in message


def write_pairs(tmp_path, pairs, with_alpha):
    photos, renders = tmp_path / "photos", tmp_path / "renders"
    photos.mkdir()
    renders.mkdir()
    for entry, a8, b8, m in pairs:
        if "alex" not in entry:
            continue
        write_png(photos / f"p{entry['index']}.png", a8)
        write_png(renders / f"p{entry['index']}.png", np.dstack([b8, m * 255]) if with_alpha
                  else b8)
    return photos, renders


def read_rows(run):
    with open(run / "per_image.csv", newline="") as f:
        return {row["name"]: row for row in csv.DictReader(f)}


def test_cli_compare_masked_column_and_summary(fixture, tmp_path):
    weights, pairs = fixture
    photos, renders = write_pairs(tmp_path, pairs, with_alpha=True)
    out = tmp_path / "run"
    subprocess.run([cli_path(), "compare", "--photos", photos, "--renders", renders,
                    "--metrics", "psnr,lpips", "--lpips-weights", weights, "--dark", "-1",
                    "--saturated", "2", "--out", out], check=True, capture_output=True)
    rows = read_rows(out)
    for entry, _, _, m in pairs:
        if "alex" not in entry:
            continue
        row = rows[f"p{entry['index']}"]
        assert abs(float(row["lpips"]) - entry["alex"]["masked"]) <= TOLERANCE
        assert int(row["lpips_evaluated"]) == int(m.astype(bool).sum())
        assert (out / "errors" / f"p{entry['index']}.lpips.exr").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert "lpips" in json.dumps(summary["metrics"])


def test_cli_compat_preset_and_metric_choice(fixture, tmp_path):
    weights, pairs = fixture
    photos, renders = write_pairs(tmp_path, pairs, with_alpha=False)
    env = dict(os.environ, REPHOTO_LPIPS_WEIGHTS=str(weights))
    # The preset's metrics: psnr, ssim, and lpips because weights are given (environment).
    out = tmp_path / "compat"
    subprocess.run([cli_path(), "compare", "--compat", "3dgs", "--photos", photos, "--renders",
                    renders, "--out", out], check=True, capture_output=True, env=env)
    rows = read_rows(out)
    for entry, _, _, _ in pairs:
        if "alex" not in entry:
            continue
        row = rows[f"p{entry['index']}"]
        assert {"psnr", "ssim", "lpips"} <= set(row)
        assert abs(float(row["lpips"]) - entry["alex"]["whole"]) <= TOLERANCE
    # --metrics chooses among the preset's metrics.
    chosen = tmp_path / "chosen"
    subprocess.run([cli_path(), "compare", "--compat", "3dgs", "--metrics", "psnr,lpips",
                    "--lpips-weights", weights, "--photos", photos, "--renders", renders,
                    "--out", chosen], check=True, capture_output=True)
    row = next(iter(read_rows(chosen).values()))
    assert "lpips" in row and "psnr" in row and "ssim" not in row
    refused = subprocess.run([cli_path(), "compare", "--compat", "3dgs", "--metrics", "1-ncc",
                              "--photos", photos, "--renders", renders, "--out",
                              tmp_path / "no"], capture_output=True, text=True)
    assert refused.returncode != 0 and "psnr, ssim, lpips" in refused.stderr


def test_cli_missing_weights(tmp_path, pair):
    photo, render = pair
    (tmp_path / "p").mkdir()
    (tmp_path / "r").mkdir()
    write_png(tmp_path / "p" / "a.png", photo)
    write_png(tmp_path / "r" / "a.png", render)
    (tmp_path / "w").mkdir()
    env = {k: v for k, v in os.environ.items() if k != "REPHOTO_LPIPS_WEIGHTS"}
    run = subprocess.run([cli_path(), "compare", "--photos", tmp_path / "p", "--renders",
                          tmp_path / "r", "--metrics", "lpips", "--lpips-weights",
                          tmp_path / "w", "--out", tmp_path / "o"], capture_output=True,
                         text=True, env=env)
    assert run.returncode == 2, run.stderr
    assert run.stderr.count("\n") == 1
    assert "alexnet-owt-7be5be79.pth" in run.stderr and "https://download.pytorch.org" in run.stderr


def test_evaluate_takes_the_weights_from_argument_config_and_cli(fixture, tmp_path):
    weights, _ = fixture
    demo = tmp_path / "demo"
    subprocess.run([cli_path(), "demo", "--out", demo, "--cameras", "4", "--width", "96",
                    "--height", "64"], check=True, capture_output=True)
    settings = dict(scene=demo / "scene" / "sparse", model=demo / "models" / "texture_noise.ply",
                    scheme="kfold:2", metrics=["psnr", "lpips"])
    run = rephoto.evaluate(out=tmp_path / "py", lpips_weights=weights, **settings)
    rows = run.per_image
    assert len(rows) == 4
    for row in rows:
        assert isinstance(row["lpips"], float) and 0 < row["lpips"] < 10
        assert row["lpips_evaluated"] > 0
    # The config key (relative to the config file) and the flag give the same run.
    (tmp_path / "exp.toml").write_text(f'lpips_weights = "{os.path.relpath(weights, tmp_path)}"\n')
    subprocess.run([cli_path(), "evaluate", "--config", tmp_path / "exp.toml", "--scene",
                    settings["scene"], "--model", settings["model"], "--scheme", "kfold:2",
                    "--metrics", "psnr,lpips", "--out", tmp_path / "cfg"], check=True,
                   capture_output=True)
    subprocess.run([cli_path(), "evaluate", "--lpips-weights", weights, "--scene",
                    settings["scene"], "--model", settings["model"], "--scheme", "kfold:2",
                    "--metrics", "psnr,lpips", "--out", tmp_path / "flag"], check=True,
                   capture_output=True)
    for other in ("cfg", "flag"):
        other_rows = rephoto.load_run(tmp_path / other).per_image
        assert [r["lpips"] for r in other_rows] == [r["lpips"] for r in rows]
