"""Scenes, splits, rendering and whole runs on the CLI's procedural demo scene."""
import subprocess

import numpy as np
import pytest

import rephoto
from conftest import cli_path


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    subprocess.run([cli_path(), "demo", "--out", str(out), "--cameras", "4", "--width", "96",
                    "--height", "64"], check=True, capture_output=True)
    return out


def test_read_scene(demo):
    scene = rephoto.read_scene(demo / "scene" / "sparse")
    assert scene.format == "colmap" and len(scene) == 4
    view = scene[0]
    assert scene[view.name].name == view.name
    assert (view.width, view.height) == (96, 64)
    assert view.camera.model == "OPENCV" and len(view.camera.params) == 8
    m = view.cam_from_world
    assert m.shape == (4, 4) and m.dtype == np.float64
    np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-9)
    assert np.all(m[3] == [0, 0, 0, 1])
    assert view.image_path.exists()


def test_split(demo):
    scene = rephoto.read_scene(demo / "scene" / "sparse")
    split = rephoto.split(scene, "kfold:2", seed=3)
    assert split["scheme"] == "kfold:2:3" and split["cross_validated"]
    tested = sorted(n for fold in split["folds"] for n in fold["test"])
    assert tested == sorted(v.name for v in scene.views)
    assert rephoto.split([v.name for v in scene.views], "kfold:2:3") == split
    with pytest.raises(rephoto.Error, match=r"needs 2 <= K <= number of images \(4\)"):
        rephoto.split(scene, "kfold:9")
    with pytest.raises(ValueError, match="--scheme 'kfold:x'"):
        rephoto.split(scene, "kfold:x")


def test_render_ground_truth_reproduces_the_photo(demo):
    from skimage import io
    scene = rephoto.read_scene(demo / "scene" / "sparse")
    model = rephoto.load_model(demo / "models" / "ground_truth.ply")
    assert model.kind == "mesh"
    view = scene[0]
    rgba, depth = model.render(view, spp=4)
    assert rgba.shape == (64, 96, 4) and rgba.dtype == np.float32
    assert depth.shape == (64, 96)
    same_pose = model.render(view.camera, cam_from_world=view.cam_from_world, spp=4)[0]
    np.testing.assert_array_equal(same_pose, rgba)
    photo = io.imread(view.image_path)
    result = rephoto.compare(photo, rgba, metrics=["psnr"])
    assert result["completeness"] > 0.5
    assert result["psnr"] > 25
    with pytest.raises(ValueError, match="cam_from_world is required"):
        model.render(view.camera)


def test_evaluate_equals_the_cli_run(demo, tmp_path, cli):
    settings = dict(scene=demo / "scene" / "sparse", model=demo / "models" / "texture_noise.ply",
                    scheme="kfold:2", metrics=["1-ncc", "psnr"])
    run = rephoto.evaluate(out=tmp_path / "py", **settings)
    cli("evaluate", "--scene", settings["scene"], "--model", settings["model"], "--scheme",
        "kfold:2", "--metrics", "1-ncc,psnr", "--out", tmp_path / "cli")
    cli_run = rephoto.load_run(tmp_path / "cli")
    assert len(run.per_image) == 4 and len(run.per_fold) == 2
    assert run.per_image == cli_run.per_image
    assert run.per_fold == cli_run.per_fold
    assert isinstance(run.per_image[0]["psnr"], float)
    pandas = pytest.importorskip("pandas")
    frame = run.per_image_frame()
    assert isinstance(frame, pandas.DataFrame) and list(frame["name"]) == [r["name"] for r in run.per_image]


def test_scene_and_run_errors(tmp_path):
    with pytest.raises(rephoto.Error, match=str(tmp_path / "nope")):
        rephoto.read_scene(tmp_path / "nope")
    with pytest.raises(ValueError, match="unknown scene format 'xyz'"):
        rephoto.read_scene(tmp_path, format="xyz")
    with pytest.raises(ValueError, match="unknown"):
        rephoto.evaluate(scene=tmp_path, no_such_setting=1, out=tmp_path / "o")
    with pytest.raises(rephoto.Error, match="no per_image.csv"):
        rephoto.load_run(tmp_path)


def write_inria_ply(path, positions, colour_dc, opacity_logit, log_scale):
    """A 3DGS (graphdeco) PLY with SH degree 0: x y z nx ny nz f_dc_0..2 opacity scale_0..2
    rot_0..3, binary little endian, as train.py writes it."""
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    rows = []
    for p in positions:
        rows.append([*p, 0, 0, 0, *colour_dc, opacity_logit, *([log_scale] * 3), 1, 0, 0, 0])
    data = np.asarray(rows, dtype="<f4")
    header = "ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % len(rows)
    header += "".join(f"property float {n}\n" for n in names) + "end_header\n"
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(data.tobytes())


def test_gaussians_render(tmp_path):
    path = tmp_path / "point_cloud.ply"
    write_inria_ply(path, [(0, 0, 4)], colour_dc=(1.0, 0.0, -1.0), opacity_logit=4.0,
                    log_scale=np.log(0.3))
    model = rephoto.load_model(path)
    assert model.kind == "gaussians"
    camera = rephoto.Camera("PINHOLE", 64, 48, [60, 60, 32, 24])
    rgba, depth = model.render(camera, cam_from_world=np.eye(4), background=(0, 0, 1))
    assert rgba.shape == (48, 64, 4)
    centre, corner = rgba[24, 32], rgba[0, 0]
    assert centre[3] > 0.9 and corner[3] < 0.05
    assert centre[0] > centre[2]  # red-ish Gaussian (SH DC) in the middle
    assert corner[2] == pytest.approx(1.0, abs=0.05)  # blue background at the corner
    assert depth[24, 32] == pytest.approx(4.0, rel=1e-3)
    with pytest.raises(rephoto.UsageError, match="gaussian_mode mip: expected classic"):
        model.render(camera, cam_from_world=np.eye(4), gaussian_mode="mip")
