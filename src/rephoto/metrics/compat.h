// PSNR and SSIM exactly as the evaluation scripts of the novel-view-synthesis field compute
// them ("compat presets"), for numbers comparable with published tables. rephoto's own metrics
// (metrics.h) differ on purpose: masked windows, windows that leave the image not evaluated,
// ill-exposed photo pixels ignored. The presets do none of that: every pixel counts.
//
// Preset "3dgs": graphdeco-inria/gaussian-splatting metrics.py (commit 15d64e6):
//   PSNR  utils/image_utils.py psnr: 20 log10(1 / sqrt(MSE)), MSE over all pixels and the 3
//         channels of the image.
//   SSIM  utils/loss_utils.py ssim: 11x11 Gaussian window, sigma 1.5 (weights
//         exp(-(k-5)^2 / (2 sigma^2)) normalised), conv2d with zero padding of 5 (so windows at
//         the border see zeros), population (co)variances, C1 = 0.01^2, C2 = 0.03^2, the SSIM
//         map averaged over every pixel and channel.
// Preset "nerfstudio": ns-eval (nerfstudio models' get_image_metrics_and_images) with
//   torchmetrics (src/torchmetrics/functional/image/ssim.py, commit 000fc92):
//   PSNR  PeakSignalNoiseRatio(data_range=1): 10 log10(1 / MSE), MSE over all pixels/channels.
//   SSIM  structural_similarity_index_measure(data_range=1): the same Gaussian window, the
//         images reflect-padded by 5 (torch "reflect": mirrored without repeating the edge
//         pixel), variances clamped at 0, the map averaged over every pixel and channel.
//   Earlier torchmetrics releases cropped the 5-pixel border instead (not reproduced here);
//   that equals the Gaussian ssim of metrics.h with every pixel valid.
//
// Ground truth with alpha: both tools composite RGBA ground truth over the background colour
// the model was trained with (3dgs: --white_background, else black; nerfstudio: the model's
// background colour, black for "random"/"last_sample") before comparing: CompositeOverBackground.
// Renderings are taken as RGB (their alpha, if any, is dropped), as both scripts do.
// Values are images in [0,1] as everywhere in rephoto; sums are in double (agreement with a
// float64 numpy re-implementation ~1e-12; the tools themselves compute in float32 on the GPU,
// which differs from both by ~1e-6).
#pragma once

#include <array>
#include <optional>
#include <string_view>

#include "rephoto/core/image.h"

namespace rephoto::metrics {

enum class CompatPreset { k3dgs, kNerfstudio };

// "3dgs" (also "graphdeco", "gaussian-splatting") or "nerfstudio" (also "ns-eval"),
// case-insensitive; std::nullopt if unknown.
std::optional<CompatPreset> ParseCompatPreset(std::string_view name);
std::string_view CompatPresetName(CompatPreset preset);

struct CompatResult {
  double psnr = 0;  // dB; +inf when the MSE is 0
  double mse = 0;   // over all pixels and channels
  double ssim = 0;  // mean of the SSIM map over all pixels and channels
  size_t pixels = 0;
};

// `photo` and `render`: same size, 3 or more channels (only the first three are used; composite
// alpha first). `squared_error` and `ssim_map`, when not null, receive 1-channel images (per
// pixel, averaged over the channels; every pixel defined). Throws Error on size or channel
// mismatch, or (nerfstudio) images smaller than 6x6, where reflect padding is undefined.
// Multi-threaded (ParallelFor over row bands), deterministic for any thread count.
CompatResult ComputeCompatMetrics(CompatPreset preset, const Image& photo, const Image& render,
                                  Image* squared_error = nullptr, Image* ssim_map = nullptr);

// RGB = rgb * alpha + background * (1 - alpha) of a 2- or 4-channel image (grey replicated);
// a 1- or 3-channel image is returned as RGB unchanged (grey replicated).
Image CompositeOverBackground(const Image& image, const std::array<float, 3>& background);

}  // namespace rephoto::metrics
