// `rephoto compare --compat PRESET`: one pair compared the way the field's evaluation scripts
// do (metrics/compat.h), for numbers comparable with published tables. Every pixel counts: no
// masks, no ill-exposure test, no completeness masking of the metrics. A photo (ground truth)
// with alpha is composited over `background`; a rendering's alpha is dropped. Only the
// metrics "psnr", "ssim" and "lpips" (the whole-image value of the lpips package, v0.1,
// normalize=True; CompareOptions::lpips_weights) exist in this mode. Completeness is still reported (rendering
// alpha/black against an all-valid photo) but does not enter the metrics.
//
// Thread safety: pure functions.
#pragma once

#include <array>
#include <string>

#include "rephoto/compare/compare.h"
#include "rephoto/metrics/compat.h"

namespace rephoto::compare {

// Throws UsageError when `metrics` holds anything but psnr, ssim and lpips.
void CheckCompatMetrics(metrics::CompatPreset preset, const std::vector<metrics::Metric>& list);

// The metrics of a compat run, the one rule for `compare --compat`, `evaluate --compat` and
// Python: `requested` when not empty (checked by CheckCompatMetrics; e.g. --metrics
// psnr,ssim,lpips), else the preset's own: psnr, ssim, and lpips when LPIPS weights are given
// (`lpips_weights` not empty, or $REPHOTO_LPIPS_WEIGHTS set: the reference scripts print LPIPS
// too, so a user who has the weights gets it without asking).
std::vector<metrics::Metric> ResolveCompatMetrics(metrics::CompatPreset preset,
                                                  const std::vector<metrics::Metric>& requested,
                                                  const std::filesystem::path& lpips_weights);

// The ImageResult of one pair under `preset` (metrics in options.metrics order; each
// "evaluated" = width * height; psnr's mean is the image's PSNR; lpips's the whole-image
// value). `squared_error` and `ssim_map` as in ComputeCompatMetrics; `lpips_map` (when lpips
// is asked) receives the LPIPS spatial map. Sizes must match (no resizing). Throws Error naming
// the rendering on a size mismatch.
ImageResult CompareCompat(const CompareOptions& options, metrics::CompatPreset preset,
                          const std::string& name, const std::filesystem::path& photo_path,
                          const std::filesystem::path& render_path, const Image& photo,
                          const Image& render, Image* squared_error = nullptr,
                          Image* ssim_map = nullptr, Image* lpips_map = nullptr);

}  // namespace rephoto::compare
