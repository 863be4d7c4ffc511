#include "rephoto/metrics/validity.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"

namespace rephoto::metrics {
namespace {

constexpr int64_t kRowGrain = 64;

// The float value a sample stands for: itself, or v / 255 for 8-bit samples (as io reads them).
inline float Value(float v) { return v; }
inline float Value(uint8_t v) { return static_cast<float>(v) / 255.f; }

template <typename T>
void CheckPhotoAndMask(const ImageT<T>& photo, const Mask& user_mask) {
  REPHOTO_CHECK(photo.channels() >= 1, "PhotoValidity: photo has no channels");
  if (!user_mask.empty()) {
    REPHOTO_CHECK(user_mask.SameSize(photo) && user_mask.channels() == 1,
                  "PhotoValidity: mask is {}x{}x{} but the photo is {}x{} (need 1 channel, same "
                  "size)",
                  user_mask.width(), user_mask.height(), user_mask.channels(), photo.width(),
                  photo.height());
  }
}

template <typename T>
Mask PhotoValidityOf(const ImageT<T>& photo, const Mask& user_mask,
                     const ExposureOptions& options) {
  CheckPhotoAndMask(photo, user_mask);
  const int channels = photo.channels();
  // Grey (1) and grey+alpha (2) images have one colour channel; otherwise the first three.
  const int colour = channels <= 2 ? 1 : 3;
  const float dark = options.dark_threshold;
  const float saturated = options.saturated_threshold;
  const int width = photo.width();
  Mask valid(width, photo.height(), 1);
  ParallelFor(0, photo.height(), kRowGrain, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      const T* row = photo.row(static_cast<int>(y));
      uint8_t* out = valid.row(static_cast<int>(y));
      const uint8_t* user = user_mask.empty() ? nullptr : user_mask.row(static_cast<int>(y));
      for (int x = 0; x < width; ++x) {
        bool ok = user == nullptr || user[x] != 0;
        for (int c = 0; c < colour; ++c) {
          const float v = Value(row[static_cast<size_t>(x) * channels + c]);
          // NaN fails both comparisons and counts as ill-exposed.
          ok = ok && v > dark && v < saturated;
        }
        out[x] = ok ? 1 : 0;
      }
    }
  });
  return valid;
}

// 8-bit photos: k / 255.f is non-decreasing in k, so the values k with dark < k / 255.f <
// saturated (the float rule above, evaluated for all 256) form one interval [lo, hi], and a
// sample passes exactly when it lies in it; the loop is then integer and branch-free (the
// float rule per sample, with its division and short-circuit, was 7 % of a 12 MP `compare`).
Mask PhotoValidity8(const Image8& photo, const Mask& user_mask, const ExposureOptions& options) {
  int lo = 256, hi = -1;
  for (int k = 0; k < 256; ++k) {
    const float v = Value(static_cast<uint8_t>(k));
    if (v > options.dark_threshold && v < options.saturated_threshold) {
      lo = std::min(lo, k);
      hi = std::max(hi, k);
    }
  }
  const int channels = photo.channels();
  const int colour = channels <= 2 ? 1 : 3;
  const int width = photo.width();
  Mask valid(width, photo.height(), 1, 0);
  if (hi < lo) return valid;  // no 8-bit value is well exposed
  const uint8_t base = static_cast<uint8_t>(lo), span = static_cast<uint8_t>(hi - lo);
  ParallelFor(0, photo.height(), kRowGrain, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      const uint8_t* row = photo.row(static_cast<int>(y));
      uint8_t* out = valid.row(static_cast<int>(y));
      const uint8_t* user = user_mask.empty() ? nullptr : user_mask.row(static_cast<int>(y));
      auto in = [&](uint8_t v) { return static_cast<uint8_t>(v - base) <= span; };
      if (colour == 3) {
        for (int x = 0; x < width; ++x) {
          const uint8_t* px = row + static_cast<size_t>(x) * channels;
          out[x] = in(px[0]) & in(px[1]) & in(px[2]);
        }
      } else {
        for (int x = 0; x < width; ++x) out[x] = in(row[static_cast<size_t>(x) * channels]);
      }
      if (user != nullptr)
        for (int x = 0; x < width; ++x) out[x] &= user[x] != 0;
    }
  });
  return valid;
}

template <typename T>
Mask RephotoValidityOf(const ImageT<T>& rephoto, const Mask& explicit_mask) {
  if (!explicit_mask.empty()) {
    REPHOTO_CHECK(explicit_mask.SameSize(rephoto) && explicit_mask.channels() == 1,
                  "RephotoValidity: mask is {}x{}x{} but the rendering is {}x{} (need 1 channel, "
                  "same size)",
                  explicit_mask.width(), explicit_mask.height(), explicit_mask.channels(),
                  rephoto.width(), rephoto.height());
    Mask valid(explicit_mask.width(), explicit_mask.height(), 1);
    for (size_t i = 0; i < valid.size(); ++i) valid.data()[i] = explicit_mask.data()[i] ? 1 : 0;
    return valid;
  }
  const int channels = rephoto.channels();
  REPHOTO_CHECK(channels >= 1 && channels <= 4, "RephotoValidity: unsupported channel count {}",
                channels);
  const bool has_alpha = channels == 2 || channels == 4;
  const int colour = has_alpha ? channels - 1 : channels;
  const int width = rephoto.width();
  Mask valid(width, rephoto.height(), 1);
  ParallelFor(0, rephoto.height(), kRowGrain, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      const T* row = rephoto.row(static_cast<int>(y));
      uint8_t* out = valid.row(static_cast<int>(y));
      if constexpr (std::is_same_v<T, uint8_t>) {
        // k / 255.f > 0 exactly when k > 0, and != 0 exactly when k != 0: integer and
        // branch-free (the same mask as the float rule below).
        if (has_alpha) {
          for (int x = 0; x < width; ++x)
            out[x] = row[static_cast<size_t>(x) * channels + channels - 1] != 0;
        } else if (colour == 3) {
          for (int x = 0; x < width; ++x) {
            const uint8_t* px = row + static_cast<size_t>(x) * channels;
            out[x] = (px[0] | px[1] | px[2]) != 0;
          }
        } else {
          for (int x = 0; x < width; ++x) out[x] = row[x] != 0;
        }
        continue;
      }
      for (int x = 0; x < width; ++x) {
        const T* px = row + static_cast<size_t>(x) * channels;
        bool ok;
        if (has_alpha) {
          ok = Value(px[channels - 1]) > 0.0f;
        } else {
          ok = false;
          for (int c = 0; c < colour; ++c) ok = ok || Value(px[c]) != 0.0f;
        }
        out[x] = ok ? 1 : 0;
      }
    }
  });
  return valid;
}

}  // namespace

Mask PhotoValidity(const Image& photo, const Mask& user_mask, const ExposureOptions& options) {
  return PhotoValidityOf(photo, user_mask, options);
}
Mask PhotoValidity(const Image8& photo, const Mask& user_mask, const ExposureOptions& options) {
  CheckPhotoAndMask(photo, user_mask);
  return PhotoValidity8(photo, user_mask, options);
}
Mask RephotoValidity(const Image& rephoto, const Mask& explicit_mask) {
  return RephotoValidityOf(rephoto, explicit_mask);
}
Mask RephotoValidity(const Image8& rephoto, const Mask& explicit_mask) {
  return RephotoValidityOf(rephoto, explicit_mask);
}

Mask CombineMasks(const Mask& a, const Mask& b) {
  REPHOTO_CHECK(a.SameSize(b) && a.channels() == 1 && b.channels() == 1,
                "CombineMasks: masks differ in size ({}x{} vs {}x{})", a.width(), a.height(),
                b.width(), b.height());
  Mask out(a.width(), a.height(), 1);
  const uint8_t* pa = a.data();
  const uint8_t* pb = b.data();
  uint8_t* po = out.data();
  for (size_t i = 0; i < out.size(); ++i) po[i] = (pa[i] != 0) & (pb[i] != 0);
  return out;
}

Mask WindowValidity(const Mask& valid, int window) {
  REPHOTO_CHECK(window >= 1 && window % 2 == 1, "WindowValidity: window {} is not odd and >= 1",
                window);
  REPHOTO_CHECK(valid.channels() == 1, "WindowValidity: mask has {} channels, need 1",
                valid.channels());
  const int width = valid.width();
  const int height = valid.height();
  const int r = window / 2;
  Mask out(width, height, 1, 0);
  if (width < window || height < window) return out;
  ParallelFor(r, height - r, kRowGrain, [&](int64_t y0, int64_t y1) {
    // Column counts of invalid pixels over rows [y - r, y + r], slid down the band.
    std::vector<int> column_invalid(static_cast<size_t>(width), 0);
    for (int64_t j = y0 - r; j <= y0 + r; ++j) {
      const uint8_t* row = valid.row(static_cast<int>(j));
      for (int x = 0; x < width; ++x) column_invalid[x] += row[x] == 0;
    }
    for (int64_t y = y0; y < y1; ++y) {
      if (y > y0) {
        const uint8_t* add = valid.row(static_cast<int>(y + r));
        const uint8_t* sub = valid.row(static_cast<int>(y - r - 1));
        for (int x = 0; x < width; ++x) column_invalid[x] += (add[x] == 0) - (sub[x] == 0);
      }
      uint8_t* out_row = out.row(static_cast<int>(y));
      int run = 0;
      for (int x = 0; x < window; ++x) run += column_invalid[x];
      out_row[r] = run == 0;
      for (int x = r + 1; x < width - r; ++x) {
        run += column_invalid[x + r] - column_invalid[x - r - 1];
        out_row[x] = run == 0;
      }
    }
  });
  return out;
}

Completeness ComputeCompleteness(const Mask& photo_valid, const Mask& rephoto_valid, int window) {
  REPHOTO_CHECK(photo_valid.SameSize(rephoto_valid),
                "ComputeCompleteness: masks differ in size ({}x{} vs {}x{})", photo_valid.width(),
                photo_valid.height(), rephoto_valid.width(), rephoto_valid.height());
  const Mask photo_windows = WindowValidity(photo_valid, window);
  const Mask both_windows = WindowValidity(CombineMasks(photo_valid, rephoto_valid), window);
  Completeness result;
  for (size_t i = 0; i < photo_windows.size(); ++i) {
    result.valid_photo += photo_windows.data()[i] != 0;
    result.valid_both += both_windows.data()[i] != 0;
  }
  result.value = result.valid_photo == 0 ? std::numeric_limits<double>::quiet_NaN()
                                         : static_cast<double>(result.valid_both) /
                                               static_cast<double>(result.valid_photo);
  return result;
}

}  // namespace rephoto::metrics
