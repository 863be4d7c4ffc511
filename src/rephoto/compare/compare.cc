#include "rephoto/compare/compare.h"

#include <signal.h>
#include <tbb/enumerable_thread_specific.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <exception>
#include <functional>
#include <future>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "rephoto/compare/compat_compare.h"
#include "rephoto/compare/error_images.h"
#include "rephoto/compare/resample.h"
#include "rephoto/core/background_worker.h"
#include "rephoto/core/colormap.h"
#include "rephoto/core/file.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/progress.h"
#include "rephoto/io/csv.h"
#include "rephoto/io/image_io.h"
#include "rephoto/run/records.h"
#include "rephoto/run/run_folder.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/split/split.h"

#ifndef REPHOTO_VERSION
#define REPHOTO_VERSION "unknown"
#endif

namespace rephoto::compare {
namespace fs = std::filesystem;
using metrics::Metric;

std::string ToolVersion() { return REPHOTO_VERSION; }

std::shared_ptr<const lpips::LpipsModel> LpipsModelFor(const CompareOptions& options) {
  return lpips::LpipsModel::LoadShared(lpips::LpipsWeightsDirectory(options.lpips_weights),
                                       options.lpips_net);
}

void CompareOptions::Check() const {
  REPHOTO_CHECK(!photos.empty(), "compare: no photo folder given");
  REPHOTO_CHECK(!renders.empty(), "compare: no rendering folder given");
  REPHOTO_CHECK(!out.empty(), "compare: no output folder given");
  REPHOTO_CHECK(!metrics.empty(), "compare: no metric selected");
  std::set<Metric> seen;
  for (Metric metric : metrics) {
    REPHOTO_CHECK(seen.insert(metric).second, "compare: metric '{}' is listed twice",
                  metrics::MetricName(metric));
  }
  REPHOTO_CHECK(metric_options.window >= 3 && metric_options.window % 2 == 1,
                "compare: the window must be odd and at least 3 (got {})", metric_options.window);
  REPHOTO_CHECK(metric_options.ssim_window >= 3 && metric_options.ssim_window % 2 == 1,
                "compare: the SSIM window must be odd and at least 3 (got {})",
                metric_options.ssim_window);
  REPHOTO_CHECK(min_alpha >= 0 && min_alpha <= 1,
                "compare: the minimum alpha must be in [0, 1] (got {})", min_alpha);
  REPHOTO_CHECK(!compat || min_alpha == 0,
                "compare: the minimum alpha does not apply in compat mode (no masks)");
  // The weights of lpips are loaded (once per process) before any pair is read, so that a
  // missing file fails at once with the message saying how to get it.
  if (std::find(metrics.begin(), metrics.end(), Metric::kLpips) != metrics.end()) {
    LpipsModelFor(*this);
  }
  REPHOTO_CHECK(exposure.dark_threshold < exposure.saturated_threshold,
                "compare: the dark threshold ({}) must be below the saturation threshold ({})",
                exposure.dark_threshold, exposure.saturated_threshold);
}

std::pair<float, float> ErrorColourRange(Metric metric) {
  switch (metric) {
    case Metric::kOneMinusNcc:
      return {0.f, 1.f};
    case Metric::kCbCr:
      return {0.f, 0.25f};
    case Metric::kZssd:
      return {0.f, 0.05f};
    case Metric::kDssim:
      return {0.f, 0.5f};
    case Metric::kCensus:
      return {0.f, 0.5f};
    case Metric::kIcid:
      return {0.f, 0.5f};
    case Metric::kPsnr:
      return {0.f, 0.0625f};
    case Metric::kSsim:
      return {1.f, 0.f};
    case Metric::kLpips:
      return {0.f, 0.5f};
  }
  return {0.f, 1.f};
}

bool WritesErrorImage(const CompareOptions& options, metrics::Metric metric) {
  return options.write_error_images &&
         (options.error_image_metrics.empty() ||
          std::find(options.error_image_metrics.begin(), options.error_image_metrics.end(),
                    metric) != options.error_image_metrics.end());
}

void ColourErrorImage(const Image& error, float low, float high, std::vector<uint8_t>* rgba) {
  REPHOTO_CHECK(error.channels() == 1, "ColourErrorImage: expected 1 channel, got {}",
                error.channels());
  REPHOTO_CHECK(low != high, "ColourErrorImage: empty range [{}, {}]", low, high);
  rgba->resize(error.pixel_count() * 4);
  ParallelFor(0, static_cast<int64_t>(error.pixel_count()), 1 << 15, [&](int64_t b, int64_t e) {
    ColourErrorValues(error.data() + b, static_cast<size_t>(e - b), low, high,
                      rgba->data() + 4 * b);
  });
}

// Buffers reused from pair to pair by the comparison itself.
struct CompareWorkspace::Buffers {
  Image render_rgb;  // a rendering to be resized, as RGB floats
  Image render_resized;
  Mask photo_alpha;
  Mask render_valid_resized;
  std::vector<metrics::MetricResult> results;
  std::vector<uint8_t> rgba;
};

CompareWorkspace::CompareWorkspace() : buffers(std::make_unique<Buffers>()) {}
CompareWorkspace::~CompareWorkspace() = default;

namespace {

using Workspace = CompareWorkspace::Buffers;

// A pair with everything known before its pixels are read.
struct PlannedPair {
  ImagePair files;
  fs::path render_mask;  // empty = none
  fs::path photo_mask;   // empty = none
  io::ImageHeader photo_header;
  io::ImageHeader render_header;
};

// The decoded files of one pair; two of these alternate so that one can be filled while the
// other is compared.
struct PairImages {
  // 8-bit files (JPEG, 8-bit PNG) are kept as stored, 4 times smaller than floats; the
  // metrics convert their rows band by band. Others (16-bit PNG, EXR, PFM) are floats.
  Image photo;
  Image8 photo8;
  bool photo_is_8bit = false;
  Image render;
  Image8 render8;
  bool render_is_8bit = false;
  Mask render_mask;
  Mask photo_mask;
};

std::string SizeText(const io::ImageHeader& h) { return fmt::format("{}x{}", h.width, h.height); }

std::vector<PlannedPair> PlanPairs(const CompareOptions& options, const Pairing& pairing) {
  std::map<std::string, fs::path> render_masks, photo_masks;
  if (!options.render_masks.empty()) {
    render_masks = ImagesByStem(ListImages(options.render_masks, "rendering masks"));
  }
  if (!options.photo_masks.empty()) {
    photo_masks = ImagesByStem(ListImages(options.photo_masks, "photo masks"));
  }
  std::vector<PlannedPair> plan;
  plan.reserve(pairing.pairs.size());
  for (const ImagePair& pair : pairing.pairs) {
    PlannedPair planned;
    planned.files = pair;
    planned.photo_header = io::ReadImageHeader(pair.photo);
    planned.render_header = io::ReadImageHeader(pair.render);
    const io::ImageHeader& ph = planned.photo_header;
    const io::ImageHeader& rh = planned.render_header;
    if (!options.resize) {
      REPHOTO_CHECK(ph.width == rh.width && ph.height == rh.height,
                    "{}: rendering is {} but its photo {} is {} (--resize rescales renderings "
                    "to the photo size)",
                    pair.render.string(), SizeText(rh), pair.photo.string(), SizeText(ph));
    }
    if (!options.render_masks.empty()) {
      auto it = render_masks.find(pair.name);
      REPHOTO_CHECK(it != render_masks.end(), "{}: no mask named '{}' for rendering {}",
                    options.render_masks.string(), pair.name, pair.render.string());
      planned.render_mask = it->second;
      const io::ImageHeader mh = io::ReadImageHeader(it->second);
      REPHOTO_CHECK(mh.width == rh.width && mh.height == rh.height,
                    "{}: mask is {} but its rendering {} is {}", it->second.string(), SizeText(mh),
                    pair.render.string(), SizeText(rh));
    }
    if (!options.photo_masks.empty()) {
      auto it = photo_masks.find(pair.name);
      REPHOTO_CHECK(it != photo_masks.end(), "{}: no mask named '{}' for photo {}",
                    options.photo_masks.string(), pair.name, pair.photo.string());
      planned.photo_mask = it->second;
      const io::ImageHeader mh = io::ReadImageHeader(it->second);
      REPHOTO_CHECK(mh.width == ph.width && mh.height == ph.height,
                    "{}: mask is {} but its photo {} is {}", it->second.string(), SizeText(mh),
                    pair.photo.string(), SizeText(ph));
    }
    plan.push_back(std::move(planned));
  }
  return plan;
}

void LoadPair(const PlannedPair& pair, PairImages* images) {
  auto check = [](const fs::path& path, const auto& image, const io::ImageHeader& header) {
    REPHOTO_CHECK(image.width() == header.width && image.height() == header.height,
                  "{}: decoded size {}x{} differs from the header's {}", path.string(),
                  image.width(), image.height(), SizeText(header));
  };
  images->photo_is_8bit = io::ReadImage8(pair.files.photo, &images->photo8, &images->photo);
  if (images->photo_is_8bit) {
    check(pair.files.photo, images->photo8, pair.photo_header);
  } else {
    check(pair.files.photo, images->photo, pair.photo_header);
  }
  images->render_is_8bit = io::ReadImage8(pair.files.render, &images->render8, &images->render);
  if (images->render_is_8bit) {
    check(pair.files.render, images->render8, pair.render_header);
  } else {
    check(pair.files.render, images->render, pair.render_header);
  }
  if (!pair.render_mask.empty()) io::ReadMask(pair.render_mask, &images->render_mask);
  if (!pair.photo_mask.empty()) io::ReadMask(pair.photo_mask, &images->photo_mask);
}

// The colour of `image` for the metrics: the image itself when it has 3 or 4 channels (the
// metrics ignore a fourth), else grey replicated into `rgb`. When `alpha_valid` is given and the
// image has alpha (2 or 4 channels), it receives alpha > 0 and true is returned.
template <typename T>
const ImageT<T>& ColourOf(const ImageT<T>& image, ImageT<T>* rgb, Mask* alpha_valid,
                          bool* has_alpha) {
  const int channels = image.channels();
  REPHOTO_CHECK(channels >= 1 && channels <= 4, "unsupported channel count {}", channels);
  *has_alpha = alpha_valid != nullptr && (channels == 2 || channels == 4);
  if (*has_alpha) alpha_valid->Resize(image.width(), image.height(), 1);
  const bool grey = channels <= 2;
  if (grey) rgb->Resize(image.width(), image.height(), 3);
  if (!grey && !*has_alpha) return image;
  ParallelFor(0, static_cast<int64_t>(image.pixel_count()), 1 << 15, [&](int64_t b, int64_t e) {
    const T* in = image.data();
    T* out = grey ? rgb->data() : nullptr;
    uint8_t* alpha = *has_alpha ? alpha_valid->data() : nullptr;
    for (int64_t i = b; i < e; ++i) {
      const T* px = in + i * channels;
      if (out) out[3 * i] = out[3 * i + 1] = out[3 * i + 2] = px[0];
      if (alpha) alpha[i] = px[channels - 1] > T(0) ? 1 : 0;
    }
  });
  return grey ? *rgb : image;
}

template <typename T>
bool HasAlpha(const ImageT<T>& image) {
  return image.channels() == 2 || image.channels() == 4;
}

// CompareOptions::min_alpha: 1 where the alpha of `image` (2 or 4 channels; 8-bit v stands for
// v / 255 as in metrics/validity.cc) is at least `min_alpha`, compared in float as `rephoto
// evaluate` compared a Gaussian rendering's PNG alpha before the rule moved here.
template <typename T>
Mask AlphaReaches(const ImageT<T>& image, double min_alpha) {
  const int channels = image.channels();
  const float threshold = static_cast<float>(min_alpha);
  Mask valid(image.width(), image.height(), 1);
  ParallelFor(0, static_cast<int64_t>(image.pixel_count()), 1 << 15, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const T a = image.data()[i * channels + channels - 1];
      float alpha;
      if constexpr (std::is_same_v<T, uint8_t>) {
        alpha = static_cast<float>(a) / 255.f;
      } else {
        alpha = a;
      }
      valid.data()[i] = alpha >= threshold ? 1 : 0;
    }
  });
  return valid;
}

// RGB floats of `image` (alpha dropped, grey replicated) in `rgb`, the values io::ReadImage
// gives for the same file when `image` holds 8-bit samples.
template <typename T>
void ToFloatRgb(const ImageT<T>& image, Image* rgb) {
  const int channels = image.channels();
  rgb->Resize(image.width(), image.height(), 3);
  ParallelFor(0, static_cast<int64_t>(image.pixel_count()), 1 << 15, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const T* px = image.data() + i * channels;
      for (int c = 0; c < 3; ++c) {
        const T v = px[channels <= 2 ? 0 : c];
        if constexpr (std::is_same_v<T, uint8_t>) {
          rgb->data()[3 * i + c] = static_cast<float>(v) / 255.f;
        } else {
          rgb->data()[3 * i + c] = v;
        }
      }
    }
  });
}

// The image as float values in [0, 1] (8-bit samples / 255); a float image as it is.
template <typename T>
const Image& AsFloatImage(const ImageT<T>& image, Image* scratch) {
  if constexpr (std::is_same_v<T, float>) {
    return image;
  } else {
    *scratch = Image(image.width(), image.height(), image.channels());
    const size_t n = static_cast<size_t>(image.width()) * image.height() * image.channels();
    for (size_t i = 0; i < n; ++i) scratch->data()[i] = static_cast<float>(image.data()[i]) / 255.f;
    return *scratch;
  }
}

// ComparePhotoAndRender for float (Image) or 8-bit (Image8) photos and renderings.
template <typename P, typename R>
ImageResult CompareImages(const CompareOptions& options, const std::string& name,
                          const fs::path& photo_path, const fs::path& render_path,
                          const ImageT<P>& photo, const ImageT<R>& render, const Mask* photo_mask,
                          const Mask* render_mask, const fs::path& error_folder,
                          std::vector<Image>* error_images, Workspace* ws) {
  if (options.compat) {  // the numbers other tools publish (compat_compare.h)
    Image photo_float, render_float, squared_error, ssim_map, lpips_map;
    ImageResult result = CompareCompat(
        options, *options.compat, name, photo_path, render_path,
        AsFloatImage(photo, &photo_float), AsFloatImage(render, &render_float),
        error_images ? &squared_error : nullptr, error_images ? &ssim_map : nullptr,
        error_images ? &lpips_map : nullptr);
    if (error_images) {
      error_images->clear();
      for (metrics::Metric metric : options.metrics) {
        error_images->push_back(metric == metrics::Metric::kPsnr   ? squared_error
                                : metric == metrics::Metric::kSsim ? ssim_map
                                                                   : lpips_map);
      }
    }
    return result;
  }
  if (!options.resize) {
    REPHOTO_CHECK(photo.SameSize(render),
                  "{}: rendering is {}x{} but its photo {} is {}x{} (--resize rescales "
                  "renderings to the photo size)",
                  render_path.string(), render.width(), render.height(), photo_path.string(),
                  photo.width(), photo.height());
  }
  REPHOTO_CHECK(!photo_mask || photo_mask->SameSize(photo), "{}: photo mask is {}x{}, photo {}x{}",
                photo_path.string(), photo_mask ? photo_mask->width() : 0,
                photo_mask ? photo_mask->height() : 0, photo.width(), photo.height());
  REPHOTO_CHECK(!render_mask || render_mask->SameSize(render),
                "{}: rendering mask is {}x{}, rendering {}x{}", render_path.string(),
                render_mask ? render_mask->width() : 0, render_mask ? render_mask->height() : 0,
                render.width(), render.height());
  ImageResult result;
  result.name = name;
  result.photo = photo_path;
  result.render = render_path;
  const int width = photo.width(), height = photo.height();
  result.width = width;
  result.height = height;

  // Photo validity: user mask AND photo alpha, then exposure.
  bool photo_has_alpha = false;
  thread_local ImageT<P> photo_grey;
  const ImageT<P>& photo_rgb = ColourOf(photo, &photo_grey, &ws->photo_alpha, &photo_has_alpha);
  Mask photo_valid;
  if (photo_mask && photo_has_alpha) {
    photo_valid = metrics::PhotoValidity(
        photo_rgb, metrics::CombineMasks(*photo_mask, ws->photo_alpha), options.exposure);
  } else {
    const Mask& user_mask = photo_mask ? *photo_mask : (photo_has_alpha ? ws->photo_alpha : Mask());
    photo_valid = metrics::PhotoValidity(photo_rgb, user_mask, options.exposure);
  }

  // Rendering validity (alpha / black / explicit mask) at the rendering's own size.
  Mask render_valid = render_mask == nullptr && options.min_alpha > 0 && HasAlpha(render)
                          ? AlphaReaches(render, options.min_alpha)
                          : metrics::RephotoValidity(render, render_mask ? *render_mask : Mask());
  bool render_has_alpha = false;
  thread_local ImageT<R> render_grey;
  const ImageT<R>* render_rgb = &ColourOf(render, &render_grey, nullptr, &render_has_alpha);
  metrics::RgbView render_view(*render_rgb);
  if (!render.SameSize(photo)) {
    ToFloatRgb(render, &ws->render_rgb);
    ResizeImage(ws->render_rgb, width, height, &ws->render_resized);
    ResizeMask(render_valid, width, height, &ws->render_valid_resized);
    render_view = metrics::RgbView(ws->render_resized);
    std::swap(render_valid, ws->render_valid_resized);
    result.resized = true;
  }

  result.completeness =
      metrics::ComputeCompleteness(photo_valid, render_valid, options.metric_options.window);
  const Mask valid = metrics::CombineMasks(photo_valid, render_valid);
  photo_valid = Mask();
  if (result.resized) {
    std::swap(render_valid, ws->render_valid_resized);  // keep the buffer
  } else {
    render_valid = Mask();
  }

  // lpips (a network over the whole image, lpips/lpips.h) is computed apart from the band
  // metrics; `band_metrics` are the others, in options.metrics order.
  std::vector<Metric> band_metrics;
  for (Metric metric : options.metrics) {
    if (!metrics::IsNetworkMetric(metric)) band_metrics.push_back(metric);
  }
  const bool want_lpips = band_metrics.size() != options.metrics.size();
  std::vector<Image> band_errors;

  // The error images are written while they are made: EXR rows band by band, then each PNG
  // from its EXR's rows read back, one at a time, so that no whole error image is held.
  std::vector<std::unique_ptr<ErrorExrWriter>> exrs;
  std::vector<size_t> exr_metric;  // exrs[j] is of band_metrics[exr_metric[j]]
  const auto stem = [&](metrics::Metric metric) {
    return fmt::format("{}.{}", name, metrics::MetricName(metric));
  };
  if (options.write_error_images && !error_images) {
    for (size_t i = 0; i < band_metrics.size(); ++i) {
      if (!WritesErrorImage(options, band_metrics[i])) continue;
      exrs.push_back(std::make_unique<ErrorExrWriter>(
          error_folder / (stem(band_metrics[i]) + ".exr"), width, height));
      exr_metric.push_back(i);
    }
  }
  metrics::ErrorBandSink sink;
  if (!exrs.empty()) {
    sink = [&](int y0, int y1, std::span<const float* const> rows) {
      for (size_t j = 0; j < exrs.size(); ++j) exrs[j]->WriteRows(y0, y1, rows[exr_metric[j]]);
    };
  } else if (error_images) {  // whole images in memory (CompareInMemory)
    band_errors.resize(band_metrics.size());
    for (Image& error : band_errors) error.Resize(width, height, 1);
    sink = [&](int y0, int y1, std::span<const float* const> rows) {
      const size_t count = static_cast<size_t>(y1 - y0) * width;
      for (size_t i = 0; i < rows.size(); ++i) {
        std::memcpy(band_errors[i].row(y0), rows[i], count * sizeof(float));
      }
    };
  }
  if (!band_metrics.empty()) {
    metrics::ComputeMetricsInBands(photo_rgb, render_view, valid, band_metrics,
                                   options.metric_options, sink, &ws->results);
  }
  for (size_t j = 0; j < exrs.size(); ++j) {
    const metrics::Metric metric = band_metrics[exr_metric[j]];
    const auto [low, high] = ErrorColourRange(metric);
    WriteErrorPng(*exrs[j], width, height, low, high, error_folder / (stem(metric) + ".png"),
                  &ws->rgba);
    exrs[j]->Commit();
    exrs[j].reset();
  }

  // lpips: the spatial map's mean over the joint validity mask; its error image is that map,
  // NaN where not valid.
  MetricValue lpips_value;
  Image lpips_map;
  if (want_lpips) {
    const bool write_map = options.write_error_images && !error_images &&
                           WritesErrorImage(options, Metric::kLpips);
    const bool need_map = write_map || error_images != nullptr;
    const lpips::LpipsValue value = LpipsModelFor(options)->Compute(
        metrics::RgbView(photo_rgb), render_view, &valid, need_map ? &lpips_map : nullptr);
    lpips_value = {value.masked, value.masked_pixels};
    if (need_map && !valid.empty()) {
      for (size_t i = 0; i < lpips_map.pixel_count(); ++i) {
        if (!valid.data()[i]) lpips_map.data()[i] = std::numeric_limits<float>::quiet_NaN();
      }
    }
    if (write_map) {
      ErrorExrWriter exr(error_folder / (stem(Metric::kLpips) + ".exr"), width, height);
      exr.WriteRows(0, height, lpips_map.data());
      const auto [low, high] = ErrorColourRange(Metric::kLpips);
      WriteErrorPng(exr, width, height, low, high,
                    error_folder / (stem(Metric::kLpips) + ".png"), &ws->rgba);
      exr.Commit();
    }
  }

  // Values (and in-memory error images) in options.metrics order.
  if (error_images) error_images->clear();
  size_t band = 0;
  for (Metric metric : options.metrics) {
    if (metrics::IsNetworkMetric(metric)) {
      result.metrics.push_back(lpips_value);
      if (error_images) error_images->push_back(std::move(lpips_map));
    } else {
      result.metrics.push_back({ws->results[band].mean, ws->results[band].evaluated});
      if (error_images) error_images->push_back(std::move(band_errors[band]));
      ++band;
    }
  }
  return result;
}

}  // namespace

template <typename P, typename R>
ImageResult ComparePhotoAndRender(const CompareOptions& options, const std::string& name,
                                  const fs::path& photo_path, const fs::path& render_path,
                                  const ImageT<P>& photo, const ImageT<R>& render,
                                  const Mask* photo_mask, const Mask* render_mask,
                                  const fs::path& error_folder, CompareWorkspace* workspace,
                                  std::vector<Image>* error_images) {
  return CompareImages(options, name, photo_path, render_path, photo, render, photo_mask,
                       render_mask, error_folder, error_images, workspace->buffers.get());
}

#define REPHOTO_COMPARE_PHOTO_AND_RENDER(P, R)                                       \
  template ImageResult ComparePhotoAndRender<P, R>(                                  \
      const CompareOptions&, const std::string&, const fs::path&, const fs::path&,   \
      const ImageT<P>&, const ImageT<R>&, const Mask*, const Mask*, const fs::path&, \
      CompareWorkspace*, std::vector<Image>*);
REPHOTO_COMPARE_PHOTO_AND_RENDER(float, float)
REPHOTO_COMPARE_PHOTO_AND_RENDER(float, uint8_t)
REPHOTO_COMPARE_PHOTO_AND_RENDER(uint8_t, float)
REPHOTO_COMPARE_PHOTO_AND_RENDER(uint8_t, uint8_t)
#undef REPHOTO_COMPARE_PHOTO_AND_RENDER

template <typename P, typename R>
ImageResult CompareInMemory(const CompareOptions& options, const ImageT<P>& photo,
                            const ImageT<R>& render, const Mask* photo_mask,
                            const Mask* render_mask, std::vector<Image>* error_images,
                            CompareWorkspace* workspace) {
  REPHOTO_CHECK_USAGE(!options.metrics.empty(), "no metric selected");
  std::set<Metric> seen;
  for (Metric metric : options.metrics) {
    REPHOTO_CHECK_USAGE(seen.insert(metric).second, "metric '{}' is listed twice",
                        metrics::MetricName(metric));
  }
  REPHOTO_CHECK_USAGE(
      !options.compat || (!photo_mask && !render_mask),
      "compat {}: masks do not exist in this mode",
      options.compat ? metrics::CompatPresetName(*options.compat) : std::string_view());
  CompareOptions in_memory = options;
  in_memory.write_error_images = false;  // nothing is written, whatever `options` says
  return CompareImages(in_memory, "", "photo", "render", photo, render, photo_mask, render_mask, {},
                       error_images, workspace->buffers.get());
}

#define REPHOTO_COMPARE_IN_MEMORY(P, R)                                                  \
  template ImageResult CompareInMemory<P, R>(const CompareOptions&, const ImageT<P>&,    \
                                             const ImageT<R>&, const Mask*, const Mask*, \
                                             std::vector<Image>*, CompareWorkspace*);
REPHOTO_COMPARE_IN_MEMORY(float, float)
REPHOTO_COMPARE_IN_MEMORY(float, uint8_t)
REPHOTO_COMPARE_IN_MEMORY(uint8_t, float)
REPHOTO_COMPARE_IN_MEMORY(uint8_t, uint8_t)
#undef REPHOTO_COMPARE_IN_MEMORY

namespace {

ImageResult ComparePair(const CompareOptions& options, const PlannedPair& pair,
                        const PairImages& images, const fs::path& error_folder,
                        CompareWorkspace* workspace) {
  const Mask* photo_mask = pair.photo_mask.empty() ? nullptr : &images.photo_mask;
  const Mask* render_mask = pair.render_mask.empty() ? nullptr : &images.render_mask;
  Workspace* ws = workspace->buffers.get();
  const auto run = [&](const auto& photo, const auto& render) {
    return CompareImages(options, pair.files.name, pair.files.photo, pair.files.render, photo,
                         render, photo_mask, render_mask, error_folder, nullptr, ws);
  };
  if (images.photo_is_8bit) {
    return images.render_is_8bit ? run(images.photo8, images.render8)
                                 : run(images.photo8, images.render);
  }
  return images.render_is_8bit ? run(images.photo, images.render8)
                               : run(images.photo, images.render);
}

// ------------------------------------------------------------------------------- outputs

std::string MissingStatus(Missing missing) {
  return missing == Missing::kRender ? "missing_render" : "missing_photo";
}

}  // namespace

std::vector<std::string> PerImageCsvHeader(const std::vector<Metric>& metric_list) {
  std::vector<std::string> header = {"name",
                                     "status",
                                     "photo",
                                     "render",
                                     "width",
                                     "height",
                                     "resized",
                                     "completeness",
                                     "valid_photo_windows",
                                     "valid_both_windows"};
  for (Metric metric : metric_list) {
    header.emplace_back(metrics::MetricName(metric));
    header.push_back(std::string(metrics::MetricName(metric)) + "_evaluated");
  }
  return header;
}

std::vector<std::string> PerImageCsvRow(const ImageResult& image) {
  std::vector<std::string> row = {image.name,
                                  "ok",
                                  image.photo.string(),
                                  image.render.string(),
                                  std::to_string(image.width),
                                  std::to_string(image.height),
                                  image.resized ? "1" : "0",
                                  io::CsvNumber(image.completeness.value),
                                  std::to_string(image.completeness.valid_photo),
                                  std::to_string(image.completeness.valid_both)};
  for (const MetricValue& value : image.metrics) {
    row.push_back(io::CsvNumber(value.mean));
    row.push_back(std::to_string(value.evaluated));
  }
  return row;
}

namespace {

std::string PerImageCsv(const CompareOptions& options, const CompareResult& result) {
  io::CsvWriter csv;
  const std::vector<std::string> header = PerImageCsvHeader(options.metrics);
  csv.AddRow(header);
  const size_t columns = header.size();
  size_t i = 0, m = 0;
  while (i < result.images.size() || m < result.missing.size()) {
    std::vector<std::string> row;
    row.reserve(columns);
    if (m == result.missing.size() ||
        (i < result.images.size() && result.images[i].name < result.missing[m].name)) {
      row = PerImageCsvRow(result.images[i++]);
    } else {
      const MissingImage& missing = result.missing[m++];
      row = {missing.name, MissingStatus(missing.missing),
             missing.missing == Missing::kRender ? missing.present.string() : "",
             missing.missing == Missing::kPhoto ? missing.present.string() : ""};
      row.resize(columns);
    }
    csv.AddRow(row);
  }
  return csv.text();
}

using Json = nlohmann::ordered_json;

using run::JsonNumber;

Json SummaryJson(const Summary& s) { return run::SummaryJson(s, "images"); }

Json OptionalPath(const fs::path& path) {
  if (path.empty()) return nullptr;
  return path.string();
}

std::string SummaryJsonText(const CompareOptions& options, const CompareResult& result) {
  const metrics::MetricOptions& mo = options.metric_options;
  Json j;
  j["schema"] = "rephoto.compare/1";
  j["tool"] = {{"name", "rephoto"}, {"version", ToolVersion()}};
  Json metric_names = Json::array();
  for (Metric metric : options.metrics) metric_names.push_back(metrics::MetricName(metric));
  j["parameters"] = {
      {"photos", options.photos.string()},
      {"renders", options.renders.string()},
      {"render_masks", OptionalPath(options.render_masks)},
      {"photo_masks", OptionalPath(options.photo_masks)},
      {"metrics", metric_names},
      {"window", mo.window},
      {"completeness_window", mo.window},
      {"ssim_mode", mo.ssim_gaussian ? "gaussian" : "uniform"},
      {"ssim_window", mo.ssim_window},
      {"ssim_sigma", mo.ssim_sigma},
      {"ncc_flat_threshold", mo.ncc_flat_threshold},
      {"icid_window", mo.icid_window},
      {"icid_sigma", mo.icid_sigma},
      {"dark_threshold", options.exposure.dark_threshold},
      {"saturated_threshold", options.exposure.saturated_threshold},
      {"resize", options.resize},
      {"error_images", options.write_error_images},
      {"compat", options.compat ? Json(metrics::CompatPresetName(*options.compat)) : Json()}};
  if (options.compat) j["parameters"]["compat_background"] = options.compat_background;
  // Only when set, so that the summaries of runs without them stay as they were.
  if (!options.image_list.empty()) j["parameters"]["image_list"] = options.image_list.string();
  if (options.min_alpha > 0) j["parameters"]["min_alpha"] = options.min_alpha;
  size_t missing_render = 0, missing_photo = 0, resized = 0;
  for (const MissingImage& m : result.missing) {
    (m.missing == Missing::kRender ? missing_render : missing_photo)++;
  }
  for (const ImageResult& image : result.images) resized += image.resized ? 1 : 0;
  j["counts"] = {{"photos", result.photo_count},
                 {"renders", result.render_count},
                 {"compared", result.images.size()},
                 {"missing", result.missing.size()},
                 {"missing_render", missing_render},
                 {"missing_photo", missing_photo},
                 {"resized", resized}};
  j["completeness"] = SummaryJson(result.completeness);
  Json metrics_json = Json::object();
  for (const MetricSummary& summary : result.metrics) {
    Json m = SummaryJson(summary.over_images);
    m["pooled"] = JsonNumber(summary.pooled);
    m["evaluated"] = summary.evaluated;
    m["higher_is_better"] = metrics::HigherIsBetter(summary.metric);
    const auto [low, high] = ErrorColourRange(summary.metric);
    m["error_png_range"] = {low, high};
    metrics_json[std::string(metrics::MetricName(summary.metric))] = m;
  }
  j["metrics"] = metrics_json;
  Json missing = Json::array();
  for (const MissingImage& m : result.missing) {
    missing.push_back({{"name", m.name},
                       {"missing", m.missing == Missing::kRender ? "render" : "photo"},
                       {"present", m.present.string()}});
  }
  j["missing"] = missing;
  j["files"] = {{"per_image", "per_image.csv"},
                {"error_images",
                 options.write_error_images ? Json("errors/<name>.<metric>.exr|png") : Json()}};
  return j.dump(2) + "\n";
}

}  // namespace

std::vector<MetricSummary> SummarizeMetrics(const std::vector<Metric>& metric_list,
                                            const std::vector<ImageResult>& images) {
  std::vector<MetricSummary> summaries;
  for (size_t k = 0; k < metric_list.size(); ++k) {
    MetricSummary s;
    s.metric = metric_list[k];
    std::vector<double> means;
    double weighted = 0;
    for (const ImageResult& image : images) {
      const MetricValue& v = image.metrics[k];
      means.push_back(v.mean);
      if (v.evaluated == 0 || std::isnan(v.mean)) continue;
      // PSNR's mean is 10 log10(1 / MSE): pool the MSEs, not the decibels.
      const double pooled_term =
          s.metric == Metric::kPsnr ? std::pow(10.0, -v.mean / 10.0) : v.mean;
      weighted += pooled_term * static_cast<double>(v.evaluated);
      s.evaluated += v.evaluated;
    }
    s.over_images = Summarize(means);
    if (s.evaluated == 0) {
      s.pooled = std::numeric_limits<double>::quiet_NaN();
    } else {
      s.pooled = weighted / static_cast<double>(s.evaluated);
      if (s.metric == Metric::kPsnr) s.pooled = 10.0 * std::log10(1.0 / s.pooled);
    }
    summaries.push_back(s);
  }
  return summaries;
}

namespace {

// --------------------------------------------------------------------------- run folder

constexpr const char* kStagingPrefix = ".rephoto-staging-";

// Removes staging folders left by killed runs (their process no longer exists).
void RemoveStaleStaging(const fs::path& out) {
  std::error_code ec;
  for (fs::directory_iterator it(out, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(kStagingPrefix, 0) != 0) continue;
    const long pid = std::strtol(name.c_str() + std::strlen(kStagingPrefix), nullptr, 10);
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == -1 && errno == ESRCH) {
      std::error_code remove_ec;
      fs::remove_all(it->path(), remove_ec);
    }
  }
}

// A compare output folder written before run folders were marked: nothing but compare's files.
bool IsLegacyCompareRun(const fs::path& dir) {
  std::error_code ec;
  bool has_summary = false;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    has_summary |= name == "summary.json";
    if (name != "summary.json" && name != "per_image.csv" && name != "errors" &&
        name.rfind(kStagingPrefix, 0) != 0) {
      return false;
    }
  }
  return has_summary;
}

void Rename(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::rename(from, to, ec);
  REPHOTO_CHECK(!ec, "{}: cannot move into place: {}", to.string(), ec.message());
}

// Moves the staged outputs into `out`; summary.json last, so that its presence means a
// complete run.
void CommitRun(const fs::path& staging, const fs::path& out, bool error_images) {
  std::error_code ec;
  if (fs::exists(out / "errors", ec)) Rename(out / "errors", staging / "previous-errors");
  if (error_images) Rename(staging / "errors", out / "errors");
  Rename(staging / "per_image.csv", out / "per_image.csv");
  Rename(staging / "summary.json", out / "summary.json");
  fs::remove_all(staging, ec);
}

// The stem a list name stands for: its file name without an image extension.
std::string ListedStem(const std::string& name) {
  const fs::path file = fs::path(name).filename();
  return io::IsImageFile(file) ? file.stem().string() : file.string();
}

// CompareOptions::image_list: keeps the photos and renderings the list names (see compare.h).
void KeepListedImages(const CompareOptions& options, std::vector<ImageFile>* photos,
                      std::vector<ImageFile>* renders) {
  const fs::path& list = options.image_list;
  struct Listed {
    std::string name;
    std::string location;  // "<list>:<line>"
  };
  std::map<std::string, Listed> by_stem;
  for (const split::ImageListEntry& entry : split::ReadImageListEntries(list)) {
    std::string location = fmt::format("{}:{}", list.string(), entry.line);
    std::string name = scene::CheckedImageName(entry.name, location);
    const std::string stem = ListedStem(name);
    const auto [it, inserted] = by_stem.emplace(stem, Listed{name, location});
    REPHOTO_CHECK(inserted,
                  "{}: image '{}' is already listed at {} as '{}' (images are paired by file "
                  "name without extension)",
                  location, name, it->second.location, it->second.name);
  }
  REPHOTO_CHECK(!by_stem.empty(), "{}: the image list names no image", list.string());
  const size_t photos_before = photos->size(), renders_before = renders->size();
  std::set<std::string> found;
  for (std::vector<ImageFile>* images : {photos, renders}) {
    std::erase_if(*images, [&](const ImageFile& image) { return !by_stem.contains(image.stem); });
    for (const ImageFile& image : *images) found.insert(image.stem);
  }
  for (const auto& [stem, listed] : by_stem) {
    REPHOTO_CHECK(found.contains(stem),
                  "{}: image '{}' has neither a photo in {} nor a rendering in {}", listed.location,
                  listed.name, options.photos.string(), options.renders.string());
  }
  LogInfo(fmt::format("{}: {} images listed; {} photos and {} renderings not listed are ignored",
                      list.string(), by_stem.size(), photos_before - photos->size(),
                      renders_before - renders->size()));
}

}  // namespace

CompareResult RunCompare(const CompareOptions& options) {
  options.Check();
  std::vector<ImageFile> photos = ListImages(options.photos, "photos");
  std::vector<ImageFile> renders = ListImages(options.renders, "renderings");
  REPHOTO_CHECK(!photos.empty(), "{}: no images in the photo folder (.png .jpg .jpeg .exr .pfm)",
                options.photos.string());
  REPHOTO_CHECK(!renders.empty(),
                "{}: no images in the rendering folder (.png .jpg .jpeg .exr .pfm)",
                options.renders.string());
  if (!options.image_list.empty()) KeepListedImages(options, &photos, &renders);
  const Pairing pairing = PairByStem(photos, renders);
  for (const MissingImage& m : pairing.missing) {
    if (m.missing == Missing::kRender) {
      LogWarning(fmt::format("{}: no rendering named '{}' in {}", m.present.string(), m.name,
                             options.renders.string()));
    } else {
      LogWarning(fmt::format("{}: no photo named '{}' in {}", m.present.string(), m.name,
                             options.photos.string()));
    }
  }
  REPHOTO_CHECK(!pairing.pairs.empty(),
                "{}: no photo has a rendering with the same name in {} ({} photos, {} "
                "renderings)",
                options.photos.string(), options.renders.string(), photos.size(), renders.size());
  const std::vector<PlannedPair> plan = PlanPairs(options, pairing);

  std::error_code ec;
  // One writer, and only into a folder compare made (run/run_folder.h). A folder that compare
  // creates and that a failure leaves holding nothing of value is removed again.
  const bool created = !fs::exists(options.out, ec);
  run::RunFolder run_folder = run::OpenRunFolder(options.out, "compare", IsLegacyCompareRun);
  struct RemoveIfFailed {
    fs::path path;
    bool armed;
    ~RemoveIfFailed() {
      std::error_code ignored;
      if (armed && std::uncaught_exceptions() > 0) fs::remove_all(path, ignored);
    }
  } remove_if_failed{options.out, created};
  RemoveStaleStaging(options.out);
  const fs::path staging = options.out / (kStagingPrefix + std::to_string(::getpid()));
  fs::remove_all(staging, ec);
  fs::create_directories(staging / "errors", ec);
  REPHOTO_CHECK(!ec, "{}: cannot create folder: {}", staging.string(), ec.message());
  struct StagingCleanup {
    fs::path path;
    ~StagingCleanup() {
      std::error_code ignored;
      fs::remove_all(path, ignored);
    }
  } cleanup{staging};

  CompareResult result;
  result.missing = pairing.missing;
  result.photo_count = photos.size();
  result.render_count = renders.size();
  LogInfo(fmt::format("comparing {} pairs ({} missing counterparts) with {}", plan.size(),
                      pairing.missing.size(), [&] {
                        std::string names;
                        for (Metric m : options.metrics) {
                          if (!names.empty()) names += ',';
                          names += metrics::MetricName(m);
                        }
                        return names;
                      }()));
  {
    std::array<PairImages, 2> slots;
    CompareWorkspace workspace;
    Progress progress("compare", plan.size());
    // Declared after the slots: its destructor finishes a pending load before they go away.
    std::unique_ptr<BackgroundWorker> worker;
    if (options.prefetch && plan.size() > 1) worker = std::make_unique<BackgroundWorker>();
    LoadPair(plan[0], &slots[0]);
    for (size_t i = 0; i < plan.size(); ++i) {
      std::future<void> next;
      if (i + 1 < plan.size()) {
        if (worker) {
          next = worker->Submit([&, i] { LoadPair(plan[i + 1], &slots[(i + 1) % 2]); });
        }
      }
      result.images.push_back(
          ComparePair(options, plan[i], slots[i % 2], staging / "errors", &workspace));
      if (i + 1 < plan.size()) {
        if (next.valid()) {
          next.get();  // rethrows a decoding error of the next pair
        } else {
          LoadPair(plan[i + 1], &slots[(i + 1) % 2]);
        }
      }
      progress.Advance(plan[i].files.name);
    }
  }
  std::vector<double> completeness;
  for (const ImageResult& image : result.images) completeness.push_back(image.completeness.value);
  result.completeness = Summarize(completeness);
  result.metrics = SummarizeMetrics(options.metrics, result.images);

  WriteTextFileAtomically(staging / "per_image.csv", PerImageCsv(options, result));
  WriteTextFileAtomically(staging / "summary.json", SummaryJsonText(options, result));
  CommitRun(staging, options.out, options.write_error_images);
  return result;
}

}  // namespace rephoto::compare
