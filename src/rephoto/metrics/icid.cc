#include "rephoto/metrics/icid.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "rephoto/core/parallel.h"
#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/simd.h"

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

// SrgbDecode of the values of 8-bit samples (v / 255, the values of nearly every photo and
// rendering), by table.
struct SrgbTable {
  float value[256];
  double decoded[256];
};
const SrgbTable& DecodeTable() {
  static const SrgbTable table = [] {
    SrgbTable t;
    for (int k = 0; k < 256; ++k) {
      t.value[k] = static_cast<float>(k) / 255.f;
      t.decoded[k] = SrgbDecode(t.value[k]);
    }
    return t;
  }();
  return table;
}

// The table entry nearest to c, in [0, 255] for any c (NaN: 0).
inline int TableIndex(float c) {
  const float v = c >= 0.f ? (c <= 1.f ? c : 1.f) : 0.f;
  return static_cast<int>(v * 255.f + 0.5f);
}

// linear[i] = SrgbDecode(c[i]) by table for the n values that are 8-bit values; returns how
// many are not (their linear[i] is to be computed by the formula). No branches: vectorises.
[[gnu::always_inline]] inline int DecodeByTableBody(const float* __restrict c, int n,
                                                    const SrgbTable& table,
                                                    double* __restrict linear) {
  int misses = 0;
  for (int i = 0; i < n; ++i) {
    const int k = TableIndex(c[i]);
    linear[i] = table.decoded[k];
    misses += table.value[k] != c[i];
  }
  return misses;
}
REPHOTO_ISA_DISPATCH(int, DecodeByTable,
                     (const float* __restrict c, int n, const SrgbTable& table,
                      double* __restrict linear),
                     (c, n, table, linear))

// Planar linear RGB (r[0..w), g[w..2w), b[2w..3w)) of an interleaved sRGB row: by table, then
// the formula for values that are not 8-bit values; the same values as SrgbDecode everywhere.
void DecodeRow(const float* rgb, int w, double* linear) {
  thread_local std::vector<float> planar;
  planar.resize(3 * static_cast<size_t>(w));
  for (int x = 0; x < w; ++x) {
    planar[x] = rgb[3 * x];
    planar[w + x] = rgb[3 * x + 1];
    planar[2 * w + x] = rgb[3 * x + 2];
  }
  const SrgbTable& table = DecodeTable();
  if (DecodeByTable(planar.data(), 3 * w, table, linear) == 0) return;
  for (int i = 0; i < 3 * w; ++i) {
    const float c = planar[i];
    const int k = TableIndex(c);
    if (table.value[k] != c) linear[i] = SrgbDecode(c);
  }
}

// DecodeRow of 8-bit pixels (`channels` values each, RGB first): the table entries of the bytes,
// which are the values DecodeRow gives for the floats v / 255.f.
void DecodeBytes(const uint8_t* __restrict pixels, int channels, int w, double* __restrict linear) {
  const double* __restrict decoded = DecodeTable().decoded;
  for (int x = 0; x < w; ++x) {
    linear[x] = decoded[pixels[channels * x]];
    linear[w + x] = decoded[pixels[channels * x + 1]];
    linear[2 * w + x] = decoded[pixels[channels * x + 2]];
  }
}

// CIELAB in float (issue 29): the quantities pass was ~40 % of iCID in double (six cube roots
// with a division each and four divisions per pixel, 4 lanes per AVX2 vector); in float it runs
// 8 lanes and without libm. The cube root of positive normal floats below 2^42 in float
// arithmetic only, so that every instruction-set path and every libm give the same bits: the
// first estimate of fdlibm's cbrtf from the bits (their integer / 3 taken by a float product,
// which moves the estimate by < 1e-5 of its ~3 % error), then two Halley steps
// y (y^3 + 2x) / (2y^3 + x) (cubic convergence: ~3e-5, then below float precision). Within
// 1 ulp of the correctly rounded cube root (icid test). Garbage (but no trap) for other x.
inline float CbrtPositiveF(float x) {
  const int32_t bits = std::bit_cast<int32_t>(x);
  const int32_t third = static_cast<int32_t>(static_cast<float>(bits) * (1.0f / 3.0f));
  float y = std::bit_cast<float>(third + 709958130);
  float y3 = y * y * y;
  y = y * (y3 + (x + x)) / ((y3 + y3) + x);
  // The second step as a correction of y, y - y (y^3 - x) / (2y^3 + x), the same iterate: the
  // roundings of the small correction barely matter, so y ends within ~1 ulp.
  y3 = y * y * y;
  return y - y * (y3 - x) / ((y3 + y3) + x);
}

// Both branches computed, then selected: no control flow in the loop.
inline float LabFFloat(float t) {
  const float root = CbrtPositiveF(t), linear = 7.787f * t + static_cast<float>(16.0 / 116.0);
  return t > 0.008856f ? root : linear;
}

// The sRGB -> XYZ matrix of SrgbToLab with the white point's division folded into its rows.
constexpr float kXr = static_cast<float>(0.412453 / 0.95047);
constexpr float kXg = static_cast<float>(0.357580 / 0.95047);
constexpr float kXb = static_cast<float>(0.180423 / 0.95047);
constexpr float kZr = static_cast<float>(0.019334 / 1.08883);
constexpr float kZg = static_cast<float>(0.119193 / 1.08883);
constexpr float kZb = static_cast<float>(0.950227 / 1.08883);

// Planar float CIELAB (L, a, b planes of w) of planar linear RGB (r, g, b planes of w): the
// formulas of SrgbToLab in float; L within ~1e-5 and a, b within ~1e-4 of SrgbToLab's (a and b
// are 500 and 200 times a difference of cube roots; icid test), which moves iCID error values by
// up to ~1e-6 (the naive-loop tests hold at 1e-6 against SrgbToLab in double).
[[gnu::always_inline]] inline void LinearToLabRowBody(const double* __restrict linear, int w,
                                                      float* __restrict lab) {
  for (int x = 0; x < w; ++x) {
    const float rl = static_cast<float>(linear[x]);
    const float gl = static_cast<float>(linear[w + x]);
    const float bl = static_cast<float>(linear[2 * w + x]);
    const float fx = LabFFloat(kXr * rl + kXg * gl + kXb * bl);
    const float fy = LabFFloat(0.212671f * rl + 0.715160f * gl + 0.072169f * bl);
    const float fz = LabFFloat(kZr * rl + kZg * gl + kZb * bl);
    lab[x] = 116.0f * fy - 16.0f;
    lab[w + x] = 500.0f * (fx - fy);
    lab[2 * w + x] = 200.0f * (fy - fz);
  }
}
REPHOTO_ISA_DISPATCH(void, LinearToLabRow,
                     (const double* __restrict linear, int w, float* __restrict lab),
                     (linear, w, lab))

// Per-pixel quantities that get window-averaged.
enum Quantity { kL1, kL2, kC1, kC2, kL1L1, kL2L2, kC1C1, kC2C2, kL1L2, kC1C2, kHue, kCount };

// The kCount quantities of a row from the planar float CIELAB of photo (1) and rendering (2)
// (LinearToLabRow), in double, one __restrict pointer per output plane (through an array of
// pointers the loop did not vectorise).
[[gnu::always_inline]] inline void IcidQuantitiesRowBody(
    const float* __restrict lab1, const float* __restrict lab2, int w, double* __restrict o_l1,
    double* __restrict o_l2, double* __restrict o_c1, double* __restrict o_c2,
    double* __restrict o_l1l1, double* __restrict o_l2l2, double* __restrict o_c1c1,
    double* __restrict o_c2c2, double* __restrict o_l1l2, double* __restrict o_c1c2,
    double* __restrict o_hue) {
  for (int x = 0; x < w; ++x) {
    const double l1 = lab1[x], a1 = lab1[w + x], b1 = lab1[2 * w + x];
    const double l2 = lab2[x], a2 = lab2[w + x], b2 = lab2[2 * w + x];
    const double chroma1 = std::sqrt(a1 * a1 + b1 * b1), chroma2 = std::sqrt(a2 * a2 + b2 * b2);
    const double da = a1 - a2, db = b1 - b2, dc = chroma1 - chroma2;
    o_l1[x] = l1;
    o_l2[x] = l2;
    o_c1[x] = chroma1;
    o_c2[x] = chroma2;
    o_l1l1[x] = l1 * l1;
    o_l2l2[x] = l2 * l2;
    // chroma^2 rather than a^2 + b^2 (equal up to rounding), so that the variance and the
    // covariance terms are computed from the very same products.
    o_c1c1[x] = chroma1 * chroma1;
    o_c2c2[x] = chroma2 * chroma2;
    o_l1l2[x] = l1 * l2;
    o_c1c2[x] = chroma1 * chroma2;
    o_hue[x] = std::sqrt(std::max(0.0, da * da + db * db - dc * dc));
  }
}
REPHOTO_ISA_DISPATCH(void, IcidQuantitiesRow,
                     (const float* __restrict lab1, const float* __restrict lab2, int w,
                      double* __restrict o_l1, double* __restrict o_l2, double* __restrict o_c1,
                      double* __restrict o_c2, double* __restrict o_l1l1, double* __restrict o_l2l2,
                      double* __restrict o_c1c1, double* __restrict o_c2c2,
                      double* __restrict o_l1l2, double* __restrict o_c1c2,
                      double* __restrict o_hue),
                     (lab1, lab2, w, o_l1, o_l2, o_c1, o_c2, o_l1l1, o_l2l2, o_c1c1, o_c2c2,
                      o_l1l2, o_c1c2, o_hue))

void IcidQuantities(const float* lab1, const float* lab2, int w, double* const* out) {
  IcidQuantitiesRow(lab1, lab2, w, out[kL1], out[kL2], out[kC1], out[kC2], out[kL1L1],
                    out[kL2L2], out[kC1C1], out[kC2C2], out[kL1L2], out[kC1C2], out[kHue]);
}

// v[x] = w[r] src[x + r stride] + sum over k = 1..r of w[r + k] (src[x + (r - k) stride] +
// src[x + (r + k) stride]), r = taps / 2: the symmetric Gaussian's taps in pairs (6 products
// instead of 11 for the 11 taps), added from the centre out. Blocks of kAcc vectors of 4 values
// accumulated in registers over the taps (a loop per tap over the whole row loaded and stored v
// at every tap: load-bound; two vectors per block were add-latency-bound), then single vectors,
// then one value at a time: the same operations per value on every path (contraction is off in
// metrics/).
typedef double V4d __attribute__((vector_size(32)));

template <int kAcc>
[[gnu::always_inline]] inline int IcidVerticalBlocks(const double* __restrict src, size_t stride,
                                                     const double* __restrict weights, int taps,
                                                     int x, int w, double* __restrict v) {
  const int r = taps / 2;
  for (; x + 4 * kAcc <= w; x += 4 * kAcc) {
    V4d a[kAcc];
    const double* centre = src + static_cast<size_t>(r) * stride + x;
    for (int j = 0; j < kAcc; ++j) a[j] = weights[r] * REPHOTO_LOAD(V4d, centre + 4 * j);
    for (int k = 1; k <= r; ++k) {
      const double* up = src + static_cast<size_t>(r - k) * stride + x;
      const double* down = src + static_cast<size_t>(r + k) * stride + x;
      for (int j = 0; j < kAcc; ++j) {
        a[j] += weights[r + k] *
                (REPHOTO_LOAD(V4d, up + 4 * j) + REPHOTO_LOAD(V4d, down + 4 * j));
      }
    }
    for (int j = 0; j < kAcc; ++j) REPHOTO_STORE(v + x + 4 * j, a[j]);
  }
  return x;
}

[[gnu::always_inline]] inline void IcidVerticalBody(const double* __restrict src, size_t stride,
                                                    const double* __restrict weights, int taps,
                                                    int w, double* __restrict v) {
  int x = IcidVerticalBlocks<8>(src, stride, weights, taps, 0, w, v);
  x = IcidVerticalBlocks<1>(src, stride, weights, taps, x, w, v);
  const int r = taps / 2;
  for (; x < w; ++x) {
    double acc = weights[r] * src[static_cast<size_t>(r) * stride + x];
    for (int k = 1; k <= r; ++k) {
      acc += weights[r + k] * (src[static_cast<size_t>(r - k) * stride + x] +
                               src[static_cast<size_t>(r + k) * stride + x]);
    }
    v[x] = acc;
  }
}
REPHOTO_ISA_DISPATCH(void, IcidVertical,
                     (const double* __restrict src, size_t stride, const double* __restrict weights,
                      int taps, int w, double* __restrict v),
                     (src, stride, weights, taps, w, v))

// f[x] = w[r] v[x] + sum over k = 1..r of w[r + k] (v[x - k] + v[x + k]), for x in [r, w - r);
// in registers as IcidVerticalBody.
template <int kAcc>
[[gnu::always_inline]] inline int IcidHorizontalBlocks(const double* __restrict v,
                                                       const double* __restrict weights, int r,
                                                       int x, int end, double* __restrict f) {
  for (; x + 4 * kAcc <= end; x += 4 * kAcc) {
    V4d a[kAcc];
    for (int j = 0; j < kAcc; ++j) a[j] = weights[r] * REPHOTO_LOAD(V4d, v + x + 4 * j);
    for (int k = 1; k <= r; ++k) {
      for (int j = 0; j < kAcc; ++j) {
        a[j] += weights[r + k] *
                (REPHOTO_LOAD(V4d, v + x - k + 4 * j) + REPHOTO_LOAD(V4d, v + x + k + 4 * j));
      }
    }
    for (int j = 0; j < kAcc; ++j) REPHOTO_STORE(f + x + 4 * j, a[j]);
  }
  return x;
}

[[gnu::always_inline]] inline void IcidHorizontalBody(const double* __restrict v,
                                                      const double* __restrict weights, int r,
                                                      int w, double* __restrict f) {
  int x = IcidHorizontalBlocks<8>(v, weights, r, r, w - r, f);
  x = IcidHorizontalBlocks<1>(v, weights, r, x, w - r, f);
  for (; x < w - r; ++x) {
    double acc = weights[r] * v[x];
    for (int k = 1; k <= r; ++k) acc += weights[r + k] * (v[x - k] + v[x + k]);
    f[x] = acc;
  }
}
REPHOTO_ISA_DISPATCH(void, IcidHorizontal,
                     (const double* __restrict v, const double* __restrict weights, int r, int w,
                      double* __restrict f),
                     (v, weights, r, w, f))

// The error 1 - (product of the seven terms) of every x in [r, w - r) from the filtered planes
// (kCount planes of w values), whether or not the window is valid (selected afterwards).
[[gnu::always_inline]] inline void IcidFormulaBody(const double* __restrict filtered, int w, int r,
                                                   float* __restrict out) {
  auto plane = [&](int q) { return filtered + static_cast<size_t>(q) * w; };
  const double* __restrict l1 = plane(kL1);
  const double* __restrict l2 = plane(kL2);
  const double* __restrict c1 = plane(kC1);
  const double* __restrict c2 = plane(kC2);
  const double* __restrict l1l1 = plane(kL1L1);
  const double* __restrict l2l2 = plane(kL2L2);
  const double* __restrict c1c1 = plane(kC1C1);
  const double* __restrict c2c2 = plane(kC2C2);
  const double* __restrict l1l2 = plane(kL1L2);
  const double* __restrict c1c2 = plane(kC1C2);
  const double* __restrict hue = plane(kHue);
  for (int x = r; x < w - r; ++x) {
    const double mu_l1 = l1[x], mu_l2 = l2[x];
    const double mu_c1 = c1[x], mu_c2 = c2[x];
    const double var_l1 = std::max(0.0, l1l1[x] - mu_l1 * mu_l1);
    const double var_l2 = std::max(0.0, l2l2[x] - mu_l2 * mu_l2);
    const double var_c1 = std::max(0.0, c1c1[x] - mu_c1 * mu_c1);
    const double var_c2 = std::max(0.0, c2c2[x] - mu_c2 * mu_c2);
    // sqrt(a * b) rather than sqrt(a) * sqrt(b): exact when a == b.
    const double sd_l12 = std::sqrt(var_l1 * var_l2);
    const double sd_c12 = std::sqrt(var_c1 * var_c2);
    const double cov_l = std::min(std::abs(l1l2[x] - mu_l1 * mu_l2), sd_l12);
    const double cov_c = std::min(std::abs(c1c2[x] - mu_c1 * mu_c2), sd_c12);
    const double dl = mu_l1 - mu_l2, dc = mu_c1 - mu_c2, dh = hue[x];
    // The seven terms (the structure one cubed) as one fraction: the numerators' product over
    // the denominators' (one division per pixel instead of seven). Lightness difference
    // 1 / (0.002 dl^2 + 1), contrast (10 + 2 sd12) / (10 + (var1 + var2)) (10 + (a + b), not
    // 10 + a + b: with identical images a == b and 10 + 2a rounds once), structure
    // (10 + cov) / (10 + sd12); chroma alike; hue difference 1 / (0.002 dh^2 + 1). With
    // identical images every numerator equals its denominator and both products are formed in
    // the same order, so the similarity is exactly 1.
    const double l_contrast_n = 10.0 + 2.0 * sd_l12, l_contrast_d = 10.0 + (var_l1 + var_l2);
    const double l_structure_n = 10.0 + cov_l, l_structure_d = 10.0 + sd_l12;
    const double c_contrast_n = 10.0 + 2.0 * sd_c12, c_contrast_d = 10.0 + (var_c1 + var_c2);
    const double c_structure_n = 10.0 + cov_c, c_structure_d = 10.0 + sd_c12;
    const double numerator = l_contrast_n * l_structure_n * l_structure_n * l_structure_n *
                             c_contrast_n * c_structure_n;
    const double denominator = l_contrast_d * l_structure_d * l_structure_d * l_structure_d *
                               c_contrast_d * c_structure_d * (0.002 * dl * dl + 1.0) *
                               (0.002 * dc * dc + 1.0) * (0.002 * dh * dh + 1.0);
    const double similarity = numerator / denominator;
    out[x] = static_cast<float>(std::clamp(1.0 - similarity, 0.0, 1.0));
  }
}
REPHOTO_ISA_DISPATCH(void, IcidFormula,
                     (const double* __restrict filtered, int w, int r, float* __restrict out),
                     (filtered, w, r, out))

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

void LinearRgbToLabFloat(const double* linear, int w, float* lab) { LinearToLabRow(linear, w, lab); }
float CubeRootFloat(float x) { return CbrtPositiveF(x); }

uint64_t NewCallId() {
  static std::atomic<uint64_t> last{0};
  return last.fetch_add(1, std::memory_order_relaxed) + 1;
}

namespace {

// The quantity rows a band shares with the next one: band [c0, c1) computes source rows
// [c0 - r, c1 + r), the next band [c1, ...) needs [c1 - r, c1 + r) first, the last 2r. When the
// same thread does the next band of the same call, it copies them instead of recomputing (the
// quantities of a pixel do not depend on the strip or band around it). Per strip s and
// quantity q, 2r rows of the strip's width at (s * kCount + q) * 2r * max_width.
struct IcidCarry {
  uint64_t call = 0;  // 0: nothing held
  int64_t next_c0 = 0;
  int width = 0, radius = 0;
  std::vector<double> rows;
};

}  // namespace

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
  // The band in strips of kStripPixels output columns (plus r on each side), so that the
  // quantity planes of a strip (kCount planes of `rows` x strip values) stay in the core's
  // cache while every output row reads 2r+1 rows of each (whole-width planes were ~15 MB per
  // band at 4000 px and came from memory 2r+1 times). Per value the same arithmetic in the same
  // order as whole rows; the error row is written strip by strip, then summed as a whole row.
  constexpr int kStripPixels = 128;
  const int max_width = std::min(w, kStripPixels + 2 * r);
  const size_t plane = static_cast<size_t>(rows) * max_width;
  thread_local std::vector<double> buffer;
  if (buffer.size() < kCount * plane + 2 * kCount * static_cast<size_t>(max_width)) {
    buffer.resize(kCount * plane + 2 * kCount * static_cast<size_t>(max_width));
  }
  double* planes = buffer.data();
  double* vertical = planes + kCount * plane;
  double* filtered = vertical + kCount * static_cast<size_t>(max_width);
  thread_local std::vector<float> value_buffer;
  if (value_buffer.size() < static_cast<size_t>(max_width)) value_buffer.resize(max_width);
  float* values = value_buffer.data();
  thread_local std::vector<double> linear_buffer;
  if (linear_buffer.size() < 6 * static_cast<size_t>(max_width)) {
    linear_buffer.resize(6 * static_cast<size_t>(max_width));
  }
  double* linear1 = linear_buffer.data();
  double* linear2 = linear1 + 3 * max_width;
  thread_local std::vector<float> lab_buffer;
  if (lab_buffer.size() < 6 * static_cast<size_t>(max_width)) {
    lab_buffer.resize(6 * static_cast<size_t>(max_width));
  }
  float* lab1 = lab_buffer.data();
  float* lab2 = lab1 + 3 * max_width;
  thread_local IcidCarry carry;
  const bool reuse = in.call != 0 && carry.call == in.call && carry.next_c0 == c0 &&
                     carry.width == w && carry.radius == r;
  const size_t carry_rows = static_cast<size_t>(2 * r) * max_width;
  const int strips = (w + kStripPixels - 1) / kStripPixels;
  if (in.call != 0 && carry.rows.size() < strips * kCount * carry_rows) {
    carry.rows.resize(strips * kCount * carry_rows);
  }
  carry.call = 0;  // until this band has stored its rows
  for (int x0 = 0; x0 < w; x0 += kStripPixels) {
    // Source columns [s0, s1) feed the output columns [max(x0, r), min(x0 + strip, w - r)).
    const int s0 = std::max(0, x0 - r), s1 = std::min(w, x0 + kStripPixels + r), sw = s1 - s0;
    const int xa = std::max(x0, r), xb = std::min(x0 + kStripPixels, w - r);
    if (xa >= xb) continue;
    double* held = in.call != 0 ? carry.rows.data() +
                                      static_cast<size_t>(x0 / kStripPixels) * kCount * carry_rows
                                : nullptr;
    const size_t held_values = static_cast<size_t>(2 * r) * sw;
    if (reuse) {
      for (int q = 0; q < kCount; ++q) {
        std::copy(held + q * carry_rows, held + q * carry_rows + held_values, planes + q * plane);
      }
    }
    for (int j = reuse ? 2 * r : 0; j < rows; ++j) {
      const int y = static_cast<int>(c0) - r + j;
      for (const auto& [rgb, linear] : {std::pair{&in.photo, linear1}, {&in.rephoto, linear2}}) {
        if (const uint8_t* bytes = rgb->bytes_row(y)) {
          DecodeBytes(bytes + static_cast<size_t>(rgb->channels()) * s0, rgb->channels(), sw,
                      linear);
        } else {
          DecodeRow(rgb->row(y) + 3 * static_cast<size_t>(s0), sw, linear);
        }
      }
      double* row_planes[kCount];
      for (int q = 0; q < kCount; ++q) {
        row_planes[q] = planes + q * plane + static_cast<size_t>(j) * sw;
      }
      LinearToLabRow(linear1, sw, lab1);
      LinearToLabRow(linear2, sw, lab2);
      IcidQuantities(lab1, lab2, sw, row_planes);
    }
    if (held) {
      for (int q = 0; q < kCount; ++q) {
        const double* last = planes + q * plane + static_cast<size_t>(rows - 2 * r) * sw;
        std::copy(last, last + held_values, held + q * carry_rows);
      }
    }
    for (int64_t y = c0; y < c1; ++y) {
      const int j0 = static_cast<int>(y - c0);
      for (int q = 0; q < kCount; ++q) {
        double* v = vertical + static_cast<size_t>(q) * sw;
        const double* src = planes + q * plane + static_cast<size_t>(j0) * sw;
        IcidVertical(src, sw, weights.data(), 2 * r + 1, sw, v);
        IcidHorizontal(v, weights.data(), r, sw, filtered + static_cast<size_t>(q) * sw);
      }
      // Local column x - s0: values for local [r, sw - r), which holds [xa, xb).
      IcidFormula(filtered, sw, r, values);
      float* out = error->row(static_cast<int>(y));
      std::copy(values + (xa - s0), values + (xb - s0), out + xa);
    }
  }
  if (in.call != 0) {
    carry.call = in.call;
    carry.next_c0 = c1;
    carry.width = w;
    carry.radius = r;
  }
  WindowValidityRows validity(in.valid, w, h, r);
  for (int64_t y = c0; y < c1; ++y) {
    const uint8_t* ok = validity.Row(static_cast<int>(y));
    float* out = error->row(static_cast<int>(y));
    double s = 0;
    size_t n = 0;
    for (int x = 0; x < w; ++x) {
      if (x < r || x >= w - r || !ok[x]) {
        out[x] = kNaN;
        continue;
      }
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
  const internal::BandInputs in{p, q, valid, w, h, internal::NewCallId()};
  const internal::ErrorRows rows{error->data(), 0, w};
  const MeanSums sums = ParallelSum<MeanSums>(0, h, kBandRows, [&](int64_t y0, int64_t y1) {
    return internal::IcidBand(in, options.window, weights, &rows, y0, y1);
  });
  *evaluated = sums.count[0];
  *mean = sums.count[0] ? sums.sum[0] / static_cast<double>(sums.count[0])
                        : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace rephoto::metrics
