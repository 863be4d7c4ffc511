"""rephoto.compare against the CLI, scikit-image, dtype/stride handling, errors and threads."""
import csv
import math
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import rephoto
from conftest import write_png


def cli_values(cli, tmp_path, photo, render, extra=()):
    (tmp_path / "p").mkdir()
    (tmp_path / "r").mkdir()
    write_png(tmp_path / "p" / "x.png", photo)
    write_png(tmp_path / "r" / "x.png", render)
    cli("compare", "--photos", tmp_path / "p", "--renders", tmp_path / "r", "--out",
        tmp_path / "out", "--no-error-images", *extra)
    with open(tmp_path / "out" / "per_image.csv") as f:
        return next(csv.DictReader(f))


def same(a, b):
    return (math.isnan(a) and math.isnan(b)) or a == b


def test_values_equal_the_cli_bit_for_bit(cli, tmp_path, pair):
    photo, render = pair
    photo = photo.copy()
    photo[:10, :10] = 255  # ill-exposed corner: both must drop it
    render_rgba = np.dstack([render, np.full(render.shape[:2], 255, np.uint8)])
    render_rgba[40:, 60:, 3] = 0  # not covered
    row = cli_values(cli, tmp_path, photo, render_rgba)
    result = rephoto.compare(photo, render_rgba)
    assert float(row["completeness"]) == result["completeness"]
    assert int(row["valid_both_windows"]) == result["valid_both_windows"]
    for name in rephoto.METRICS:
        # per_image.csv prints 17 significant digits: equal as doubles.
        assert same(float(row[name]), result[name]), name
        assert int(row[name + "_evaluated"]) == result["evaluated"][name]


def test_resize_equals_the_cli(cli, tmp_path, pair):
    """A half-size RGBA rendering, rescaled to the photo's size as `rephoto compare --resize`."""
    photo, render = pair
    small = np.dstack([render[::2, ::2], np.full((34, 46), 255, np.uint8)])
    small[25:, 30:, 3] = 0  # not covered: validity decided before rescaling
    row = cli_values(cli, tmp_path, photo, small, ["--resize"])
    assert row["resized"] == "1"
    for kind in ("uint8", "float32"):
        args = (photo, small) if kind == "uint8" else (photo, small.astype(np.float32) / 255)
        result = rephoto.compare(*args, resize=True)
        assert result["resized"]
        assert float(row["completeness"]) == result["completeness"]
        assert int(row["valid_both_windows"]) == result["valid_both_windows"]
        for name in rephoto.METRICS:
            if kind == "uint8":  # the CLI's 8-bit path, bit for bit
                assert same(float(row[name]), result[name]), name
            else:
                assert float(row[name]) == pytest.approx(result[name], rel=1e-5, abs=1e-6), name
            assert int(row[name + "_evaluated"]) == result["evaluated"][name]
    # The render mask is rescaled with the rendering; it must have the rendering's size.
    render_mask = np.ones((34, 46), bool)
    masked = rephoto.compare(photo, small[..., :3], render_mask=render_mask, resize=True,
                             metrics="psnr")
    assert masked["evaluated"]["psnr"] > result["evaluated"]["psnr"]
    with pytest.raises(ValueError, match=r"^render_mask is 91x67 but render is 46x34$"):
        rephoto.compare(photo, small, render_mask=np.ones(photo.shape[:2], bool), resize=True)
    assert not rephoto.compare(photo, render, resize=True)["resized"]


def test_compat_equals_the_cli(cli, tmp_path, pair):
    photo, render = pair
    row = cli_values(cli, tmp_path, photo, render, ["--compat", "nerfstudio"])
    result = rephoto.compare(photo, render, compat="nerfstudio")
    assert float(row["psnr"]) == result["psnr"]
    assert float(row["ssim"]) == result["ssim"]


def test_psnr_and_ssim_equal_scikit_image(pair):
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity
    photo, render = (a.astype(np.float64) / 255 for a in pair)
    result = rephoto.compare(*pair, metrics=["psnr", "ssim"])
    assert result["psnr"] == pytest.approx(peak_signal_noise_ratio(photo, render, data_range=1),
                                           abs=2e-7 * 100)
    reference = structural_similarity(photo, render, data_range=1, channel_axis=2,
                                      gaussian_weights=True, sigma=1.5,
                                      use_sample_covariance=False)
    assert result["ssim"] == pytest.approx(reference, abs=2e-6)
    skimage_mode = rephoto.compare(*pair, metrics="ssim", ssim_mode="skimage")
    assert skimage_mode["ssim"] == pytest.approx(
        structural_similarity(photo, render, data_range=1, channel_axis=2), abs=2e-6)


def test_dtypes_layouts_and_strides_give_the_same_values(pair):
    photo, render = pair
    reference = rephoto.compare(photo, render)
    as_float = rephoto.compare((photo / np.float32(255)).astype(np.float32),
                               (render / np.float32(255)).astype(np.float32))
    as_uint16 = rephoto.compare(photo.astype(np.uint16) * 257, render.astype(np.uint16) * 257)
    opaque = np.full(photo.shape[:2] + (1,), 255, np.uint8)
    as_rgba = rephoto.compare(np.dstack([photo, opaque]), np.dstack([render, opaque]))
    # Non-contiguous views: every other column of a wider array, and a channel-reversed view.
    wide_p = np.repeat(photo, 2, axis=1)
    wide_r = np.repeat(render, 2, axis=1)
    strided = rephoto.compare(wide_p[:, ::2], wide_r[:, ::2])
    bgr_p = np.ascontiguousarray(photo[..., ::-1])
    flipped = rephoto.compare(bgr_p[..., ::-1], render)
    fortran = rephoto.compare(np.asfortranarray(photo), np.asfortranarray(render))
    for other in (as_uint16, as_rgba, strided, flipped, fortran):
        for name in rephoto.METRICS:
            assert same(other[name], reference[name]), name
    for name in rephoto.METRICS:  # float32 values differ from v/255 in the last bit at most
        assert as_float[name] == pytest.approx(reference[name], rel=1e-5, abs=1e-6), name


def test_masks_alpha_and_grey(pair):
    photo, render = pair
    mask = np.ones(photo.shape[:2], bool)
    mask[:, :20] = False
    masked = rephoto.compare(photo, render, mask=mask, metrics="psnr")
    via_alpha = rephoto.compare(np.dstack([photo, mask.astype(np.uint8) * 255]), render,
                                metrics="psnr")
    assert masked["psnr"] == via_alpha["psnr"]
    assert masked["evaluated"]["psnr"] == mask.sum()
    grey = rephoto.compare(photo[..., 0], render[..., 0], metrics="psnr")
    grey3 = rephoto.compare(np.dstack([photo[..., 0]] * 3), np.dstack([render[..., 0]] * 3),
                            metrics="psnr")
    assert grey["psnr"] == grey3["psnr"]


def test_error_images(pair):
    photo, render = pair
    result = rephoto.compare(photo, render, metrics=["1-ncc", "psnr"], error_images=True)
    ncc = result["errors"]["1-ncc"]
    assert ncc.shape == photo.shape[:2] and ncc.dtype == np.float32
    assert np.isnan(ncc[0, 0]) and not np.isnan(ncc[30, 40])
    assert np.nanmean(ncc.astype(np.float64)) == pytest.approx(result["1-ncc"], rel=1e-6)
    sq = rephoto.error_image(photo, render, "psnr")
    expected = ((photo / np.float32(255) - render / np.float32(255)) ** 2).mean(axis=2)
    np.testing.assert_allclose(sq, expected, rtol=1e-5, atol=1e-9)
    assert sq.flags.writeable and sq.base is not None  # the library's buffer, not a copy


def test_errors_are_one_line_exceptions(pair):
    photo, render = pair
    with pytest.raises(ValueError, match=r"^render is 91x60 but photo is 91x67 "
                       r"\(same size required, or resize=True\)$"):
        rephoto.compare(photo, render[:60])
    with pytest.raises(rephoto.UsageError, match="dtype float64 is not supported"):
        rephoto.compare(photo.astype(np.float64), render)
    with pytest.raises(rephoto.Error, match="unknown metric 'ncc'"):
        rephoto.compare(photo, render, metrics=["ncc"])
    with pytest.raises(ValueError, match="5 channels"):
        rephoto.compare(np.zeros((4, 4, 5), np.uint8), np.zeros((4, 4, 5), np.uint8))
    with pytest.raises(ValueError, match="metric 'icid' does not exist in this mode"):
        rephoto.compare(photo, render, metrics="icid", compat="3dgs")
    with pytest.raises(ValueError, match="compat: 'mipnerf' is not 3dgs or nerfstudio"):
        rephoto.compare(photo, render, compat="mipnerf")
    assert issubclass(rephoto.UsageError, rephoto.Error)


def test_threads_run_concurrently_and_agree(pair):
    photo, render = pair
    big_p = np.tile(photo, (4, 4, 1))
    big_r = np.tile(render, (4, 4, 1))
    serial = rephoto.compare(big_p, big_r)
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda _: rephoto.compare(big_p, big_r), range(8)))
    for result in results:
        for name in rephoto.METRICS:
            assert same(result[name], serial[name])
    # The GIL is released: another Python thread makes progress during a call.
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(1)

    t = threading.Thread(target=tick)
    t.start()
    for _ in range(3):
        rephoto.compare(big_p, big_r)
    stop.set()
    t.join()
    assert len(ticks) > 100


def test_isa_path_is_reported_and_a_bad_one_fails_the_import(tmp_path):
    """build_info names the instruction-set path (core/isa.h); REPHOTO_ISA=bogus fails the import
    with a message naming it."""
    import os
    import subprocess
    import sys
    assert rephoto.build_info["isa"] in ("baseline", "avx2", "avx512")
    forced = subprocess.run(
        [sys.executable, "-c", "import rephoto; print(rephoto.build_info['isa'])"],
        env={**os.environ, "REPHOTO_ISA": "baseline"}, capture_output=True, text=True)
    assert forced.returncode == 0, forced.stderr
    assert forced.stdout.strip() == "baseline"
    bad = subprocess.run([sys.executable, "-c", "import rephoto"],
                         env={**os.environ, "REPHOTO_ISA": "bogus"}, capture_output=True,
                         text=True)
    assert bad.returncode != 0
    assert "REPHOTO_ISA=bogus: must be baseline, avx2 or avx512" in bad.stderr


def test_huge_shapes_are_refused_before_narrowing_or_allocating():
    """Sides beyond 32 bits are not truncated (2^32 + 16 must not become 16), and an image over
    the pixel limit is an Error naming the limit, not a MemoryError."""
    from numpy.lib.stride_tricks import as_strided
    base = np.zeros(3, np.uint8)
    small = np.zeros((16, 16, 3), np.uint8)
    for shape in [(2**32 + 16, 16, 3), (2**33, 1, 3), (100000, 100000, 3)]:
        huge = as_strided(base, shape=shape, strides=(0, 0, 1))
        with pytest.raises(rephoto.Error, match="larger than the limit"):
            rephoto.compare(huge, small if shape[0] != 100000 else huge)


def test_min_alpha_counts_pixels_whose_alpha_reaches_it(pair):
    """A rendering of uniform alpha 0.4: covered for min_alpha 0 (any alpha above 0) and 0.4,
    not at all for 0.5 (closed form: completeness 1, 1, 0)."""
    photo, _ = pair
    rgb = photo[..., :3].astype(np.float32) / 255.0
    render = np.dstack([rgb, np.full(rgb.shape[:2], 0.4, np.float32)])
    assert rephoto.compare(rgb, render, metrics="1-ncc")["completeness"] == 1.0
    assert rephoto.compare(rgb, render, metrics="1-ncc", min_alpha=0.4)["completeness"] == 1.0
    none = rephoto.compare(rgb, render, metrics="1-ncc", min_alpha=0.5)
    assert none["completeness"] == 0.0 and none["evaluated"]["1-ncc"] == 0
    with pytest.raises(ValueError, match="min_alpha"):
        rephoto.compare(rgb, render, min_alpha=1.5)
    with pytest.raises(ValueError, match="min_alpha"):
        rephoto.compare(rgb, render, compat="3dgs", min_alpha=0.5)
