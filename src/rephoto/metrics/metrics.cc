#include "rephoto/metrics/metrics.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/metrics/icid.h"
#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/simd.h"

namespace rephoto::metrics {
namespace {

using internal::CensusValues;
using internal::FillNaN;
using internal::kBandRows;
using internal::kNaN;
using internal::MaskRange;
using internal::MeanSums;
using internal::WindowValidityRows;

using internal::Deinterleave8;
using internal::ErrorRows;
using internal::Scratch;
using internal::V8f;
using internal::V8i;
using Inputs = internal::BandInputs;

// ---------------------------------------------------------------------------------------------
// 1-NCC and ZSSD need, per window, the sums of x_c and y_c per channel c, and of
// sum_c x_c^2, sum_c y_c^2 and sum_c x_c y_c (9 planar quantities, in double so that
// E[x^2] - E[x]^2 does not cancel). Column sums slide down the band; row sums come from prefix
// sums, so the cost does not depend on the window.

constexpr int kBoxQuantities = 9;

// Splits an interleaved RGB row into three planes. Eight pixels at a time by shuffles (the
// compiler's stride-3 loop was a sixth of census's time); pure data movement.
[[gnu::always_inline]] inline void DeinterleaveBody(const float* __restrict rgb, int w,
                                                    float* __restrict c0, float* __restrict c1,
                                                    float* __restrict c2) {
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    V8f r, g, bl;
    Deinterleave8(rgb + 3 * x, &r, &g, &bl);
    __builtin_memcpy(c0 + x, &r, 32);
    __builtin_memcpy(c1 + x, &g, 32);
    __builtin_memcpy(c2 + x, &bl, 32);
  }
  for (; x < w; ++x) {
    c0[x] = rgb[3 * x];
    c1[x] = rgb[3 * x + 1];
    c2[x] = rgb[3 * x + 2];
  }
}
REPHOTO_ISA_DISPATCH(void, Deinterleave,
                     (const float* __restrict rgb, int w, float* __restrict c0,
                      float* __restrict c1, float* __restrict c2),
                     (rgb, w, c0, c1, c2))

// Census keys (kernels.h CensusKey) of an interleaved float RGB row, eight pixels at a time by
// shuffles: census alone needs no planes.
[[gnu::always_inline]] inline void CensusKeysInterleavedBody(const float* __restrict rgb, int w,
                                                             int16_t* __restrict keys) {
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    V8f r, g, bl;
    Deinterleave8(rgb + 3 * x, &r, &g, &bl);
    internal::CensusKeys8(&r, &g, &bl, keys + x);
  }
  for (; x < w; ++x) keys[x] = internal::CensusKey(rgb[3 * x], rgb[3 * x + 1], rgb[3 * x + 2]);
}
REPHOTO_ISA_DISPATCH(void, CensusKeysInterleaved,
                     (const float* __restrict rgb, int w, int16_t* __restrict keys),
                     (rgb, w, keys))

// cols[q * w + x] += quantity q of the planar rows p (3 planes) and q (3 planes); with
// `leaving` (kSlide), the same then -= quantity q of the planar rows `leaving`: the window's
// column sums move down one row in one pass over cols, with the operations (and so the values)
// of adding then subtracting in two passes. In the types of the double path (float planes,
// double sums) and of the exact path below (byte planes, int32 sums: every operation exact).
template <typename In, typename Acc, bool kSlide>
[[gnu::always_inline]] inline void ColumnSums(const In* __restrict planes,
                                              const In* __restrict leaving, int w,
                                              Acc* __restrict cols) {
  const In* __restrict a0 = planes;
  const In* __restrict a1 = planes + w;
  const In* __restrict a2 = planes + 2 * w;
  const In* __restrict b0 = planes + 3 * w;
  const In* __restrict b1 = planes + 4 * w;
  const In* __restrict b2 = planes + 5 * w;
  const In* __restrict la0 = leaving;
  const In* __restrict la1 = leaving + w;
  const In* __restrict la2 = leaving + 2 * w;
  const In* __restrict lb0 = leaving + 3 * w;
  const In* __restrict lb1 = leaving + 4 * w;
  const In* __restrict lb2 = leaving + 5 * w;
  Acc* __restrict sx0 = cols;
  Acc* __restrict sx1 = cols + w;
  Acc* __restrict sx2 = cols + 2 * w;
  Acc* __restrict sy0 = cols + 3 * w;
  Acc* __restrict sy1 = cols + 4 * w;
  Acc* __restrict sy2 = cols + 5 * w;
  Acc* __restrict sxx = cols + 6 * w;
  Acc* __restrict syy = cols + 7 * w;
  Acc* __restrict sxy = cols + 8 * w;
  // Three simple loops vectorise where one loop over fifteen streams does not.
  for (int x = 0; x < w; ++x) {
    Acc s0 = sx0[x] + static_cast<Acc>(a0[x]);
    Acc s1 = sx1[x] + static_cast<Acc>(a1[x]);
    Acc s2 = sx2[x] + static_cast<Acc>(a2[x]);
    if constexpr (kSlide) {
      s0 -= static_cast<Acc>(la0[x]);
      s1 -= static_cast<Acc>(la1[x]);
      s2 -= static_cast<Acc>(la2[x]);
    }
    sx0[x] = s0;
    sx1[x] = s1;
    sx2[x] = s2;
  }
  for (int x = 0; x < w; ++x) {
    Acc s0 = sy0[x] + static_cast<Acc>(b0[x]);
    Acc s1 = sy1[x] + static_cast<Acc>(b1[x]);
    Acc s2 = sy2[x] + static_cast<Acc>(b2[x]);
    if constexpr (kSlide) {
      s0 -= static_cast<Acc>(lb0[x]);
      s1 -= static_cast<Acc>(lb1[x]);
      s2 -= static_cast<Acc>(lb2[x]);
    }
    sy0[x] = s0;
    sy1[x] = s1;
    sy2[x] = s2;
  }
  for (int x = 0; x < w; ++x) {
    const Acc p0 = a0[x], p1 = a1[x], p2 = a2[x];
    const Acc q0 = b0[x], q1 = b1[x], q2 = b2[x];
    Acc xx = sxx[x] + (p0 * p0 + p1 * p1 + p2 * p2);
    Acc yy = syy[x] + (q0 * q0 + q1 * q1 + q2 * q2);
    Acc xy = sxy[x] + (p0 * q0 + p1 * q1 + p2 * q2);
    if constexpr (kSlide) {
      const Acc lp0 = la0[x], lp1 = la1[x], lp2 = la2[x];
      const Acc lq0 = lb0[x], lq1 = lb1[x], lq2 = lb2[x];
      xx -= lp0 * lp0 + lp1 * lp1 + lp2 * lp2;
      yy -= lq0 * lq0 + lq1 * lq1 + lq2 * lq2;
      xy -= lp0 * lq0 + lp1 * lq1 + lp2 * lq2;
    }
    sxx[x] = xx;
    syy[x] = yy;
    sxy[x] = xy;
  }
}
// Adds the planes `entering` to the column sums, and subtracts `leaving` unless it is null. One
// overload per path (float planes into double sums, byte planes into int32 sums).
template <typename In, typename Acc>
[[gnu::always_inline]] inline void BoxColumnsBody(const In* __restrict entering,
                                                  const In* __restrict leaving, int w,
                                                  Acc* __restrict cols) {
  if (leaving) {
    ColumnSums<In, Acc, true>(entering, leaving, w, cols);
  } else {
    ColumnSums<In, Acc, false>(entering, entering, w, cols);
  }
}
REPHOTO_ISA_DISPATCH(void, BoxColumns,
                     (const float* __restrict entering, const float* __restrict leaving, int w,
                      double* __restrict cols),
                     (entering, leaving, w, cols))
REPHOTO_ISA_DISPATCH(void, BoxColumns,
                     (const uint8_t* __restrict entering, const uint8_t* __restrict leaving, int w,
                      int32_t* __restrict cols),
                     (entering, leaving, w, cols))

// prefix[q * (w + 1) + x + 1] = prefix[q * (w + 1) + x] + cols[q * w + x]. Independent chains
// are interleaved so the adds overlap, kChains quantities per pass starting at q0 (all nine in
// one loop needed 18 pointers: the compiler kept them on the stack and reloaded them).
template <int kChains>
[[gnu::always_inline]] inline void BoxPrefixChains(const double* __restrict cols, int w, int q0,
                                                   double* __restrict prefix) {
  const int m = w + 1;
  const double* __restrict in[kChains];
  double* __restrict out[kChains];
  double run[kChains];
  for (int c = 0; c < kChains; ++c) {
    in[c] = cols + static_cast<size_t>(q0 + c) * w;
    out[c] = prefix + static_cast<size_t>(q0 + c) * m;
    out[c][0] = 0;
    run[c] = 0;
  }
  for (int x = 0; x < w; ++x) {
    for (int c = 0; c < kChains; ++c) {
      run[c] += in[c][x];
      out[c][x + 1] = run[c];
    }
  }
}

void BoxPrefix(const double* __restrict cols, int w, double* __restrict prefix) {
  static_assert(kBoxQuantities == 9);
  BoxPrefixChains<5>(cols, w, 0, prefix);
  BoxPrefixChains<4>(cols, w, 5, prefix);
}

// 1-NCC of a window from its (scaled) summed squared deviations dx, dy and co-deviation dxy,
// with the flat rule at `flat` in the same units (both paths; the same operations).
[[gnu::always_inline]] inline float NccFromDeviations(double dx, double dy, double dxy,
                                                      double flat) {
  const bool flat_x = dx <= flat, flat_y = dy <= flat;
  double e = 1.0 - dxy / std::sqrt(dx * dy);
  e = e < 0.0 ? 0.0 : (e > 2.0 ? 2.0 : e);
  e = flat_x ? (flat_y ? 0.0 : 1.0) : (flat_y ? 1.0 : e);
  return static_cast<float>(e);
}

// 1-NCC and ZSSD for centres x in [r, w - r) (no validity test yet).
[[gnu::always_inline]] inline void BoxErrorsBody(const double* __restrict prefix, int w, int r,
                                                 double inv_count, double flat,
                                                 float* __restrict ncc, float* __restrict zssd) {
  const int m = w + 1;
  const double* __restrict p[kBoxQuantities];
  for (int q = 0; q < kBoxQuantities; ++q) p[q] = prefix + q * m;
  for (int x = r; x < w - r; ++x) {
    const int hi = x + r + 1, lo = x - r;
    const double sx0 = p[0][hi] - p[0][lo], sx1 = p[1][hi] - p[1][lo], sx2 = p[2][hi] - p[2][lo];
    const double sy0 = p[3][hi] - p[3][lo], sy1 = p[4][hi] - p[4][lo], sy2 = p[5][hi] - p[5][lo];
    const double sxx = p[6][hi] - p[6][lo], syy = p[7][hi] - p[7][lo];
    const double sxy = p[8][hi] - p[8][lo];
    // Summed squared deviations from the per-channel window means, and co-deviation.
    const double dx = sxx - (sx0 * sx0 + sx1 * sx1 + sx2 * sx2) * inv_count;
    const double dy = syy - (sy0 * sy0 + sy1 * sy1 + sy2 * sy2) * inv_count;
    const double dxy = sxy - (sx0 * sy0 + sx1 * sy1 + sx2 * sy2) * inv_count;
    ncc[x] = NccFromDeviations(dx, dy, dxy, flat);
    const double z = dx + dy - 2.0 * dxy;
    zssd[x] = static_cast<float>((z > 0.0 ? z : 0.0) * inv_count * (1.0 / 3.0));
  }
}
REPHOTO_ISA_DISPATCH(void, BoxErrors,
                     (const double* __restrict prefix, int w, int r, double inv_count, double flat,
                      float* __restrict ncc, float* __restrict zssd),
                     (prefix, w, r, inv_count, flat, ncc, zssd))

// ---------------------------------------------------------------------------------------------
// The exact path of 1-NCC and ZSSD. When every value of a band's source rows is k / 255.f for an
// integer k (8-bit inputs, and floats converted from them as io::ReadImage does), the window
// sums are sums of the integers k, k^2 and k k': exact in 32-bit integers, and the deviations
// n sum(k^2) - (sum k)^2 exact in double. The errors are then the correctly computed formula
// of exact window statistics (one rounding each in dx dy, the square root, the division),
// whereas the double path rounds while it sums; both agree within ~1e-12 before the error is
// stored as a float. Integer sums are the same on every ISA whatever the compiler vectorises.

// Windows up to 9 x 9 (the default; windows are odd): n^2 3 255^2 < 2^31 holds up to n = 104,
// so every window sum and deviation below fits in int32.
constexpr int kMaxExactWindow = 9;

// The red, green and blue bytes of 16 interleaved 8-bit pixels (3 or 4 channels: alpha dropped),
// by byte shuffles (the compiler's stride-3 loop was scalar: 12 % of census alone at 12 MP).
typedef unsigned char V16u8 __attribute__((vector_size(16)));
[[gnu::always_inline]] inline void DeinterleaveBytes16(const uint8_t* row, int channels,
                                                       V16u8* red, V16u8* green, V16u8* blue) {
  if (channels == 4) {
    V16u8 a, b, c, d;
    __builtin_memcpy(&a, row, 16);
    __builtin_memcpy(&b, row + 16, 16);
    __builtin_memcpy(&c, row + 32, 16);
    __builtin_memcpy(&d, row + 48, 16);
    // Per pair of vectors, the first 8 lanes red, then green; blue by itself.
    const V16u8 rg_ab =
        __builtin_shufflevector(a, b, 0, 4, 8, 12, 16, 20, 24, 28, 1, 5, 9, 13, 17, 21, 25, 29);
    const V16u8 rg_cd =
        __builtin_shufflevector(c, d, 0, 4, 8, 12, 16, 20, 24, 28, 1, 5, 9, 13, 17, 21, 25, 29);
    const V16u8 b_ab =
        __builtin_shufflevector(a, b, 2, 6, 10, 14, 18, 22, 26, 30, 2, 6, 10, 14, 18, 22, 26, 30);
    const V16u8 b_cd =
        __builtin_shufflevector(c, d, 2, 6, 10, 14, 18, 22, 26, 30, 2, 6, 10, 14, 18, 22, 26, 30);
    *red = __builtin_shufflevector(rg_ab, rg_cd, 0, 1, 2, 3, 4, 5, 6, 7, 16, 17, 18, 19, 20, 21,
                                   22, 23);
    *green = __builtin_shufflevector(rg_ab, rg_cd, 8, 9, 10, 11, 12, 13, 14, 15, 24, 25, 26, 27,
                                     28, 29, 30, 31);
    *blue = __builtin_shufflevector(b_ab, b_cd, 0, 1, 2, 3, 4, 5, 6, 7, 16, 17, 18, 19, 20, 21, 22,
                                    23);
    return;
  }
  V16u8 a, b, c;
  __builtin_memcpy(&a, row, 16);
  __builtin_memcpy(&b, row + 16, 16);
  __builtin_memcpy(&c, row + 32, 16);
  // Red is bytes 0, 3, ..., 45 of the 48: 6 from a, 5 from b, 5 from c; green and blue alike.
  const V16u8 red_ab =
      __builtin_shufflevector(a, b, 0, 3, 6, 9, 12, 15, 18, 21, 24, 27, 30, 0, 0, 0, 0, 0);
  const V16u8 green_ab =
      __builtin_shufflevector(a, b, 1, 4, 7, 10, 13, 16, 19, 22, 25, 28, 31, 0, 0, 0, 0, 0);
  const V16u8 blue_ab =
      __builtin_shufflevector(a, b, 2, 5, 8, 11, 14, 17, 20, 23, 26, 29, 0, 0, 0, 0, 0, 0);
  *red = __builtin_shufflevector(red_ab, c, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 17, 20, 23, 26, 29);
  *green =
      __builtin_shufflevector(green_ab, c, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 18, 21, 24, 27, 30);
  *blue = __builtin_shufflevector(blue_ab, c, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 16, 19, 22, 25, 28, 31);
}

// The byte planes of an interleaved 8-bit row (3 or 4 channels: alpha dropped).
[[gnu::always_inline]] inline void BytePlanesBody(const uint8_t* __restrict row, int channels,
                                                  int w, uint8_t* __restrict c0,
                                                  uint8_t* __restrict c1, uint8_t* __restrict c2) {
  int x = 0;
  for (; x + 16 <= w; x += 16) {
    V16u8 red, green, blue;
    DeinterleaveBytes16(row + channels * x, channels, &red, &green, &blue);
    __builtin_memcpy(c0 + x, &red, 16);
    __builtin_memcpy(c1 + x, &green, 16);
    __builtin_memcpy(c2 + x, &blue, 16);
  }
  for (; x < w; ++x) {
    c0[x] = row[channels * x];
    c1[x] = row[channels * x + 1];
    c2[x] = row[channels * x + 2];
  }
}
REPHOTO_ISA_DISPATCH(void, BytePlanes,
                     (const uint8_t* __restrict row, int channels, int w, uint8_t* __restrict c0,
                      uint8_t* __restrict c1, uint8_t* __restrict c2),
                     (row, channels, w, c0, c1, c2))

// The byte planes k of an interleaved float RGB row whose every value is k / 255.f; false
// (planes then undefined) when some value is not (NaN and values outside [0, 1] included).
[[gnu::always_inline]] inline bool FloatBytePlanesBody(const float* __restrict rgb, int w,
                                                       uint8_t* __restrict c0,
                                                       uint8_t* __restrict c1,
                                                       uint8_t* __restrict c2) {
  int fails = 0;
  uint8_t* __restrict planes[3] = {c0, c1, c2};
  for (int c = 0; c < 3; ++c) {
    uint8_t* __restrict plane = planes[c];
    for (int x = 0; x < w; ++x) {
      const float v = rgb[3 * x + c];
      const bool in_range = v >= 0.f && v <= 1.f;  // false for NaN
      const int k = static_cast<int>((in_range ? v : 0.f) * 255.f + 0.5f);
      fails += !in_range || static_cast<float>(k) / 255.f != v;
      plane[x] = static_cast<uint8_t>(k);
    }
  }
  return fails == 0;
}
REPHOTO_ISA_DISPATCH(bool, FloatBytePlanes,
                     (const float* __restrict rgb, int w, uint8_t* __restrict c0,
                      uint8_t* __restrict c1, uint8_t* __restrict c2),
                     (rgb, w, c0, c1, c2))

// The window's deviation sums of centres x in [r, w - r), in units of k: dx = n sum_c x_c^2 -
// sum_c (sum x_c)^2 (n x the summed squared deviation from the per-channel means), dy the same
// of the rephoto, dxy = n sum_c x_c y_c - sum_c (sum x_c)(sum y_c). The window sums are added
// from the column sums directly (2r + 1 loads per quantity and 8 centres); every value is an
// integer below 2^31 for windows up to kMaxExactWindow, so int32 arithmetic is exact on every
// path however it is vectorised.
template <int kR>  // the radius when known at compile time (the default window), else 0
[[gnu::always_inline]] inline void ExactDeviationsRadius(const int32_t* __restrict cols, int w,
                                                         int r, int32_t n, int32_t* __restrict dx,
                                                         int32_t* __restrict dy,
                                                         int32_t* __restrict dxy) {
  if constexpr (kR > 0) r = kR;
  const int32_t* __restrict c[kBoxQuantities];
  for (int q = 0; q < kBoxQuantities; ++q) c[q] = cols + static_cast<size_t>(q) * w;
  int x = r;
  for (; x + 8 <= w - r; x += 8) {
    V8i sum[kBoxQuantities];
    for (int q = 0; q < kBoxQuantities; ++q) {
      sum[q] = REPHOTO_LOAD(V8i, c[q] + x - r);
      for (int k = 1; k <= 2 * r; ++k) sum[q] += REPHOTO_LOAD(V8i, c[q] + x - r + k);
    }
    const V8i vx = n * sum[6] - (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
    const V8i vy = n * sum[7] - (sum[3] * sum[3] + sum[4] * sum[4] + sum[5] * sum[5]);
    const V8i vxy = n * sum[8] - (sum[0] * sum[3] + sum[1] * sum[4] + sum[2] * sum[5]);
    REPHOTO_STORE(dx + x, vx);
    REPHOTO_STORE(dy + x, vy);
    REPHOTO_STORE(dxy + x, vxy);
  }
  for (; x < w - r; ++x) {
    int32_t sum[kBoxQuantities];
    for (int q = 0; q < kBoxQuantities; ++q) {
      sum[q] = 0;
      for (int k = 0; k <= 2 * r; ++k) sum[q] += c[q][x - r + k];
    }
    dx[x] = n * sum[6] - (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
    dy[x] = n * sum[7] - (sum[3] * sum[3] + sum[4] * sum[4] + sum[5] * sum[5]);
    dxy[x] = n * sum[8] - (sum[0] * sum[3] + sum[1] * sum[4] + sum[2] * sum[5]);
  }
}
[[gnu::always_inline]] inline void ExactDeviationsBody(const int32_t* __restrict cols, int w, int r,
                                                       int32_t n, int32_t* __restrict dx,
                                                       int32_t* __restrict dy,
                                                       int32_t* __restrict dxy) {
  if (r == 4) {
    ExactDeviationsRadius<4>(cols, w, r, n, dx, dy, dxy);
  } else {
    ExactDeviationsRadius<0>(cols, w, r, n, dx, dy, dxy);
  }
}
REPHOTO_ISA_DISPATCH(void, ExactDeviations,
                     (const int32_t* __restrict cols, int w, int r, int32_t n,
                      int32_t* __restrict dx, int32_t* __restrict dy, int32_t* __restrict dxy),
                     (cols, w, r, n, dx, dy, dxy))

// 1-NCC and ZSSD for centres x in [r, w - r) from the exact deviation sums (no validity test
// yet). flat_scaled = the flat threshold in units of k (flat n 255^2); zssd_scale = 1 / (n^2
// 255^2 3). In double: dx dy rounds once, then the square root and the division; z is exact.
[[gnu::always_inline]] inline void ExactErrorsBody(const int32_t* __restrict dx_row,
                                                   const int32_t* __restrict dy_row,
                                                   const int32_t* __restrict dxy_row, int w, int r,
                                                   double flat_scaled, double zssd_scale,
                                                   float* __restrict ncc, float* __restrict zssd) {
  for (int x = r; x < w - r; ++x) {
    const double dx = dx_row[x], dy = dy_row[x], dxy = dxy_row[x];
    ncc[x] = NccFromDeviations(dx, dy, dxy, flat_scaled);
    const double z = dx + dy - 2.0 * dxy;
    zssd[x] = static_cast<float>((z > 0.0 ? z : 0.0) * zssd_scale);
  }
}
REPHOTO_ISA_DISPATCH(void, ExactErrors,
                     (const int32_t* __restrict dx_row, const int32_t* __restrict dy_row,
                      const int32_t* __restrict dxy_row, int w, int r, double flat_scaled,
                      double zssd_scale, float* __restrict ncc, float* __restrict zssd),
                     (dx_row, dy_row, dxy_row, w, r, flat_scaled, zssd_scale, ncc, zssd))

double MaskRow(const float* values, const uint8_t* ok, int w, float* out) {
  return MaskRange(values, ok, 0, w, out);
}

size_t CountRow(const uint8_t* __restrict ok, int w, int r) {
  size_t n = 0;
  for (int x = r; x < w - r; ++x) n += ok[x] != 0;
  return n;
}

// ---------------------------------------------------------------------------------------------
// Census on luma.

// Census keys of planar float rows.
[[gnu::always_inline]] inline void CensusKeysPlanarBody(const float* __restrict red,
                                                        const float* __restrict green,
                                                        const float* __restrict blue, int w,
                                                        int16_t* __restrict keys) {
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    const V8f r = REPHOTO_LOAD(V8f, red + x), g = REPHOTO_LOAD(V8f, green + x),
              b = REPHOTO_LOAD(V8f, blue + x);
    internal::CensusKeys8(&r, &g, &b, keys + x);
  }
  for (; x < w; ++x) keys[x] = internal::CensusKey(red[x], green[x], blue[x]);
}
REPHOTO_ISA_DISPATCH(void, CensusKeysPlanar,
                     (const float* __restrict red, const float* __restrict green,
                      const float* __restrict blue, int w, int16_t* __restrict keys),
                     (red, green, blue, w, keys))

// Census keys of 8-bit values (kernels.h CensusKeyOfBytes), 16 at a time in 16-bit lanes.
typedef unsigned short V16u16 __attribute__((vector_size(32)));
[[gnu::always_inline]] inline void CensusKeys16(const V16u8* red, const V16u8* green,
                                                const V16u8* blue, int16_t* keys) {
  const V16u16 r = __builtin_convertvector(*red, V16u16);
  const V16u16 g = __builtin_convertvector(*green, V16u16);
  const V16u16 b = __builtin_convertvector(*blue, V16u16);
  const V16u16 a = 74 * r + 146 * g + 28 * b;
  const V16u16 low = 3 * r + 3 * g + 2 * b;
  const V16u16 k = a + (low >> 2) - 32768;
  __builtin_memcpy(keys, &k, 32);
}

// Census keys of 8-bit planes.
[[gnu::always_inline]] inline void CensusKeysOfBytesBody(const uint8_t* __restrict red,
                                                         const uint8_t* __restrict green,
                                                         const uint8_t* __restrict blue, int w,
                                                         int16_t* __restrict keys) {
  int x = 0;
  for (; x + 16 <= w; x += 16) {
    V16u8 r, g, b;
    __builtin_memcpy(&r, red + x, 16);
    __builtin_memcpy(&g, green + x, 16);
    __builtin_memcpy(&b, blue + x, 16);
    CensusKeys16(&r, &g, &b, keys + x);
  }
  for (; x < w; ++x) keys[x] = internal::CensusKeyOfBytes(red[x], green[x], blue[x]);
}
REPHOTO_ISA_DISPATCH(void, CensusKeysOfBytes,
                     (const uint8_t* __restrict red, const uint8_t* __restrict green,
                      const uint8_t* __restrict blue, int w, int16_t* __restrict keys),
                     (red, green, blue, w, keys))

// 1-NCC, ZSSD and census share the window and the source rows: each source row is split into
// planes and converted to census keys once, and kept in a ring of 2r+2 rows (the window plus the row
// that leaves the column sums). With `exact`, 1-NCC and ZSSD take the exact path (above); it
// returns false as soon as a source row holds a value that is not k / 255.f (the caller then
// runs the band again without it).
bool WindowBandPass(const Inputs& in, int window, double flat, const ErrorRows* ncc,
                    const ErrorRows* zssd, const ErrorRows* census, int64_t y0, int64_t y1,
                    bool exact, MeanSums* out_sums) {
  const int w = in.width, h = in.height, r = window / 2;
  const bool box = ncc != nullptr || zssd != nullptr;
  MeanSums& sums = *out_sums;
  sums = MeanSums();
  const int64_t c0 = std::max<int64_t>(y0, r), c1 = std::min<int64_t>(y1, h - r);
  for (int64_t y = y0; y < y1; ++y) {
    if (y >= c0 && y < c1 && w >= window) continue;
    for (const ErrorRows* out : {ncc, zssd, census}) {
      if (out) FillNaN(out->row(static_cast<int>(y)), w);
    }
  }
  if (c0 >= c1 || w < window) return true;
  // Ring slot: photo R, G, B, rephoto R, G, B (6 planes of w; on the exact path bytes at the
  // start of the slot); census keys of the photo and the rephoto in their own ring (2 x w).
  const int ring = 2 * r + 2;
  const size_t slot_size = static_cast<size_t>(6) * w;
  thread_local std::vector<int16_t> key_buffer;
  int16_t* key_slots = census ? Scratch(key_buffer, ring * 2 * static_cast<size_t>(w)) : nullptr;
  auto keys = [&](int64_t j) { return key_slots + static_cast<size_t>(j % ring) * 2 * w; };
  thread_local std::vector<float> float_buffer;
  float* slots = Scratch(float_buffer, ring * slot_size + 3 * static_cast<size_t>(w));
  float* ncc_values = slots + ring * slot_size;
  float* zssd_values = ncc_values + w;
  thread_local std::vector<double> double_buffer;
  thread_local std::vector<int32_t> int_buffer;
  const bool double_box = box && !exact;
  double* cols = double_box
                     ? Scratch(double_buffer, static_cast<size_t>(kBoxQuantities) * (2 * w + 1))
                     : nullptr;
  double* prefix = double_box ? cols + kBoxQuantities * w : nullptr;
  // Column sums (kBoxQuantities rows of w), then the deviation rows dx, dy, dxy.
  int32_t* exact_cols =
      exact ? Scratch(int_buffer, static_cast<size_t>(kBoxQuantities + 3) * w) : nullptr;
  int32_t* deviations = exact ? exact_cols + static_cast<size_t>(kBoxQuantities) * w : nullptr;
  auto slot = [&](int64_t j) { return slots + static_cast<size_t>(j % ring) * slot_size; };
  auto bytes = [&](int64_t j) { return reinterpret_cast<uint8_t*>(slot(j)); };
  // Loads source row j into its slot; false when the exact path cannot take it.
  auto load = [&](int64_t j) {
    float* s = slot(j);
    const int yj = static_cast<int>(j);
    const uint8_t* photo_bytes = in.photo.bytes_row(yj);
    const uint8_t* rephoto_bytes = in.rephoto.bytes_row(yj);
    uint8_t* b = bytes(j);
    if (!box) {  // census alone: keys only, from the bytes when there are any
      // (Keys straight from the interleaved bytes, without the planes, measured no faster.)
      if (photo_bytes) {
        BytePlanes(photo_bytes, in.photo.channels(), w, b, b + w, b + 2 * w);
        CensusKeysOfBytes(b, b + w, b + 2 * w, w, keys(j));
      } else {
        CensusKeysInterleaved(in.photo.row(yj), w, keys(j));
      }
      if (rephoto_bytes) {
        BytePlanes(rephoto_bytes, in.rephoto.channels(), w, b + 3 * w, b + 4 * w, b + 5 * w);
        CensusKeysOfBytes(b + 3 * w, b + 4 * w, b + 5 * w, w, keys(j) + w);
      } else {
        CensusKeysInterleaved(in.rephoto.row(yj), w, keys(j) + w);
      }
      return true;
    }
    if (exact) {
      bool ok = true;
      if (photo_bytes) {
        BytePlanes(photo_bytes, in.photo.channels(), w, b, b + w, b + 2 * w);
      } else {
        ok = FloatBytePlanes(in.photo.row(yj), w, b, b + w, b + 2 * w);
      }
      if (rephoto_bytes) {
        BytePlanes(rephoto_bytes, in.rephoto.channels(), w, b + 3 * w, b + 4 * w, b + 5 * w);
      } else {
        ok = ok && FloatBytePlanes(in.rephoto.row(yj), w, b + 3 * w, b + 4 * w, b + 5 * w);
      }
      if (ok && census) {  // the keys of the bytes are those of their floats (CensusKey)
        CensusKeysOfBytes(b, b + w, b + 2 * w, w, keys(j));
        CensusKeysOfBytes(b + 3 * w, b + 4 * w, b + 5 * w, w, keys(j) + w);
      }
      return ok;
    }
    const float* p = in.photo.row(yj);
    const float* q = in.rephoto.row(yj);
    Deinterleave(p, w, s, s + w, s + 2 * w);
    Deinterleave(q, w, s + 3 * w, s + 4 * w, s + 5 * w);
    if (census) {
      CensusKeysPlanar(s, s + w, s + 2 * w, w, keys(j));
      CensusKeysPlanar(s + 3 * w, s + 4 * w, s + 5 * w, w, keys(j) + w);
    }
    return true;
  };
  if (double_box) std::fill(cols, cols + kBoxQuantities * w, 0.0);
  if (exact) std::fill(exact_cols, exact_cols + kBoxQuantities * w, 0);
  for (int64_t j = c0 - r; j <= c0 + r; ++j) {
    if (!load(j)) return false;
    if (double_box) BoxColumns(slot(j), nullptr, w, cols);
    if (exact) BoxColumns(bytes(j), nullptr, w, exact_cols);
  }
  WindowValidityRows validity(in.valid, w, h, r);
  const double inv_count = 1.0 / (static_cast<double>(window) * window);
  const double n = static_cast<double>(window) * window;
  const double flat_scaled = flat * n * (255.0 * 255.0);
  const double zssd_scale = 1.0 / (n * n * (255.0 * 255.0) * 3.0);
  const float inv_bits = 1.0f / static_cast<float>(window * window - 1);
  std::vector<const int16_t*> photo_rows(2 * r + 1), rephoto_rows(2 * r + 1);
  for (int64_t y = c0; y < c1; ++y) {
    const int yi = static_cast<int>(y);
    if (y > c0) {
      if (!load(y + r)) return false;
      if (double_box) BoxColumns(slot(y + r), slot(y - r - 1), w, cols);
      if (exact) BoxColumns(bytes(y + r), bytes(y - r - 1), w, exact_cols);
    }
    const uint8_t* ok = validity.Row(yi);
    const size_t evaluated = CountRow(ok, w, r);
    if (box) {
      if (exact) {
        ExactDeviations(exact_cols, w, r, window * window, deviations, deviations + w,
                        deviations + 2 * w);
        ExactErrors(deviations, deviations + w, deviations + 2 * w, w, r, flat_scaled, zssd_scale,
                    ncc_values, zssd_values);
      } else {
        BoxPrefix(cols, w, prefix);
        BoxErrors(prefix, w, r, inv_count, flat, ncc_values, zssd_values);
      }
      if (ncc) sums.sum[0] += MaskRow(ncc_values, ok, w, ncc->row(yi));
      if (zssd) sums.sum[1] += MaskRow(zssd_values, ok, w, zssd->row(yi));
      sums.count[0] += evaluated;
      sums.count[1] += evaluated;
    }
    if (census) {
      for (int k = 0; k <= 2 * r; ++k) {
        photo_rows[k] = keys(y - r + k);
        rephoto_rows[k] = keys(y - r + k) + w;
      }
      float* census_values = zssd_values + w;
      const int done =
          CensusValues(photo_rows.data(), rephoto_rows.data(), r, w, inv_bits, census_values);
      for (int x = done; x < w - r; ++x) {  // tail
        int n = 0;
        const int16_t cp = photo_rows[r][x], cr = rephoto_rows[r][x];
        for (int k = 0; k <= 2 * r; ++k) {
          for (int dx = -r; dx <= r; ++dx) {
            n += (photo_rows[k][x + dx] < cp) != (rephoto_rows[k][x + dx] < cr);
          }
        }
        census_values[x] = static_cast<float>(n) * inv_bits;
      }
      const double s = MaskRow(census_values, ok, w, census->row(yi));
      sums.sum[2] += s;
      sums.count[2] += evaluated;
    }
  }
  return true;
}

MeanSums WindowBand(const Inputs& in, int window, double flat, const ErrorRows* ncc,
                    const ErrorRows* zssd, const ErrorRows* census, int64_t y0, int64_t y1) {
  MeanSums sums;
  const bool try_exact = (ncc != nullptr || zssd != nullptr) && window <= kMaxExactWindow;
  if (!try_exact || !WindowBandPass(in, window, flat, ncc, zssd, census, y0, y1, true, &sums)) {
    WindowBandPass(in, window, flat, ncc, zssd, census, y0, y1, false, &sums);
  }
  return sums;
}

// ---------------------------------------------------------------------------------------------
// Pixel metrics: Cb+Cr and the squared error of PSNR.

typedef double V4d __attribute__((vector_size(32)));
typedef float V4f __attribute__((vector_size(16)));
typedef unsigned char V8u8 __attribute__((vector_size(8)));
typedef int V4i __attribute__((vector_size(16)));
typedef long long V4l __attribute__((vector_size(32)));

// (dr^2 + dg^2 + db^2) / 3 in double of four pixels' float differences.
// (Vectors through pointers: see simd.h on the ABI.)
[[gnu::always_inline]] inline void SquaredError4(const V4f* dr, const V4f* dg, const V4f* db,
                                                 V4d* e) {
  const V4d r = __builtin_convertvector(*dr, V4d);
  const V4d g = __builtin_convertvector(*dg, V4d);
  const V4d b = __builtin_convertvector(*db, V4d);
  *e = (r * r + g * g + b * b) / 3.0;
}

// Cb+Cr difference and squared error (of PSNR) of the pixels x in [0, w) of a row pair:
// cbcr[x] and squared[x] = the values where ok[x], else NaN; sums[0] and sums[1] += their sums
// over the kept pixels (eight partial sums, lane k holding x = k mod 8, added in a fixed order at
// the end, the tail into lane 0: the same order on every path); returns the kept count.
// Full-range BT.601 (JPEG): Cb = -0.168736 R - 0.331264 G + 0.5 B, Cr = 0.5 R - 0.418688 G -
// 0.081312 B (the +0.5 offsets cancel in the difference). The squared error is in double, so
// that the masked MSE keeps full precision for nearly identical images.
[[gnu::always_inline]] inline size_t PixelRowBody(const float* __restrict p,
                                                  const float* __restrict q,
                                                  const uint8_t* __restrict ok, int w,
                                                  float* __restrict cbcr, float* __restrict squared,
                                                  double* __restrict sums) {
  const V8f nan = V8f{} + kNaN;
  V4d cb_lo{}, cb_hi{}, sq_lo{}, sq_hi{};
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    V8f r0, g0, b0, r1, g1, b1;
    Deinterleave8(p + 3 * x, &r0, &g0, &b0);
    Deinterleave8(q + 3 * x, &r1, &g1, &b1);
    const V8f dr = r0 - r1, dg = g0 - g1, db = b0 - b1;
    const V8f dcb = -0.168736f * dr - 0.331264f * dg + 0.5f * db;
    const V8f dcr = 0.5f * dr - 0.418688f * dg - 0.081312f * db;
    const V8i no_sign = V8i{} + 0x7fffffff;  // |x|: the sign bit cleared
    const V8f v = (V8f)((V8i)dcb & no_sign) + (V8f)((V8i)dcr & no_sign);
    const V8i keep = __builtin_convertvector(REPHOTO_LOAD(V8u8, ok + x), V8i) != 0;
    const V8f kept = (V8f)((V8i)v & keep);
    REPHOTO_STORE(cbcr + x, (V8f)(((V8i)v & keep) | ((V8i)nan & ~keep)));
    cb_lo += __builtin_convertvector(__builtin_shufflevector(kept, kept, 0, 1, 2, 3), V4d);
    cb_hi += __builtin_convertvector(__builtin_shufflevector(kept, kept, 4, 5, 6, 7), V4d);
    // The squared error in double, four pixels at a time.
    const V4i k_lo = __builtin_shufflevector(keep, keep, 0, 1, 2, 3);
    const V4i k_hi = __builtin_shufflevector(keep, keep, 4, 5, 6, 7);
    const V4f dr_lo = __builtin_shufflevector(dr, dr, 0, 1, 2, 3);
    const V4f dg_lo = __builtin_shufflevector(dg, dg, 0, 1, 2, 3);
    const V4f db_lo = __builtin_shufflevector(db, db, 0, 1, 2, 3);
    const V4f dr_hi = __builtin_shufflevector(dr, dr, 4, 5, 6, 7);
    const V4f dg_hi = __builtin_shufflevector(dg, dg, 4, 5, 6, 7);
    const V4f db_hi = __builtin_shufflevector(db, db, 4, 5, 6, 7);
    V4d e_lo, e_hi;
    SquaredError4(&dr_lo, &dg_lo, &db_lo, &e_lo);
    SquaredError4(&dr_hi, &dg_hi, &db_hi, &e_hi);
    sq_lo += (V4d)((V4l)e_lo & __builtin_convertvector(k_lo, V4l));
    sq_hi += (V4d)((V4l)e_hi & __builtin_convertvector(k_hi, V4l));
    const V4i nan4 = (V4i)(V4f{} + kNaN);
    const V4i f_lo = (V4i) __builtin_convertvector(e_lo, V4f);
    const V4i f_hi = (V4i) __builtin_convertvector(e_hi, V4f);
    REPHOTO_STORE(squared + x, (V4f)((f_lo & k_lo) | (nan4 & ~k_lo)));
    REPHOTO_STORE(squared + x + 4, (V4f)((f_hi & k_hi) | (nan4 & ~k_hi)));
  }
  double cb[8] = {cb_lo[0], cb_lo[1], cb_lo[2], cb_lo[3], cb_hi[0], cb_hi[1], cb_hi[2], cb_hi[3]};
  double sq[8] = {sq_lo[0], sq_lo[1], sq_lo[2], sq_lo[3], sq_hi[0], sq_hi[1], sq_hi[2], sq_hi[3]};
  for (; x < w; ++x) {  // the same arithmetic, one pixel at a time
    const float dr = p[3 * x] - q[3 * x];
    const float dg = p[3 * x + 1] - q[3 * x + 1];
    const float db = p[3 * x + 2] - q[3 * x + 2];
    const float dcb = -0.168736f * dr - 0.331264f * dg + 0.5f * db;
    const float dcr = 0.5f * dr - 0.418688f * dg - 0.081312f * db;
    const float v = std::abs(dcb) + std::abs(dcr);
    const double e = (static_cast<double>(dr) * dr + static_cast<double>(dg) * dg +
                      static_cast<double>(db) * db) /
                     3.0;
    cbcr[x] = ok[x] ? v : kNaN;
    squared[x] = ok[x] ? static_cast<float>(e) : kNaN;
    if (ok[x]) {
      cb[0] += v;
      sq[0] += e;
    }
  }
  sums[0] += ((cb[0] + cb[1]) + (cb[2] + cb[3])) + ((cb[4] + cb[5]) + (cb[6] + cb[7]));
  sums[1] += ((sq[0] + sq[1]) + (sq[2] + sq[3])) + ((sq[4] + sq[5]) + (sq[6] + sq[7]));
  size_t n = 0;
  for (int i = 0; i < w; ++i) n += ok[i] != 0;
  return n;
}
REPHOTO_ISA_DISPATCH(size_t, PixelRow,
                     (const float* __restrict p, const float* __restrict q,
                      const uint8_t* __restrict ok, int w, float* __restrict cbcr,
                      float* __restrict squared, double* __restrict sums),
                     (p, q, ok, w, cbcr, squared, sums))

// Pixel metrics: Cb+Cr and the squared error of PSNR (PixelRow); rows that are not asked for
// go to scratch.
MeanSums PixelBand(const Inputs& in, const ErrorRows* cbcr, const ErrorRows* squared, int64_t y0,
                   int64_t y1) {
  MeanSums sums;
  const int w = in.width;
  thread_local std::vector<float> scratch;
  thread_local std::vector<uint8_t> all_valid;
  float* spare = Scratch(scratch, 2 * static_cast<size_t>(w));
  if (in.valid.empty() && all_valid.size() < static_cast<size_t>(w)) all_valid.assign(w, 1);
  for (int64_t y = y0; y < y1; ++y) {
    const int yi = static_cast<int>(y);
    const uint8_t* ok = in.valid.empty() ? all_valid.data() : in.valid.row(yi);
    double row_sums[2] = {0, 0};
    const size_t evaluated =
        PixelRow(in.photo.row(yi), in.rephoto.row(yi), ok, w, cbcr ? cbcr->row(yi) : spare,
                 squared ? squared->row(yi) : spare + w, row_sums);
    sums.sum[0] += row_sums[0];
    sums.sum[1] += row_sums[1];
    sums.count[0] += evaluated;
    sums.count[1] += evaluated;
  }
  return sums;
}

double MeanOf(const MeanSums& sums, int slot) {
  return sums.count[slot] == 0 ? std::numeric_limits<double>::quiet_NaN()
                               : sums.sum[slot] / static_cast<double>(sums.count[slot]);
}

void CheckOptions(const MetricOptions& o) {
  REPHOTO_CHECK(o.window >= 3 && o.window % 2 == 1,
                "metric options: window {} must be odd and >= 3", o.window);
  REPHOTO_CHECK(o.ssim_window >= 3 && o.ssim_window % 2 == 1,
                "metric options: SSIM window {} must be odd and >= 3", o.ssim_window);
  REPHOTO_CHECK(!o.ssim_gaussian || o.ssim_sigma > 0, "metric options: SSIM sigma {} must be > 0",
                o.ssim_sigma);
  REPHOTO_CHECK(o.icid_window >= 3 && o.icid_window % 2 == 1 && o.icid_sigma > 0,
                "metric options: iCID window {} must be odd and >= 3 and sigma {} > 0",
                o.icid_window, o.icid_sigma);
}

}  // namespace

std::string_view MetricName(Metric metric) {
  switch (metric) {
    case Metric::kOneMinusNcc:
      return "1-ncc";
    case Metric::kCbCr:
      return "cb+cr";
    case Metric::kZssd:
      return "zssd";
    case Metric::kDssim:
      return "dssim";
    case Metric::kCensus:
      return "census";
    case Metric::kIcid:
      return "icid";
    case Metric::kPsnr:
      return "psnr";
    case Metric::kSsim:
      return "ssim";
    case Metric::kLpips:
      return "lpips";
  }
  return "unknown";
}

const std::vector<Metric>& AllMetrics() {
  static const std::vector<Metric> all = {Metric::kOneMinusNcc, Metric::kCbCr,   Metric::kZssd,
                                          Metric::kDssim,       Metric::kCensus, Metric::kIcid,
                                          Metric::kPsnr,        Metric::kSsim};
  return all;
}

bool IsNetworkMetric(Metric metric) { return metric == Metric::kLpips; }

Metric HeadlineMetric(const std::vector<Metric>& metrics) {
  REPHOTO_CHECK(!metrics.empty(), "no metric selected");
  for (Metric m : metrics) {
    if (m == Metric::kOneMinusNcc) return m;
  }
  return metrics.front();
}

std::optional<Metric> ParseMetric(std::string_view name) {
  std::string lower(name);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (Metric m : AllMetrics()) {
    if (MetricName(m) == lower) return m;
  }
  if (lower == MetricName(Metric::kLpips)) return Metric::kLpips;
  return std::nullopt;
}

std::vector<Metric> ParseMetricList(std::string_view list) {
  std::vector<Metric> out;
  size_t start = 0;
  while (start <= list.size()) {
    size_t end = list.find(',', start);
    if (end == std::string_view::npos) end = list.size();
    std::string_view item = list.substr(start, end - start);
    while (!item.empty() && std::isspace(static_cast<unsigned char>(item.front()))) {
      item.remove_prefix(1);
    }
    while (!item.empty() && std::isspace(static_cast<unsigned char>(item.back()))) {
      item.remove_suffix(1);
    }
    std::string lower(item);
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (lower == "all") {
      for (Metric m : AllMetrics()) {
        if (std::find(out.begin(), out.end(), m) == out.end()) out.push_back(m);
      }
    } else {
      const std::optional<Metric> m = ParseMetric(item);
      if (!m) {
        std::string known;
        for (Metric k : AllMetrics())
          known += (known.empty() ? "" : ", ") + std::string(MetricName(k));
        known += ", " + std::string(MetricName(Metric::kLpips));
        ThrowError("--metrics: unknown metric '{}' (known: {}, all)", item, known);
      }
      if (std::find(out.begin(), out.end(), *m) == out.end()) out.push_back(*m);
    }
    start = end + 1;
  }
  return out;
}

bool HigherIsBetter(Metric metric) { return metric == Metric::kPsnr || metric == Metric::kSsim; }

bool ErrorImageHigherIsBetter(Metric metric) { return metric == Metric::kSsim; }

namespace {

// Everything a band needs, set up once per call.
struct Engine {
  const RgbView& photo;
  const RgbView& rephoto;
  const Mask& valid;
  int width = 0, height = 0;
  MetricOptions options;
  bool want[8] = {};
  int halo = 0;  // source rows needed above and below a band
  internal::SsimSetup ssim;
  std::vector<double> icid_weights;
  uint64_t call = internal::NewCallId();

  bool Wants(Metric m) const { return want[static_cast<int>(m)]; }
};

// Partial sums of one band for every metric group, added in band order.
struct BandSums {
  MeanSums window, pixel, ssim, icid;
  BandSums& operator+=(const BandSums& other) {
    window += other.window;
    pixel += other.pixel;
    ssim += other.ssim;
    icid += other.icid;
    return *this;
  }
};

// All requested metrics for output rows [y0, y1): the band's source rows are converted once
// (when the inputs are not float RGB) and go through every metric while they are in cache.
BandSums ComputeBand(const Engine& e, const ErrorRows* const* rows, int64_t y0, int64_t y1) {
  thread_local std::vector<float> photo_scratch, rephoto_scratch;
  internal::RgbRows p, q;
  const int first = static_cast<int>(y0) - e.halo, end = static_cast<int>(y1) + e.halo;
  // iCID and census read 8-bit rows themselves, and so do 1-NCC and ZSSD on their exact path
  // when both images are 8-bit (windows up to kMaxExactWindow; it then takes every row; with one
  // float image a row may fail the exact path and go to the double one, which reads floats):
  // without the other metrics, 8-bit images need no float rows.
  const bool both_bytes = e.photo.bytes() != nullptr && e.rephoto.bytes() != nullptr;
  bool floats = false;
  for (int m = 0; m < 8; ++m) {
    const Metric metric = static_cast<Metric>(m);
    const bool reads_bytes =
        metric == Metric::kIcid || metric == Metric::kCensus ||
        ((metric == Metric::kOneMinusNcc || metric == Metric::kZssd) && both_bytes &&
         e.options.window <= kMaxExactWindow);
    floats |= e.want[m] && !reads_bytes;
  }
  p.Load(e.photo, first, end, &photo_scratch, floats);
  q.Load(e.rephoto, first, end, &rephoto_scratch, floats);
  const Inputs in{p, q, e.valid, e.width, e.height, e.call};
  // Without rows to keep (a null sink), each band writes its error rows into per-thread scratch
  // that stays in cache instead of streaming them to memory.
  ErrorRows local[8];
  const ErrorRows* local_rows[8] = {};
  if (rows == nullptr) {
    thread_local UninitVector<float> scratch;
    const size_t band = static_cast<size_t>(y1 - y0) * e.width;
    int count = 0;
    for (bool want : e.want) count += want;
    if (scratch.size() < count * band) scratch.resize(count * band);
    size_t offset = 0;
    for (int m = 0; m < 8; ++m) {
      if (!e.want[m]) continue;
      local[m] = ErrorRows{scratch.data() + offset, static_cast<int>(y0), e.width};
      local_rows[m] = &local[m];
      offset += band;
    }
    rows = local_rows;
  }
  auto out = [&](Metric m) { return rows[static_cast<int>(m)]; };
  BandSums sums;
  if (e.Wants(Metric::kOneMinusNcc) || e.Wants(Metric::kZssd) || e.Wants(Metric::kCensus)) {
    sums.window =
        WindowBand(in, e.options.window, e.options.ncc_flat_threshold, out(Metric::kOneMinusNcc),
                   out(Metric::kZssd), out(Metric::kCensus), y0, y1);
  }
  if (e.Wants(Metric::kCbCr) || e.Wants(Metric::kPsnr)) {
    sums.pixel = PixelBand(in, out(Metric::kCbCr), out(Metric::kPsnr), y0, y1);
  }
  if (e.Wants(Metric::kSsim) || e.Wants(Metric::kDssim)) {
    sums.ssim = internal::SsimBand(in, e.ssim, out(Metric::kSsim), out(Metric::kDssim), y0, y1);
  }
  if (e.Wants(Metric::kIcid)) {
    sums.icid =
        internal::IcidBand(in, e.options.icid_window, e.icid_weights, out(Metric::kIcid), y0, y1);
  }
  return sums;
}

// Output rows [y_begin, y_end) (y_begin a multiple of kBandRows) in bands of kBandRows rows,
// in parallel; their sums are added to *total in band order, so that the result is the same
// whether the image is done at once or in several calls.
void RunBands(const Engine& e, const ErrorRows* const* rows, int64_t y_begin, int64_t y_end,
              BandSums* total, bool* first) {
  if (y_end <= y_begin) return;
  const int64_t bands = (y_end - y_begin + kBandRows - 1) / kBandRows;
  std::vector<BandSums> partial(static_cast<size_t>(bands));
  ParallelFor(0, bands, 1, [&](int64_t b0, int64_t b1) {
    for (int64_t b = b0; b < b1; ++b) {
      const int64_t y0 = y_begin + b * kBandRows;
      partial[static_cast<size_t>(b)] = ComputeBand(e, rows, y0, std::min(y_end, y0 + kBandRows));
    }
  });
  for (const BandSums& p : partial) {
    if (*first) {
      *total = p;  // as ParallelSum: the first partial itself, then += the others
      *first = false;
    } else {
      *total += p;
    }
  }
}

void CheckInputs(const RgbView& photo, const RgbView& rephoto, const Mask& valid,
                 const std::vector<Metric>& metrics, const MetricOptions& options,
                 bool allow_alpha) {
  const bool photo_ok = photo.channels() == 3 || (allow_alpha && photo.channels() == 4);
  const bool rephoto_ok = rephoto.channels() == 3 || (allow_alpha && rephoto.channels() == 4);
  REPHOTO_CHECK(photo_ok && rephoto_ok,
                "metrics: need 3-channel RGB images, got {} (photo) and {} (rendering) channels",
                photo.channels(), rephoto.channels());
  REPHOTO_CHECK(photo.width() == rephoto.width() && photo.height() == rephoto.height(),
                "metrics: photo is {}x{} but the rendering is {}x{}", photo.width(), photo.height(),
                rephoto.width(), rephoto.height());
  REPHOTO_CHECK(valid.empty() || (valid.width() == photo.width() &&
                                  valid.height() == photo.height() && valid.channels() == 1),
                "metrics: validity mask is {}x{}x{} but the images are {}x{}", valid.width(),
                valid.height(), valid.channels(), photo.width(), photo.height());
  CheckOptions(options);
  for (size_t i = 0; i < metrics.size(); ++i) {
    REPHOTO_CHECK(!IsNetworkMetric(metrics[i]),
                  "metrics: {} is a network metric, computed by compare (CompareOptions), not "
                  "by ComputeMetrics",
                  MetricName(metrics[i]));
    for (size_t j = 0; j < i; ++j) {
      REPHOTO_CHECK(metrics[i] != metrics[j], "metrics: {} requested twice",
                    MetricName(metrics[i]));
    }
  }
}

Engine MakeEngine(const RgbView& photo, const RgbView& rephoto, const Mask& valid,
                  const std::vector<Metric>& metrics, const MetricOptions& options) {
  Engine e{photo, rephoto, valid};
  e.width = photo.width();
  e.height = photo.height();
  e.options = options;
  for (Metric m : metrics) e.want[static_cast<int>(m)] = true;
  if (e.Wants(Metric::kOneMinusNcc) || e.Wants(Metric::kZssd) || e.Wants(Metric::kCensus)) {
    e.halo = std::max(e.halo, options.window / 2);
  }
  if (e.Wants(Metric::kSsim) || e.Wants(Metric::kDssim)) {
    e.halo = std::max(e.halo, options.ssim_window / 2);
    e.ssim.window = options.ssim_window;
    e.ssim.weights = internal::FilterWeights(options.ssim_window / 2,
                                             options.ssim_gaussian ? options.ssim_sigma : 0);
    const double n = static_cast<double>(options.ssim_window) * options.ssim_window;
    e.ssim.cov_norm = options.ssim_gaussian ? 1.0f : static_cast<float>(n / (n - 1));
  }
  if (e.Wants(Metric::kIcid)) {
    e.halo = std::max(e.halo, options.icid_window / 2);
    const std::vector<float> wf =
        internal::FilterWeights(options.icid_window / 2, options.icid_sigma);
    e.icid_weights.assign(wf.begin(), wf.end());
  }
  return e;
}

// Means and counts of `results` (already holding metrics in order) from the summed bands.
void Finish(const BandSums& sums, std::vector<MetricResult>* results) {
  for (MetricResult& res : *results) {
    const auto set = [&](const MeanSums& s, int slot) {
      res.mean = MeanOf(s, slot);
      res.evaluated = s.count[slot];
    };
    switch (res.metric) {
      case Metric::kOneMinusNcc:
        set(sums.window, 0);
        break;
      case Metric::kZssd:
        set(sums.window, 1);
        break;
      case Metric::kCensus:
        set(sums.window, 2);
        break;
      case Metric::kCbCr:
        set(sums.pixel, 0);
        break;
      case Metric::kPsnr:
        set(sums.pixel, 1);
        if (res.evaluated > 0) {
          // mean currently holds the masked MSE.
          res.mean = res.mean > 0 ? 10.0 * std::log10(1.0 / res.mean)
                                  : std::numeric_limits<double>::infinity();
        }
        break;
      case Metric::kSsim:
        set(sums.ssim, 0);
        break;
      case Metric::kDssim:
        set(sums.ssim, 1);
        break;
      case Metric::kIcid:
        set(sums.icid, 0);
        break;
      case Metric::kLpips:  // refused by CheckInputs
        break;
    }
  }
}

void PrepareResults(const std::vector<Metric>& metrics, std::vector<MetricResult>* results) {
  results->resize(metrics.size());
  for (size_t i = 0; i < metrics.size(); ++i) {
    MetricResult& res = (*results)[i];
    res.metric = metrics[i];
    res.mean = std::numeric_limits<double>::quiet_NaN();
    res.evaluated = 0;
  }
}

void ComputeMetricsOnFinite(const Image& photo, const Image& rephoto, const Mask& valid,
                            const std::vector<Metric>& metrics, const MetricOptions& options,
                            std::vector<MetricResult>* results) {
  CheckInputs(photo, rephoto, valid, metrics, options, /*allow_alpha=*/false);
  const RgbView photo_view(photo), rephoto_view(rephoto);
  const Engine e = MakeEngine(photo_view, rephoto_view, valid, metrics, options);
  PrepareResults(metrics, results);
  ErrorRows images[8];
  const ErrorRows* rows[8] = {};
  for (MetricResult& res : *results) {
    res.error.Resize(e.width, e.height, 1);
    const int m = static_cast<int>(res.metric);
    images[m] = ErrorRows{res.error.data(), 0, e.width};
    rows[m] = &images[m];
  }
  BandSums sums;
  bool first = true;
  RunBands(e, rows, 0, e.height, &sums, &first);
  Finish(sums, results);
}

bool IsNaN(double value) {
  // Tested on the bits: an optimised -fno-trapping-math build was seen to drop the
  // floating-point test.
  uint64_t bits;
  std::memcpy(&bits, &value, sizeof(bits));
  return (bits & 0x7ff0000000000000ull) == 0x7ff0000000000000ull &&
         (bits & 0x000fffffffffffffull) != 0;
}

// Copies of the colour of `photo` and `rephoto` where pixels with a non-finite value in either
// are 0, and `valid` without them.
void RemoveNonFinite(const RgbView& photo, const RgbView& rephoto, const Mask& valid, Image* p,
                     Image* q, Mask* v) {
  const int w = photo.width(), h = photo.height();
  p->Resize(w, h, 3);
  q->Resize(w, h, 3);
  *v = Mask(w, h, 1);
  std::vector<float> ps, qs;
  for (int y = 0; y < h; ++y) {
    internal::RgbRows pr, qr;
    pr.Load(photo, y, y + 1, &ps);
    qr.Load(rephoto, y, y + 1, &qs);
    std::copy(pr.row(y), pr.row(y) + 3 * w, p->row(y));
    std::copy(qr.row(y), qr.row(y) + 3 * w, q->row(y));
  }
  for (size_t i = 0; i < v->size(); ++i) {
    bool finite = true;
    for (int c = 0; c < 3; ++c) {
      finite = finite && std::isfinite(p->data()[3 * i + c]) && std::isfinite(q->data()[3 * i + c]);
    }
    if (!finite) {
      for (int c = 0; c < 3; ++c) p->data()[3 * i + c] = q->data()[3 * i + c] = 0.0f;
    }
    v->data()[i] = finite && (valid.empty() || valid.data()[i] != 0);
  }
}

// True when a float image has a non-finite colour value.
bool HasNonFinite(const RgbView& image) {
  if (!image.floats()) return false;
  const int w = image.width(), channels = image.channels();
  const MeanSums found = ParallelSum<MeanSums>(0, image.height(), 64, [&](int64_t y0, int64_t y1) {
    MeanSums s;
    for (int64_t y = y0; y < y1; ++y) {
      const float* row = image.floats() + static_cast<size_t>(y) * w * channels;
      uint32_t all = 0;
      for (int x = 0; x < w; ++x) {
        for (int c = 0; c < 3; ++c) {
          uint32_t bits;
          std::memcpy(&bits, row + static_cast<size_t>(x) * channels + c, 4);
          // Exponent all ones: infinity or NaN.
          all |= static_cast<uint32_t>((bits & 0x7f800000u) == 0x7f800000u);
        }
      }
      s.count[0] += all;
    }
    return s;
  });
  return found.count[0] > 0;
}

// Band of output rows delivered to the sink at a time: a multiple of kBandRows, so that the
// bands (and the order of their sums) are those of ComputeMetrics.
constexpr int kSinkRows = 8 * static_cast<int>(kBandRows);

}  // namespace

void ComputeMetrics(const Image& photo, const Image& rephoto, const Mask& valid,
                    const std::vector<Metric>& metrics, const MetricOptions& options,
                    std::vector<MetricResult>* results) {
  ComputeMetricsOnFinite(photo, rephoto, valid, metrics, options, results);
  // A non-finite input value poisons the running sums, which shows as a NaN mean. Only then
  // (no cost otherwise): treat pixels with a non-finite value as invalid and recompute on
  // copies where they are 0.
  bool poisoned = false;
  for (const MetricResult& res : *results) {
    poisoned = poisoned || (res.evaluated > 0 && IsNaN(res.mean));
  }
  if (!poisoned) return;
  Image p, q;
  Mask v;
  RemoveNonFinite(photo, rephoto, valid, &p, &q, &v);
  ComputeMetricsOnFinite(p, q, v, metrics, options, results);
}

void ComputeMetricsInBands(const RgbView& photo, const RgbView& rephoto, const Mask& valid,
                           const std::vector<Metric>& metrics, const MetricOptions& options,
                           const ErrorBandSink& sink, std::vector<MetricResult>* results) {
  CheckInputs(photo, rephoto, valid, metrics, options, /*allow_alpha=*/true);
  if (HasNonFinite(photo) || HasNonFinite(rephoto)) {
    Image p, q;
    Mask v;
    RemoveNonFinite(photo, rephoto, valid, &p, &q, &v);
    ComputeMetricsInBands(p, q, v, metrics, options, sink, results);
    return;
  }
  const Engine e = MakeEngine(photo, rephoto, valid, metrics, options);
  PrepareResults(metrics, results);
  for (MetricResult& res : *results) res.error = Image();
  const int w = e.width;
  if (!sink) {  // nothing to hand over: no band buffers
    BandSums sums;
    bool first = true;
    RunBands(e, nullptr, 0, e.height, &sums, &first);
    Finish(sums, results);
    return;
  }
  // Band buffers, kept by the calling thread for its next pairs (first touch is costly).
  thread_local std::vector<UninitVector<float>> buffers;
  if (buffers.size() < metrics.size()) buffers.resize(metrics.size());
  ErrorRows bands[8];
  const ErrorRows* rows[8] = {};
  std::vector<const float*> pointers(metrics.size());
  for (size_t i = 0; i < metrics.size(); ++i) {
    buffers[i].resize(static_cast<size_t>(kSinkRows) * w);
    const int m = static_cast<int>(metrics[i]);
    bands[m] = ErrorRows{buffers[i].data(), 0, w};
    rows[m] = &bands[m];
    pointers[i] = buffers[i].data();
  }
  BandSums sums;
  bool first = true;
  for (int y0 = 0; y0 < e.height; y0 += kSinkRows) {
    const int y1 = std::min(e.height, y0 + kSinkRows);
    for (ErrorRows& band : bands) band.first = y0;
    RunBands(e, rows, y0, y1, &sums, &first);
    sink(y0, y1, pointers);
  }
  Finish(sums, results);
}

std::vector<MetricResult> ComputeMetrics(const Image& photo, const Image& rephoto,
                                         const Mask& valid, const std::vector<Metric>& metrics,
                                         const MetricOptions& options) {
  std::vector<MetricResult> results;
  ComputeMetrics(photo, rephoto, valid, metrics, options, &results);
  return results;
}

MetricResult ComputeMetric(Metric metric, const Image& photo, const Image& rephoto,
                           const Mask& valid, const MetricOptions& options) {
  std::vector<MetricResult> results = ComputeMetrics(photo, rephoto, valid, {metric}, options);
  return std::move(results[0]);
}

}  // namespace rephoto::metrics
