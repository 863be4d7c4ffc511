"""Independent numpy re-implementations of the field's PSNR/SSIM evaluation scripts.

Written from the tools' source, not from rephoto's C++:
- graphdeco-inria/gaussian-splatting, commit 15d64e67814605c4d5b24a326aad29da74898acc:
  utils/loss_utils.py (gaussian, create_window, _ssim: F.conv2d with padding=window_size // 2,
  i.e. zero padding; ssim_map.mean()), utils/image_utils.py (psnr = 20 log10(1 / sqrt(mse)),
  mse over all values), metrics.py (images read with PIL, tf.to_tensor, [:3] channels).
- Lightning-AI/torchmetrics, commit 000fc9209c9af6149b74d02ff3e674c6305cae8f:
  src/torchmetrics/functional/image/ssim.py (_ssim_update: gauss_kernel_size =
  int(3.5 sigma + 0.5) * 2 + 1, F.pad(mode="reflect"), valid conv2d, variances clamped at 0,
  mean over the full image), PSNR with data_range=1: 10 log10(1 / mse); as called by
  nerfstudio's ns-eval (models' get_image_metrics_and_images: gt composited with
  renderer_rgb.blend_background, black for "random"/"last_sample").
Images are float64 H x W x 3 in [0, 1].
"""
import numpy as np


def gaussian_window(size=11, sigma=1.5):
    x = np.arange(size) - size // 2
    g = np.exp(-(x ** 2) / (2 * sigma ** 2))
    g /= g.sum()
    return np.outer(g, g)


def conv2d_valid(image, window):
    """Cross-correlation of a 2D image with `window`, 'valid' region only (as F.conv2d)."""
    k = window.shape[0]
    h, w = image.shape[0] - k + 1, image.shape[1] - k + 1
    out = np.zeros((h, w))
    for dy in range(k):
        for dx in range(k):
            out += window[dy, dx] * image[dy:dy + h, dx:dx + w]
    return out


def ssim_3dgs(img1, img2):
    window = gaussian_window()
    pad = 11 // 2
    total = []
    for c in range(3):
        a = np.pad(img1[..., c], pad)  # zeros, as conv2d(padding=5)
        b = np.pad(img2[..., c], pad)
        mu1, mu2 = conv2d_valid(a, window), conv2d_valid(b, window)
        s11 = conv2d_valid(a * a, window) - mu1 ** 2
        s22 = conv2d_valid(b * b, window) - mu2 ** 2
        s12 = conv2d_valid(a * b, window) - mu1 * mu2
        c1, c2 = 0.01 ** 2, 0.03 ** 2
        total.append(((2 * mu1 * mu2 + c1) * (2 * s12 + c2)) /
                     ((mu1 ** 2 + mu2 ** 2 + c1) * (s11 + s22 + c2)))
    return float(np.mean(total))


def ssim_torchmetrics(preds, target, sigma=1.5, data_range=1.0):
    size = int(3.5 * sigma + 0.5) * 2 + 1
    window = gaussian_window(size, sigma)
    pad = (size - 1) // 2
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    total = []
    for c in range(3):
        p = np.pad(preds[..., c], pad, mode="reflect")
        t = np.pad(target[..., c], pad, mode="reflect")
        mp, mt = conv2d_valid(p, window), conv2d_valid(t, window)
        spp = np.maximum(conv2d_valid(p * p, window) - mp ** 2, 0.0)
        stt = np.maximum(conv2d_valid(t * t, window) - mt ** 2, 0.0)
        spt = conv2d_valid(p * t, window) - mp * mt
        total.append(((2 * mp * mt + c1) * (2 * spt + c2)) / ((mp ** 2 + mt ** 2 + c1) * (spp + stt + c2)))
    return float(np.mean(total))


def psnr_3dgs(img1, img2):
    mse = np.mean((img1 - img2) ** 2)
    return float(20 * np.log10(1.0 / np.sqrt(mse)))


def psnr_torchmetrics(preds, target, data_range=1.0):
    mse = np.sum((preds - target) ** 2) / preds.size
    return float(10 * np.log10(data_range ** 2 / mse))


def composite(rgba, background):
    rgb, alpha = rgba[..., :3], rgba[..., 3:4]
    return rgb * alpha + np.asarray(background, dtype=np.float64) * (1 - alpha)
