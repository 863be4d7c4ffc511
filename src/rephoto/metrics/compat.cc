#include "rephoto/metrics/compat.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/parallel.h"

namespace rephoto::metrics {
namespace {

constexpr int kRadius = 5;  // 11x11 window
constexpr double kSigma = 1.5;
constexpr double kC1 = 0.01 * 0.01;
constexpr double kC2 = 0.03 * 0.03;
constexpr int kBandRows = 32;

std::array<double, 2 * kRadius + 1> GaussianWeights() {
  std::array<double, 2 * kRadius + 1> w{};
  double sum = 0;
  for (int k = -kRadius; k <= kRadius; ++k) {
    w[k + kRadius] = std::exp(-(k * k) / (2 * kSigma * kSigma));
    sum += w[k + kRadius];
  }
  for (double& v : w) v /= sum;
  return w;
}

// Index of padded position i in [0, n): -1 for a zero-padded position outside, else the
// reflected index (torch/numpy "reflect": -1 -> 1, n -> n - 2).
int PaddedIndex(int i, int n, CompatPreset preset) {
  if (i >= 0 && i < n) return i;
  if (preset == CompatPreset::k3dgs) return -1;
  return i < 0 ? -i : 2 * (n - 1) - i;
}

struct Sums {
  double squared_error = 0;
  double ssim = 0;
  Sums& operator+=(const Sums& o) {
    squared_error += o.squared_error;
    ssim += o.ssim;
    return *this;
  }
};

// One band of rows [y0, y1) of one channel: adds each pixel's SSIM of channel c to
// ssim_band (row-major, (y1 - y0) x width). The window sums are those of direct loops over the
// 11 taps, k in increasing order, accumulated from 0 (a zero-padded tap adds w * 0 = +0, which
// leaves a sum unchanged): every output gets the same operations in the same order on every
// path, and the loops over x vectorize (k outer, x inner; planar sums).
struct SsimBand {
  CompatPreset preset;
  const Image* photo;
  const Image* render;
  const double* w;  // 2 kRadius + 1 weights
  int width, height, y0, y1, c;
  std::vector<double>* padded;  // 2 rows of width + 2 kRadius
  std::vector<double>* h;       // 5 planes of (y1 - y0 + 2 kRadius) rows of width
  std::vector<double>* m;       // 5 rows of width
  double* ssim_band;
};

[[gnu::always_inline]] inline void SsimBandChannelBody(const SsimBand& b) {
  const int width = b.width, rows = b.y1 - b.y0 + 2 * kRadius;
  const int pc = b.photo->channels(), rc = b.render->channels();
  const size_t ext = static_cast<size_t>(width) + 2 * kRadius;
  const size_t plane = static_cast<size_t>(rows) * width;
  b.padded->resize(2 * ext);
  b.h->resize(5 * plane);
  b.m->resize(5 * static_cast<size_t>(width));
  double* pa = b.padded->data();
  double* pb = pa + ext;
  const double* w = b.w;
  for (int r = 0; r < rows; ++r) {
    double* h0 = b.h->data() + static_cast<size_t>(r) * width;
    double* h1 = h0 + plane;
    double* h2 = h1 + plane;
    double* h3 = h2 + plane;
    double* h4 = h3 + plane;
    const int sy = PaddedIndex(b.y0 - kRadius + r, b.height, b.preset);
    if (sy < 0) {
      for (double* hq : {h0, h1, h2, h3, h4}) std::fill(hq, hq + width, 0.0);
      continue;
    }
    const float* prow = b.photo->row(sy);
    const float* rrow = b.render->row(sy);
    for (int i = 0; i < width + 2 * kRadius; ++i) {
      const int sx = PaddedIndex(i - kRadius, width, b.preset);
      pa[i] = sx < 0 ? 0.0 : static_cast<double>(prow[static_cast<size_t>(sx) * pc + b.c]);
      pb[i] = sx < 0 ? 0.0 : static_cast<double>(rrow[static_cast<size_t>(sx) * rc + b.c]);
    }
    for (int x = 0; x < width; ++x) h0[x] = h1[x] = h2[x] = h3[x] = h4[x] = 0.0;
    for (int k = 0; k <= 2 * kRadius; ++k) {
      const double wk = w[k];
      const double* __restrict a = pa + k;
      const double* __restrict bb = pb + k;
#pragma GCC ivdep  // the planes and the padded rows do not overlap
      for (int x = 0; x < width; ++x) {
        h0[x] += wk * a[x];
        h1[x] += wk * bb[x];
        h2[x] += wk * a[x] * a[x];
        h3[x] += wk * bb[x] * bb[x];
        h4[x] += wk * a[x] * bb[x];
      }
    }
  }
  double* m0 = b.m->data();
  double* m1 = m0 + width;
  double* m2 = m1 + width;
  double* m3 = m2 + width;
  double* m4 = m3 + width;
  const bool clamp = b.preset == CompatPreset::kNerfstudio;
  for (int y = b.y0; y < b.y1; ++y) {
    for (int x = 0; x < width; ++x) m0[x] = m1[x] = m2[x] = m3[x] = m4[x] = 0.0;
    for (int k = 0; k <= 2 * kRadius; ++k) {
      const double wk = w[k];
      const double* __restrict in0 = b.h->data() + static_cast<size_t>(y - b.y0 + k) * width;
      const double* __restrict in1 = in0 + plane;
      const double* __restrict in2 = in1 + plane;
      const double* __restrict in3 = in2 + plane;
      const double* __restrict in4 = in3 + plane;
#pragma GCC ivdep
      for (int x = 0; x < width; ++x) {
        m0[x] += wk * in0[x];
        m1[x] += wk * in1[x];
        m2[x] += wk * in2[x];
        m3[x] += wk * in3[x];
        m4[x] += wk * in4[x];
      }
    }
    double* ssim_row = b.ssim_band + static_cast<size_t>(y - b.y0) * width;
#pragma GCC ivdep
    for (int x = 0; x < width; ++x) {
      const double mu_x = m0[x], mu_y = m1[x];
      double var_x = m2[x] - mu_x * mu_x;
      double var_y = m3[x] - mu_y * mu_y;
      if (clamp) {
        var_x = var_x < 0.0 ? 0.0 : var_x;  // std::max(var_x, 0.0), as a select
        var_y = var_y < 0.0 ? 0.0 : var_y;
      }
      const double cov = m4[x] - mu_x * mu_y;
      ssim_row[x] += ((2 * mu_x * mu_y + kC1) * (2 * cov + kC2)) /
                     ((mu_x * mu_x + mu_y * mu_y + kC1) * (var_x + var_y + kC2));
    }
  }
}

REPHOTO_ISA_DISPATCH(void, SsimBandChannel, (const SsimBand& b), (b))

}  // namespace

std::optional<CompatPreset> ParseCompatPreset(std::string_view name) {
  std::string lower(name);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == "3dgs" || lower == "graphdeco" || lower == "gaussian-splatting") {
    return CompatPreset::k3dgs;
  }
  if (lower == "nerfstudio" || lower == "ns-eval") return CompatPreset::kNerfstudio;
  return std::nullopt;
}

std::string_view CompatPresetName(CompatPreset preset) {
  return preset == CompatPreset::k3dgs ? "3dgs" : "nerfstudio";
}

CompatResult ComputeCompatMetrics(CompatPreset preset, const Image& photo, const Image& render,
                                  Image* squared_error, Image* ssim_map) {
  REPHOTO_CHECK(photo.SameSize(render), "compat {}: photo is {}x{} but rendering is {}x{}",
                CompatPresetName(preset), photo.width(), photo.height(), render.width(),
                render.height());
  REPHOTO_CHECK(photo.channels() >= 3 && render.channels() >= 3,
                "compat {}: images need 3 colour channels (photo has {}, rendering {})",
                CompatPresetName(preset), photo.channels(), render.channels());
  const int width = photo.width(), height = photo.height();
  REPHOTO_CHECK(width > 0 && height > 0, "compat {}: empty image", CompatPresetName(preset));
  REPHOTO_CHECK(preset != CompatPreset::kNerfstudio || (width > kRadius && height > kRadius),
                "compat nerfstudio: image is {}x{}, reflect padding needs at least {}x{}", width,
                height, kRadius + 1, kRadius + 1);
  if (squared_error) squared_error->Resize(width, height, 1);
  if (ssim_map) ssim_map->Resize(width, height, 1);
  const std::array<double, 2 * kRadius + 1> w = GaussianWeights();
  const int pc = photo.channels(), rc = render.channels();

  const int64_t bands = (height + kBandRows - 1) / kBandRows;
  const Sums sums = ParallelSum<Sums>(0, bands, 1, [&](int64_t band_begin, int64_t band_end) {
    Sums total;
    // Horizontal sums of x, y, x^2, y^2, xy for the band's rows plus the window margin.
    std::vector<double> padded, h, m;
    for (int64_t band = band_begin; band < band_end; ++band) {
      const int y0 = static_cast<int>(band) * kBandRows;
      const int y1 = std::min(height, y0 + kBandRows);
      for (int y = y0; y < y1; ++y) {
        double row_se = 0;
        for (int x = 0; x < width; ++x) {
          double se = 0;
          for (int c = 0; c < 3; ++c) {
            const double d = static_cast<double>(photo.at(x, y, c)) - render.at(x, y, c);
            se += d * d;
          }
          row_se += se;
          if (squared_error) squared_error->at(x, y) = static_cast<float>(se / 3);
        }
        total.squared_error += row_se;
      }
      std::vector<double> ssim_band(static_cast<size_t>(y1 - y0) * width, 0.0);
      for (int c = 0; c < 3; ++c) {
        SsimBandChannel(SsimBand{preset, &photo, &render, w.data(), width, height, y0, y1, c,
                                 &padded, &h, &m, ssim_band.data()});
      }
      for (int y = y0; y < y1; ++y) {
        const double* ssim_row = ssim_band.data() + static_cast<size_t>(y - y0) * width;
        for (int x = 0; x < width; ++x) {
          total.ssim += ssim_row[x];
          if (ssim_map) ssim_map->at(x, y) = static_cast<float>(ssim_row[x] / 3);
        }
      }
    }
    return total;
  });

  CompatResult result;
  result.pixels = static_cast<size_t>(width) * height;
  const double values = static_cast<double>(result.pixels) * 3;
  result.mse = sums.squared_error / values;
  result.psnr = result.mse == 0 ? std::numeric_limits<double>::infinity()
                                : 10.0 * std::log10(1.0 / result.mse);
  result.ssim = sums.ssim / values;
  return result;
}

Image CompositeOverBackground(const Image& image, const std::array<float, 3>& background) {
  const int channels = image.channels();
  REPHOTO_CHECK(channels >= 1 && channels <= 4, "unsupported channel count {}", channels);
  Image rgb(image.width(), image.height(), 3);
  const bool grey = channels <= 2;
  const bool alpha = channels == 2 || channels == 4;
  ParallelFor(0, static_cast<int64_t>(image.pixel_count()), 1 << 15, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const float* px = image.data() + i * channels;
      const float a = alpha ? px[channels - 1] : 1.0f;
      for (int c = 0; c < 3; ++c) {
        const float v = grey ? px[0] : px[c];
        rgb.data()[3 * i + c] = alpha ? v * a + background[c] * (1.0f - a) : v;
      }
    }
  });
  return rgb;
}

}  // namespace rephoto::metrics
