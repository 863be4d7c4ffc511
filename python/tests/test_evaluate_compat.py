"""`rephoto evaluate --compat`: the numbers papers publish in one command (issue 30).

The acceptance test: a 3D Gaussian splatting model of a real scene (LLFF fern, 20 photos) is
evaluated with `--compat 3dgs`; an independent re-implementation of graphdeco's metrics.py
(compat_reference.py, written from its source) reads the renderings rephoto wrote and the
photos from disk, computes the per-image SSIM/PSNR and their means itself, and must find the
values of results.json, per_view.json and the printed lines. The model: one isotropic Gaussian
per COLMAP point of the scene, coloured with the point's colour (SH degree 0), as 3DGS
initialises its training from the same points.
"""
import json
import re
from pathlib import Path

import numpy as np
import pytest

import rephoto
import compat_reference as ref

ROOT = Path(__file__).resolve().parents[2]
FERN = ROOT.parent / "shared" / "data" / "llff_fern"
SCENE = FERN / "sparse_text_images_8_derived"
IMAGES = FERN / "images_8"
SH_C0 = 0.28209479177387814


def read_image(path):
    """RGB in [0, 1] as metrics.py reads it: PIL, torchvision's to_tensor (float32 v / 255),
    [:3]; then float64 for the sums."""
    from PIL import Image
    rgb = np.asarray(Image.open(path))[..., :3]
    return (rgb.astype(np.float32) / np.float32(255)).astype(np.float64)


def fern_points():
    positions, colours = [], []
    for line in (SCENE / "points3D.txt").read_text().splitlines():
        if not line or line.startswith("#"):
            continue
        f = line.split()
        positions.append([float(v) for v in f[1:4]])
        colours.append([int(v) for v in f[4:7]])
    return np.asarray(positions), np.asarray(colours) / 255.0


@pytest.fixture(scope="module")
def gaussian_model(tmp_path_factory):
    if not SCENE.is_dir():
        pytest.skip(f"{SCENE} not found (the shared datasets)")
    positions, colours = fern_points()
    folder = tmp_path_factory.mktemp("fern_3dgs") / "point_cloud" / "iteration_7000"
    folder.mkdir(parents=True)
    path = folder / "point_cloud.ply"
    # A graphdeco PLY (as train.py writes it, SH degree 0), one row per point.
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    extent = np.percentile(positions, 95, axis=0) - np.percentile(positions, 5, axis=0)
    log_scale = np.log(0.012 * np.linalg.norm(extent))
    rows = np.zeros((len(positions), len(names)), dtype="<f4")
    rows[:, 0:3] = positions
    rows[:, 6:9] = (colours - 0.5) / SH_C0
    rows[:, 9] = 3.0  # opacity logit: alpha 0.95
    rows[:, 10:13] = log_scale
    rows[:, 13] = 1.0
    header = "ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % len(rows)
    header += "".join(f"property float {n}\n" for n in names) + "end_header\n"
    path.write_bytes(header.encode() + rows.tobytes())
    return path


def metrics_py(run, renders_dir, photo_of):
    """graphdeco's metrics.py on the renderings rephoto wrote, against the photos on disk:
    per image ssim and psnr (compat_reference), then torch.tensor(values).mean()."""
    ssims, psnrs, names = [], [], []
    for render_path in sorted(renders_dir.glob("*.png")):
        if render_path.name.endswith(".depth.png"):
            continue
        render = read_image(render_path)
        gt = read_image(photo_of(render_path.stem))
        ssims.append(ref.ssim_3dgs(render, gt))
        psnrs.append(ref.psnr_3dgs(render, gt))
        names.append(render_path.name)
    return names, ssims, psnrs


def test_evaluate_compat_3dgs_writes_what_metrics_py_prints(gaussian_model, tmp_path, cli):
    out = tmp_path / "run"
    proc = cli("evaluate", "--compat", "3dgs", "--scene", SCENE, "--image-root", IMAGES,
               "--model", gaussian_model, "--out", out, check=False)
    assert proc.returncode == 0, proc.stderr
    # The preset's split: every 8th image in name order (3DGS llffhold): image000/008/016.
    renders = out / "folds" / "fold_00" / "renders"
    names, ssims, psnrs = metrics_py(out, renders, lambda stem: IMAGES / f"{stem}.png")
    assert names == ["image000.png", "image008.png", "image016.png"]
    results = json.loads((out / "results.json").read_text())
    per_view = json.loads((out / "per_view.json").read_text())
    assert list(results) == ["ours_7000"]  # the method folder render.py would name
    method = results["ours_7000"]
    assert list(method) == ["SSIM", "PSNR"]  # LPIPS only with --lpips-weights
    assert method["SSIM"] == pytest.approx(np.mean(ssims), abs=1e-9)
    assert method["PSNR"] == pytest.approx(np.mean(psnrs), abs=1e-7)
    for name, s, p in zip(names, ssims, psnrs):
        assert per_view["ours_7000"]["SSIM"][name] == pytest.approx(s, abs=1e-9)
        assert per_view["ours_7000"]["PSNR"][name] == pytest.approx(p, abs=1e-7)
    # What metrics.py prints, to the digit.
    printed = (f"  SSIM : {np.mean(ssims):>12.7f}\n"
               f"  PSNR : {np.mean(psnrs):>12.7f}\n")
    assert printed in proc.stdout
    assert (out / "metrics.txt").read_text() == (
        f"Scene: {out.resolve()}\nMethod: ours_7000\n{printed}\n")
    # json.dump(indent=True): one space per level.
    assert (out / "results.json").read_text().startswith('{\n "ours_7000": {\n  "SSIM": ')

    # rephoto's own masked metrics and completeness beside them, in the same tables.
    run = rephoto.load_run(out)
    assert [r["name"] for r in run.per_image] == ["image000", "image008", "image016"]
    for row, s, p in zip(run.per_image, ssims, psnrs):
        assert row["3dgs_ssim"] == pytest.approx(s, abs=1e-9)
        assert row["3dgs_psnr"] == pytest.approx(p, abs=1e-7)
        assert 0 < row["completeness"] <= 1 and np.isfinite(row["1-ncc"])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scheme"] == "every:8"
    assert summary["compat"]["preset"] == "3dgs"
    assert summary["compat"]["metrics"]["psnr"]["mean"] == pytest.approx(np.mean(psnrs), abs=1e-7)
    assert summary["compat"]["metrics"]["ssim"]["std"] == pytest.approx(np.std(ssims, ddof=1),
                                                                        abs=1e-9)
    assert set(summary["metrics"]) >= {"1-ncc", "psnr", "ssim"}
    assert summary["files"]["results"] == "results.json"
    assert (out / "report.html").is_file()


def test_evaluate_compat_nerfstudio_from_python(gaussian_model, tmp_path):
    """Python evaluate(compat=...) (raised UsageError before issue 30) with nerfstudio's
    definitions (torchmetrics: reflect padding, 10 log10(1/MSE)) and ns-eval's output.json."""
    out = tmp_path / "ns"
    run = rephoto.evaluate(compat="nerfstudio", scene=SCENE, image_root=IMAGES,
                           model=gaussian_model, background=(1, 1, 1), metrics=["1-ncc"], out=out)
    renders = out / "folds" / "fold_00" / "renders"
    psnrs, ssims = [], []
    for stem in ("image000", "image008", "image016"):
        render = read_image(renders / f"{stem}.png")
        gt = read_image(IMAGES / f"{stem}.png")
        psnrs.append(ref.psnr_torchmetrics(render, gt))
        ssims.append(ref.ssim_torchmetrics(render, gt))
    output = json.loads((out / "output.json").read_text())
    assert output["experiment_name"] == SCENE.name  # the scene folder, as ns-train names it
    assert list(output["results"]) == ["psnr", "psnr_std", "ssim", "ssim_std"]
    results = output["results"]
    assert results["psnr"] == pytest.approx(np.mean(psnrs), abs=1e-7)
    assert results["psnr_std"] == pytest.approx(np.std(psnrs, ddof=1), abs=1e-7)
    assert results["ssim"] == pytest.approx(np.mean(ssims), abs=1e-9)
    assert results["ssim_std"] == pytest.approx(np.std(ssims, ddof=1), abs=1e-9)
    assert [r["nerfstudio_psnr"] for r in run.per_image] == pytest.approx(psnrs, abs=1e-7)
    assert not (out / "results.json").exists()
    # A rerun without --compat leaves no reference file of the earlier run behind.
    rephoto.evaluate(scene=SCENE, image_root=IMAGES, model=gaussian_model, scheme="every:8",
                     metrics=["1-ncc"], out=out)
    assert not (out / "output.json").exists()
    assert "nerfstudio_psnr" not in rephoto.load_run(out).per_image[0]


def test_evaluate_compat_settings_are_checked(tmp_path):
    with pytest.raises(rephoto.UsageError, match="'mip' is not 3dgs, nerfstudio or none"):
        rephoto.evaluate(compat="mip", scene=tmp_path, model=tmp_path / "m.ply", out=tmp_path)
    with pytest.raises(rephoto.UsageError, match="metric 'dssim' does not exist in this mode"):
        rephoto.evaluate(compat="3dgs", compat_metrics="psnr,dssim", scene=tmp_path,
                         model=tmp_path / "m.ply", out=tmp_path)
    with pytest.raises(rephoto.UsageError, match="--compat-metrics needs a --compat preset"):
        rephoto.evaluate(compat_metrics="psnr", scene=tmp_path, model=tmp_path / "m.ply",
                         out=tmp_path)
