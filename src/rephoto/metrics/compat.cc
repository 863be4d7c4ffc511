#include "rephoto/metrics/compat.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "rephoto/core/error.h"
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
    std::vector<double> h;
    for (int64_t band = band_begin; band < band_end; ++band) {
      const int y0 = static_cast<int>(band) * kBandRows;
      const int y1 = std::min(height, y0 + kBandRows);
      const int rows = y1 - y0 + 2 * kRadius;
      h.assign(static_cast<size_t>(rows) * width * 5, 0.0);
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
        for (int r = 0; r < rows; ++r) {
          double* out = h.data() + static_cast<size_t>(r) * width * 5;
          const int sy = PaddedIndex(y0 - kRadius + r, height, preset);
          if (sy < 0) {
            std::fill(out, out + static_cast<size_t>(width) * 5, 0.0);
            continue;
          }
          const float* prow = photo.row(sy);
          const float* rrow = render.row(sy);
          for (int x = 0; x < width; ++x) {
            double s[5] = {0, 0, 0, 0, 0};
            for (int k = -kRadius; k <= kRadius; ++k) {
              const int sx = PaddedIndex(x + k, width, preset);
              if (sx < 0) continue;
              const double a = prow[static_cast<size_t>(sx) * pc + c];
              const double b = rrow[static_cast<size_t>(sx) * rc + c];
              const double wk = w[k + kRadius];
              s[0] += wk * a;
              s[1] += wk * b;
              s[2] += wk * a * a;
              s[3] += wk * b * b;
              s[4] += wk * a * b;
            }
            for (int q = 0; q < 5; ++q) out[static_cast<size_t>(x) * 5 + q] = s[q];
          }
        }
        for (int y = y0; y < y1; ++y) {
          double* ssim_row = ssim_band.data() + static_cast<size_t>(y - y0) * width;
          for (int x = 0; x < width; ++x) {
            double m[5] = {0, 0, 0, 0, 0};
            for (int k = 0; k <= 2 * kRadius; ++k) {
              const double* in = h.data() + (static_cast<size_t>(y - y0 + k) * width + x) * 5;
              for (int q = 0; q < 5; ++q) m[q] += w[k] * in[q];
            }
            const double mu_x = m[0], mu_y = m[1];
            double var_x = m[2] - mu_x * mu_x;
            double var_y = m[3] - mu_y * mu_y;
            if (preset == CompatPreset::kNerfstudio) {
              var_x = std::max(var_x, 0.0);
              var_y = std::max(var_y, 0.0);
            }
            const double cov = m[4] - mu_x * mu_y;
            ssim_row[x] += ((2 * mu_x * mu_y + kC1) * (2 * cov + kC2)) /
                           ((mu_x * mu_x + mu_y * mu_y + kC1) * (var_x + var_y + kC2));
          }
        }
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
