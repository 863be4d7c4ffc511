#include "rephoto/compare/compat_compare.h"

#include <algorithm>

#include "rephoto/core/error.h"
#include "rephoto/metrics/validity.h"

namespace rephoto::compare {

void CheckCompatMetrics(metrics::CompatPreset preset, const std::vector<metrics::Metric>& list) {
  for (metrics::Metric metric : list) {
    REPHOTO_CHECK_USAGE(metric == metrics::Metric::kPsnr || metric == metrics::Metric::kSsim ||
                            metric == metrics::Metric::kLpips,
                        "--compat {}: metric '{}' does not exist in this mode (psnr, ssim, lpips)",
                        metrics::CompatPresetName(preset), metrics::MetricName(metric));
  }
}

std::vector<metrics::Metric> ResolveCompatMetrics(metrics::CompatPreset preset,
                                                  const std::vector<metrics::Metric>& requested,
                                                  const std::filesystem::path& lpips_weights) {
  if (!requested.empty()) {
    CheckCompatMetrics(preset, requested);
    return requested;
  }
  std::vector<metrics::Metric> list = {metrics::Metric::kPsnr, metrics::Metric::kSsim};
  if (!lpips::LpipsWeightsDirectory(lpips_weights).empty()) list.push_back(metrics::Metric::kLpips);
  return list;
}

ImageResult CompareCompat(const CompareOptions& options, metrics::CompatPreset preset,
                          const std::string& name, const std::filesystem::path& photo_path,
                          const std::filesystem::path& render_path, const Image& photo,
                          const Image& render, Image* squared_error, Image* ssim_map,
                          Image* lpips_map) {
  CheckCompatMetrics(preset, options.metrics);
  REPHOTO_CHECK(photo.SameSize(render), "{}: rendering is {}x{} but its photo {} is {}x{}",
                render_path.string(), render.width(), render.height(), photo_path.string(),
                photo.width(), photo.height());
  const Image photo_rgb = metrics::CompositeOverBackground(photo, options.compat_background);
  // A rendering's alpha is dropped, not composited: take its RGB channels as they are.
  Image render_colour;
  const Image* rendered = &render;
  if (render.channels() != 3) {
    render_colour.Resize(render.width(), render.height(), 3);
    const int channels = render.channels();
    for (size_t i = 0; i < render.pixel_count(); ++i) {
      for (int c = 0; c < 3; ++c) {
        render_colour.data()[3 * i + c] = render.data()[i * channels + (channels <= 2 ? 0 : c)];
      }
    }
    rendered = &render_colour;
  }
  const metrics::CompatResult values =
      metrics::ComputeCompatMetrics(preset, photo_rgb, *rendered, squared_error, ssim_map);

  ImageResult result;
  result.name = name;
  result.photo = photo_path;
  result.render = render_path;
  result.width = photo.width();
  result.height = photo.height();
  const Mask all_valid(photo.width(), photo.height(), 1, 1);
  result.completeness = metrics::ComputeCompleteness(all_valid, metrics::RephotoValidity(render),
                                                     options.metric_options.window);
  // lpips: the whole-image value on the same inputs (the composited photo, the rendering's RGB).
  double lpips_whole = 0;
  if (std::find(options.metrics.begin(), options.metrics.end(), metrics::Metric::kLpips) !=
      options.metrics.end()) {
    lpips_whole = LpipsModelFor(options)
                      ->Compute(photo_rgb, *rendered, nullptr, lpips_map, /*masked=*/false)
                      .whole;
  }
  for (metrics::Metric metric : options.metrics) {
    const double value = metric == metrics::Metric::kPsnr   ? values.psnr
                         : metric == metrics::Metric::kSsim ? values.ssim
                                                            : lpips_whole;
    result.metrics.push_back({value, values.pixels});
  }
  return result;
}

}  // namespace rephoto::compare
