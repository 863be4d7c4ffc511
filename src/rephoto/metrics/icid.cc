#include "rephoto/metrics/icid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "rephoto/core/parallel.h"
#include "rephoto/metrics/kernels.h"

namespace rephoto::metrics {
namespace {

using internal::FillNaN;
using internal::kBandRows;
using internal::kNaN;
using internal::MeanSums;
using internal::WindowValidityRows;

double SrgbDecode(double c) {
  c = std::clamp(c, 0.0, 1.0);
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

double LabF(double t) { return t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116.0; }

// Per-pixel quantities that get window-averaged.
enum Quantity { kL1, kL2, kC1, kC2, kL1L1, kL2L2, kC1C1, kC2C2, kL1L2, kC1C2, kHue, kCount };

}  // namespace

void SrgbToLab(float r, float g, float b, double lab[3]) {
  const double rl = SrgbDecode(r), gl = SrgbDecode(g), bl = SrgbDecode(b);
  // sRGB -> XYZ (D65), then normalised by the D65 white point (0.95047, 1, 1.08883).
  const double x = (0.412453 * rl + 0.357580 * gl + 0.180423 * bl) / 0.95047;
  const double y = 0.212671 * rl + 0.715160 * gl + 0.072169 * bl;
  const double z = (0.019334 * rl + 0.119193 * gl + 0.950227 * bl) / 1.08883;
  const double fx = LabF(x), fy = LabF(y), fz = LabF(z);
  lab[0] = 116.0 * fy - 16.0;
  lab[1] = 500.0 * (fx - fy);
  lab[2] = 200.0 * (fy - fz);
}

namespace internal {

MeanSums IcidBand(const BandInputs& in, int window, const std::vector<double>& weights,
                  const ErrorRows* error, int64_t y0, int64_t y1) {
  const int w = in.width, h = in.height, r = window / 2;
  MeanSums band_sums;
  for (int64_t y = y0; y < y1; ++y) {
    if (y < r || y >= h - r || w < window) FillNaN(error->row(static_cast<int>(y)), w);
  }
  const int64_t c0 = std::max<int64_t>(y0, r), c1 = std::min<int64_t>(y1, h - r);
  if (c0 >= c1 || w < window) return band_sums;
  const int rows = static_cast<int>(c1 - c0) + 2 * r;
  const size_t plane = static_cast<size_t>(rows) * w;
  // Quantity planes for source rows [c0 - r, c1 + r), then one filtered row per quantity.
  thread_local std::vector<double> buffer;
  if (buffer.size() < kCount * plane + 2 * kCount * static_cast<size_t>(w)) {
    buffer.resize(kCount * plane + 2 * kCount * static_cast<size_t>(w));
  }
  double* planes = buffer.data();
  double* vertical = planes + kCount * plane;
  double* filtered = vertical + kCount * static_cast<size_t>(w);
  for (int j = 0; j < rows; ++j) {
    const int y = static_cast<int>(c0) - r + j;
    const float* p = in.photo.row(y);
    const float* q = in.rephoto.row(y);
    for (int x = 0; x < w; ++x) {
      double lab1[3], lab2[3];
      SrgbToLab(p[3 * x], p[3 * x + 1], p[3 * x + 2], lab1);
      SrgbToLab(q[3 * x], q[3 * x + 1], q[3 * x + 2], lab2);
      const double c1sq = lab1[1] * lab1[1] + lab1[2] * lab1[2];
      const double c2sq = lab2[1] * lab2[1] + lab2[2] * lab2[2];
      const double chroma1 = std::sqrt(c1sq), chroma2 = std::sqrt(c2sq);
      const double da = lab1[1] - lab2[1], db = lab1[2] - lab2[2], dc = chroma1 - chroma2;
      const size_t i = static_cast<size_t>(j) * w + x;
      planes[kL1 * plane + i] = lab1[0];
      planes[kL2 * plane + i] = lab2[0];
      planes[kC1 * plane + i] = chroma1;
      planes[kC2 * plane + i] = chroma2;
      planes[kL1L1 * plane + i] = lab1[0] * lab1[0];
      planes[kL2L2 * plane + i] = lab2[0] * lab2[0];
      // chroma^2 rather than a^2 + b^2 (equal up to rounding), so that the variance and the
      // covariance terms are computed from the very same products.
      planes[kC1C1 * plane + i] = chroma1 * chroma1;
      planes[kC2C2 * plane + i] = chroma2 * chroma2;
      planes[kL1L2 * plane + i] = lab1[0] * lab2[0];
      planes[kC1C2 * plane + i] = chroma1 * chroma2;
      planes[kHue * plane + i] = std::sqrt(std::max(0.0, da * da + db * db - dc * dc));
    }
  }
  WindowValidityRows validity(in.valid, w, h, r);
  for (int64_t y = c0; y < c1; ++y) {
    const int j0 = static_cast<int>(y - c0);
    for (int q = 0; q < kCount; ++q) {
      double* v = vertical + static_cast<size_t>(q) * w;
      const double* src = planes + q * plane + static_cast<size_t>(j0) * w;
      for (int x = 0; x < w; ++x) v[x] = weights[0] * src[x];
      for (int k = 1; k <= 2 * r; ++k) {
        const double wk = weights[k];
        const double* s = src + static_cast<size_t>(k) * w;
        for (int x = 0; x < w; ++x) v[x] += wk * s[x];
      }
      double* f = filtered + static_cast<size_t>(q) * w;
      for (int x = r; x < w - r; ++x) {
        double s = 0;
        for (int k = 0; k <= 2 * r; ++k) s += weights[k] * v[x - r + k];
        f[x] = s;
      }
    }
    const uint8_t* ok = validity.Row(static_cast<int>(y));
    float* out = error->row(static_cast<int>(y));
    auto at = [&](int q, int x) { return filtered[static_cast<size_t>(q) * w + x]; };
    double s = 0;
    size_t n = 0;
    for (int x = 0; x < w; ++x) {
      if (x < r || x >= w - r || !ok[x]) {
        out[x] = kNaN;
        continue;
      }
      const double mu_l1 = at(kL1, x), mu_l2 = at(kL2, x);
      const double mu_c1 = at(kC1, x), mu_c2 = at(kC2, x);
      const double var_l1 = std::max(0.0, at(kL1L1, x) - mu_l1 * mu_l1);
      const double var_l2 = std::max(0.0, at(kL2L2, x) - mu_l2 * mu_l2);
      const double var_c1 = std::max(0.0, at(kC1C1, x) - mu_c1 * mu_c1);
      const double var_c2 = std::max(0.0, at(kC2C2, x) - mu_c2 * mu_c2);
      // sqrt(a * b) rather than sqrt(a) * sqrt(b): exact when a == b.
      const double sd_l12 = std::sqrt(var_l1 * var_l2);
      const double sd_c12 = std::sqrt(var_c1 * var_c2);
      const double cov_l = std::min(std::abs(at(kL1L2, x) - mu_l1 * mu_l2), sd_l12);
      const double cov_c = std::min(std::abs(at(kC1C2, x) - mu_c1 * mu_c2), sd_c12);
      const double dl = mu_l1 - mu_l2, dc = mu_c1 - mu_c2, dh = at(kHue, x);
      const double lightness_difference = 1.0 / (0.002 * dl * dl + 1.0);
      // 10 + (a + b), not 10 + a + b: with identical images a == b and the numerator 10 + 2a
      // rounds once, so the term is exactly 1 (two roundings could differ by an ulp).
      const double lightness_contrast = (10.0 + 2.0 * sd_l12) / (10.0 + (var_l1 + var_l2));
      const double lightness_structure = (10.0 + cov_l) / (10.0 + sd_l12);
      const double chroma_difference = 1.0 / (0.002 * dc * dc + 1.0);
      const double hue_difference = 1.0 / (0.002 * dh * dh + 1.0);
      const double chroma_contrast = (10.0 + 2.0 * sd_c12) / (10.0 + (var_c1 + var_c2));
      const double chroma_structure = (10.0 + cov_c) / (10.0 + sd_c12);
      const double similarity = lightness_difference * lightness_contrast * lightness_structure *
                                lightness_structure * lightness_structure * chroma_difference *
                                hue_difference * chroma_contrast * chroma_structure;
      out[x] = static_cast<float>(std::clamp(1.0 - similarity, 0.0, 1.0));
      s += out[x];
      ++n;
    }
    band_sums.sum[0] += s;
    band_sums.count[0] += n;
  }
  return band_sums;
}

}  // namespace internal

void ComputeIcid(const Image& photo, const Image& rephoto, const Mask& valid,
                 const IcidOptions& options, Image* error, double* mean, size_t* evaluated) {
  const int w = photo.width(), h = photo.height();
  const std::vector<float> wf = internal::FilterWeights(options.window / 2, options.sigma);
  const std::vector<double> weights(wf.begin(), wf.end());
  internal::RgbRows p, q;
  std::vector<float> unused;
  p.Load(photo, 0, h, &unused);
  q.Load(rephoto, 0, h, &unused);
  const internal::BandInputs in{p, q, valid, w, h};
  const internal::ErrorRows rows{error->data(), 0, w};
  const MeanSums sums = ParallelSum<MeanSums>(0, h, kBandRows, [&](int64_t y0, int64_t y1) {
    return internal::IcidBand(in, options.window, weights, &rows, y0, y1);
  });
  *evaluated = sums.count[0];
  *mean = sums.count[0] ? sums.sum[0] / static_cast<double>(sums.count[0])
                        : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace rephoto::metrics
