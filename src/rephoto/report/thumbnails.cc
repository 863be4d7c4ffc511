#include "rephoto/report/thumbnails.h"

#include <fmt/format.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <memory>
#include <optional>
#include <vector>

#include "rephoto/compare/compare.h"
#include "rephoto/compare/resample.h"
#include "rephoto/core/error.h"
#include "rephoto/core/recent_cache.h"
#include "rephoto/io/image_encode.h"
#include "rephoto/io/image_io.h"
#include "rephoto/report/html.h"

namespace rephoto::report {
namespace fs = std::filesystem;
namespace {

// Thumbnail size for a width x height image.
void ThumbnailSize(int width, int height, int max_width, int* out_width, int* out_height) {
  if (max_width <= 0 || width <= max_width) {
    *out_width = width;
    *out_height = height;
    return;
  }
  *out_width = max_width;
  *out_height =
      std::max(1, static_cast<int>(std::lround(static_cast<double>(height) * max_width / width)));
}

// `image` shrunk to at most max_width wide: `image` itself when it is not wider, else `out`.
const Image& Shrink(const Image& image, int max_width, Image* out) {
  int w = 0, h = 0;
  ThumbnailSize(image.width(), image.height(), max_width, &w, &h);
  if (w == image.width() && h == image.height()) return image;
  compare::ResizeImage(image, w, h, out);
  return *out;
}

uint8_t ToByte(float v) {
  const float clamped = v > 0.f ? (v < 1.f ? v : 1.f) : 0.f;  // NaN -> 0
  return static_cast<uint8_t>(clamped * 255.f + 0.5f);
}

// RGB bytes of an image with 1-4 channels; alpha (2 or 4 channels) composites over black.
std::vector<uint8_t> RgbBytes(const Image& image) {
  std::vector<uint8_t> rgb(image.pixel_count() * 3);
  const int c = image.channels();
  const bool alpha = c == 2 || c == 4;
  for (size_t i = 0; i < image.pixel_count(); ++i) {
    const float* p = image.data() + i * c;
    const float a = alpha ? std::clamp(p[c - 1], 0.f, 1.f) : 1.f;
    for (int k = 0; k < 3; ++k) rgb[i * 3 + k] = ToByte(p[c >= 3 ? k : 0] * a);
  }
  return rgb;
}

Thumbnail Jpeg(const Image& image, const std::string& name) {
  Thumbnail t;
  t.width = image.width();
  t.height = image.height();
  t.data_uri = DataUri("image/jpeg",
                       io::EncodeJpegToMemory(RgbBytes(image), t.width, t.height, 3, 85, name));
  return t;
}

// Colour-mapped RGBA -> JPEG (4:4:4, quality 80; about a third of the size of an RGBA PNG of noisy
// error images), transparent pixels shown as a grey checkerboard of 8-pixel squares (jet has no
// greys, so "not evaluated" stays recognisable).
Thumbnail ErrorJpeg(const std::vector<uint8_t>& rgba, int width, int height,
                    const std::string& name) {
  std::vector<uint8_t> rgb(static_cast<size_t>(width) * height * 3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const size_t i = static_cast<size_t>(y) * width + x;
      const float a = rgba[4 * i + 3] / 255.f;
      const float checker = ((x / 8 + y / 8) % 2) ? 200.f : 150.f;
      for (int k = 0; k < 3; ++k) {
        rgb[3 * i + k] =
            static_cast<uint8_t>(std::lround(rgba[4 * i + k] * a + checker * (1.f - a)));
      }
    }
  }
  Thumbnail t;
  t.width = width;
  t.height = height;
  t.data_uri = DataUri("image/jpeg", io::EncodeJpegToMemory(rgb, width, height, 3, 80, name,
                                                            /*full_chroma=*/true));
  return t;
}

Thumbnail Failed(const std::string& message) {
  Thumbnail t;
  t.error = message;
  return t;
}

// What identifies a file's content for the cache: its absolute path, device and inode (a file
// replaced by a rename, as rephoto writes its outputs, is a new inode), size and modification
// and status-change times in nanoseconds; "-" when it does not exist; nullopt when it cannot be
// told (then nothing is cached).
std::optional<std::string> FileIdentity(const fs::path& path) {
  if (path.empty()) return std::string("-");
  std::error_code ec;
  const fs::path absolute = fs::absolute(path, ec).lexically_normal();
  if (ec) return std::nullopt;
  struct stat st {};
  if (::stat(absolute.c_str(), &st) != 0) {
    if (errno == ENOENT) return std::string("-");
    return std::nullopt;
  }
  if (!S_ISREG(st.st_mode)) return std::nullopt;
  return fmt::format("{}\n{} {} {} {}.{} {}.{}", absolute.string(), st.st_dev, st.st_ino,
                     st.st_size, st.st_mtim.tv_sec, st.st_mtim.tv_nsec, st.st_ctim.tv_sec,
                     st.st_ctim.tv_nsec);
}

// The finished thumbnails of the process (see thumbnails.h, "Cache"): at most 64 MiB of data
// URIs, the least recently used dropped first (4096 entries bound the linear lookup).
using ThumbnailCache = RecentCache<std::string, std::vector<Thumbnail>>;
ThumbnailCache& FinishedThumbnails() {
  static ThumbnailCache cache(4096, size_t{64} << 20);
  return cache;
}

// The key of a thumbnail of `files` made by `kind` at `width` (nullopt: not cacheable).
std::optional<std::string> CacheKey(const std::string& kind, int width,
                                    std::initializer_list<const fs::path*> files) {
  std::string key = fmt::format("{}\n{}", kind, width);
  for (const fs::path* file : files) {
    const std::optional<std::string> identity = FileIdentity(*file);
    if (!identity) return std::nullopt;
    key += "\n" + *identity;
  }
  return key;
}

// make() unless the cache holds the thumbnails of key_of(); stored when they all succeeded and
// key_of() still gives the same key afterwards (a file rewritten meanwhile is not stored under
// its old identity).
template <typename Key, typename Make>
std::vector<Thumbnail> Cached(const Key& key_of, const Make& make) {
  const std::optional<std::string> key = key_of();
  if (!key) return make();
  if (const auto found = FinishedThumbnails().Find(*key)) return *found;
  std::vector<Thumbnail> made = make();
  size_t bytes = key->size();
  bool ok = true;
  for (const Thumbnail& t : made) {
    bytes += t.data_uri.size();
    ok = ok && !t.data_uri.empty();
  }
  if (ok && key_of() == key) {
    FinishedThumbnails().Put(*key, std::make_shared<const std::vector<Thumbnail>>(made), bytes);
  }
  return made;
}

Thumbnail MakePhotoThumbnail(const fs::path& photo, int width, ThumbnailScratch* scratch);
void MakeRenderThumbnails(const fs::path& render, int width, Thumbnail* rephoto, Thumbnail* mask,
                          ThumbnailScratch* scratch);
Thumbnail MakeErrorThumbnail(const fs::path& exr, const fs::path& png, metrics::Metric metric,
                             int width, ThumbnailScratch* scratch);

}  // namespace

Thumbnail PhotoThumbnail(const fs::path& photo, int width, ThumbnailScratch* scratch) {
  if (photo.empty()) return Failed("no photo");
  const auto key = [&] { return CacheKey("photo", width, {&photo}); };
  return Cached(
      key, [&] { return std::vector<Thumbnail>{MakePhotoThumbnail(photo, width, scratch)}; })[0];
}

void RenderThumbnails(const fs::path& render, int width, Thumbnail* rephoto, Thumbnail* mask,
                      ThumbnailScratch* scratch) {
  if (render.empty()) {
    *rephoto = *mask = Failed("no rendering");
    return;
  }
  const auto key = [&] { return CacheKey("render", width, {&render}); };
  std::vector<Thumbnail> both = Cached(key, [&] {
    std::vector<Thumbnail> made(2);
    MakeRenderThumbnails(render, width, &made[0], &made[1], scratch);
    return made;
  });
  *rephoto = std::move(both[0]);
  *mask = std::move(both[1]);
}

Thumbnail ErrorThumbnail(const fs::path& exr, const fs::path& png, metrics::Metric metric,
                         int width, ThumbnailScratch* scratch) {
  const auto key = [&] {
    return CacheKey(fmt::format("error {}", metrics::MetricName(metric)), width, {&exr, &png});
  };
  return Cached(key, [&] {
    return std::vector<Thumbnail>{MakeErrorThumbnail(exr, png, metric, width, scratch)};
  })[0];
}

std::unique_ptr<ThumbnailScratch> ThumbnailScratches::Acquire() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (free_.empty()) return std::make_unique<ThumbnailScratch>();
  std::unique_ptr<ThumbnailScratch> scratch = std::move(free_.back());
  free_.pop_back();
  return scratch;
}

void ThumbnailScratches::Release(std::unique_ptr<ThumbnailScratch> scratch) {
  std::lock_guard<std::mutex> lock(mutex_);
  free_.push_back(std::move(scratch));
}

namespace {

Thumbnail MakePhotoThumbnail(const fs::path& photo, int width, ThumbnailScratch* scratch) {
  ThumbnailScratch local;
  ThumbnailScratch& s = scratch != nullptr ? *scratch : local;
  try {
    // The thumbnail's size from the photo's own size; a JPEG is decoded at a reduced size of at
    // least that width (io::ReadImagePreview), then resampled to it.
    const io::ImageHeader header = io::ReadImageHeader(photo);
    int w = 0, h = 0;
    ThumbnailSize(header.width, header.height, width, &w, &h);
    io::ReadImagePreview(photo, w, &s.decoded);
    if (s.decoded.width() == w && s.decoded.height() == h) return Jpeg(s.decoded, photo.string());
    compare::ResizeImage(s.decoded, w, h, &s.shrunk);
    return Jpeg(s.shrunk, photo.string());
  } catch (const Error& e) {
    return Failed(e.what());
  }
}

void MakeRenderThumbnails(const fs::path& render, int width, Thumbnail* rephoto, Thumbnail* mask,
                          ThumbnailScratch* scratch) {
  ThumbnailScratch local;
  ThumbnailScratch& s = scratch != nullptr ? *scratch : local;
  try {
    io::ReadImage(render, &s.decoded);
    const Image& image = s.decoded;
    // Coverage before shrinking: alpha, else not pure black. (In the buffer the error image's
    // weights use: one large buffer less per scratch.)
    const int c = image.channels();
    Image& coverage = s.weighted;
    coverage.Resize(image.width(), image.height(), 1);
    for (size_t i = 0; i < image.pixel_count(); ++i) {
      const float* p = image.data() + i * c;
      if (c == 2 || c == 4) {
        coverage.data()[i] = p[c - 1] > 0.f ? 1.f : 0.f;
      } else {
        bool black = true;
        for (int k = 0; k < c; ++k) black = black && p[k] == 0.f;
        coverage.data()[i] = black ? 0.f : 1.f;
      }
    }
    *rephoto = Jpeg(Shrink(image, width, &s.shrunk), render.string());
    const Image& small = Shrink(coverage, width, &s.shrunk);  // the rephoto's JPEG is made
    std::vector<uint8_t> grey(small.pixel_count());
    for (size_t i = 0; i < grey.size(); ++i) grey[i] = ToByte(small.data()[i]);
    mask->width = small.width();
    mask->height = small.height();
    mask->error.clear();
    mask->data_uri = DataUri("image/png", io::EncodePngToMemory(grey, small.width(), small.height(),
                                                                1, render.string()));
  } catch (const Error& e) {
    *rephoto = *mask = Failed(e.what());
  }
}

Thumbnail MakeErrorThumbnail(const fs::path& exr, const fs::path& png, metrics::Metric metric,
                             int width, ThumbnailScratch* scratch) {
  std::error_code ec;
  ThumbnailScratch local;
  ThumbnailScratch& s = scratch != nullptr ? *scratch : local;
  try {
    if (!exr.empty() && fs::exists(exr, ec)) {
      io::ReadImage(exr, &s.decoded);
      const Image& error = s.decoded;
      REPHOTO_CHECK(error.channels() == 1, "{}: error image has {} channels, expected 1",
                    exr.string(), error.channels());
      // NaN-aware shrinking: (value * weight, weight) with weight 1 where evaluated.
      Image& weighted = s.weighted;
      weighted.Resize(error.width(), error.height(), 2);
      for (size_t i = 0; i < error.pixel_count(); ++i) {
        const float v = error.data()[i];
        const bool ok = std::isfinite(v);
        weighted.data()[2 * i] = ok ? v : 0.f;
        weighted.data()[2 * i + 1] = ok ? 1.f : 0.f;
      }
      const Image& small = Shrink(weighted, width, &s.shrunk);
      Image values(small.width(), small.height(), 1);
      for (size_t i = 0; i < values.pixel_count(); ++i) {
        const float w = small.data()[2 * i + 1];
        values.data()[i] = w >= 0.5f ? small.data()[2 * i] / w : std::nanf("");
      }
      const auto [low, high] = compare::ErrorColourRange(metric);
      std::vector<uint8_t> rgba;
      compare::ColourErrorImage(values, low, high, &rgba);
      return ErrorJpeg(rgba, values.width(), values.height(), exr.string());
    }
    if (!png.empty() && fs::exists(png, ec)) {
      io::ReadImage(png, &s.decoded);
      const Image& small = Shrink(s.decoded, width, &s.shrunk);
      REPHOTO_CHECK(small.channels() == 4, "{}: error PNG has {} channels, expected RGBA",
                    png.string(), small.channels());
      std::vector<uint8_t> rgba(small.size());
      for (size_t i = 0; i < rgba.size(); ++i) rgba[i] = ToByte(small.data()[i]);
      return ErrorJpeg(rgba, small.width(), small.height(), png.string());
    }
    return Failed("no error image (" + png.filename().string() + ")");
  } catch (const Error& e) {
    return Failed(e.what());
  }
}

}  // namespace
}  // namespace rephoto::report
