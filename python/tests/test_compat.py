"""--compat presets against independent numpy re-implementations (compat_reference.py)."""
import numpy as np
import pytest

import rephoto
import compat_reference as ref


def test_3dgs_preset_matches_graphdeco_metrics(pair):
    photo, render = (a.astype(np.float64) / 255 for a in pair)
    result = rephoto.compare(*pair, compat="3dgs")
    assert result["psnr"] == pytest.approx(ref.psnr_3dgs(render, photo), abs=1e-6)
    assert result["ssim"] == pytest.approx(ref.ssim_3dgs(render, photo), abs=1e-6)
    assert result["evaluated"]["ssim"] == photo.shape[0] * photo.shape[1]


def test_nerfstudio_preset_matches_torchmetrics(pair):
    photo, render = (a.astype(np.float64) / 255 for a in pair)
    result = rephoto.compare(*pair, compat="nerfstudio")
    assert result["psnr"] == pytest.approx(ref.psnr_torchmetrics(render, photo), abs=1e-6)
    assert result["ssim"] == pytest.approx(ref.ssim_torchmetrics(render, photo), abs=1e-6)


def test_presets_differ_from_rephotos_default_ssim_as_documented(pair):
    own = rephoto.compare(*pair, metrics="ssim")["ssim"]
    zero_padded = rephoto.compare(*pair, compat="3dgs")["ssim"]
    reflected = rephoto.compare(*pair, compat="nerfstudio")["ssim"]
    assert len({round(own, 6), round(zero_padded, 6), round(reflected, 6)}) == 3


def test_rgba_ground_truth_is_composited_over_the_background(pair):
    photo, render = pair
    alpha = np.linspace(0, 255, photo.shape[1]).astype(np.uint8)[None, :].repeat(photo.shape[0], 0)
    rgba = np.dstack([photo, alpha])
    for preset, psnr, ssim in (("3dgs", ref.psnr_3dgs, ref.ssim_3dgs),
                               ("nerfstudio", ref.psnr_torchmetrics, ref.ssim_torchmetrics)):
        for background in ((0, 0, 0), (1, 1, 1)):
            gt = ref.composite(rgba.astype(np.float64) / 255, background)
            # The reference composites in float64, rephoto in float32: agreement ~1e-7.
            gt = gt.astype(np.float32).astype(np.float64)
            pred = render.astype(np.float64) / 255
            result = rephoto.compare(rgba, render, compat=preset, background=background)
            assert result["psnr"] == pytest.approx(psnr(pred, gt), abs=1e-5)
            assert result["ssim"] == pytest.approx(ssim(pred, gt), abs=1e-6)


def test_compat_on_random_float_images():
    rng = np.random.default_rng(3)
    a = rng.random((40, 33, 3), dtype=np.float32)
    b = np.clip(a + rng.normal(0, 0.1, a.shape).astype(np.float32), 0, 1).astype(np.float32)
    for preset, ssim in (("3dgs", ref.ssim_3dgs), ("nerfstudio", ref.ssim_torchmetrics)):
        result = rephoto.compare(a, b, compat=preset)
        assert result["ssim"] == pytest.approx(ssim(b.astype(np.float64), a.astype(np.float64)),
                                               abs=1e-6)


def test_compat_error_images_average_to_the_values():
    """Under compat the psnr image is the squared error (its mean is the MSE of the PSNR) and
    the ssim image the SSIM map (its mean is the SSIM), from the same C++ call as the CLI's."""
    rng = np.random.default_rng(1)
    photo = rng.integers(0, 256, (40, 50, 3), dtype=np.uint8)
    render = rng.integers(0, 256, (40, 50, 3), dtype=np.uint8)
    result = rephoto.compare(photo, render, compat="3dgs", error_images=True)
    squared = result["errors"]["psnr"].astype(np.float64)
    expected = ((photo / 255.0 - render / 255.0) ** 2).mean(axis=2)
    np.testing.assert_allclose(squared, expected, rtol=1e-5, atol=1e-9)
    assert -10 * np.log10(squared.mean()) == pytest.approx(result["psnr"], abs=1e-6)
    assert result["errors"]["ssim"].mean(dtype=np.float64) == pytest.approx(result["ssim"],
                                                                              abs=1e-6)
