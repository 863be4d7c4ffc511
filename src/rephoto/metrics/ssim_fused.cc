#include <algorithm>
#include <utility>
#include <vector>

#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/simd.h"

// The fused SSIM filters (kernels.h): the four products of an input row are formed once, then
// filtered vertically for a block of output rows at a time (each loaded row feeds every output
// row of the block whose window holds it, so loads per output row drop from 2r+1 to
// (2r+B)/B), then horizontally. Four quantities instead of five: the SSIM formula needs only
// sigma_x^2 + sigma_y^2, so x^2 + y^2 is filtered as one quantity.
//
// Compiled with -ffp-contract=fast (CMakeLists.txt), like ssim_filter.cc. Identical images still
// give identical moments: the product x^2 + y^2 is fma(a, a, round(b * b)), which for a == b is
// round(a^2 + round(a^2)) = 2 round(a^2) exactly (the rounding error of round(a^2) is at most a
// quarter ulp of the doubled value), i.e. exactly twice the product xy = round(a * b); the
// filters are linear, so every filtered x^2 + y^2 is then exactly twice the filtered xy.
// As in ssim_filter.cc, each kernel is one template inlined into a 16-wide AVX-512 function and
// an 8-wide function cloned for AVX2 and the baseline, with the same arithmetic element-wise.
namespace rephoto::metrics::internal {
namespace {

// Start of the vector at i: whole vectors, the last one overlapping its predecessor when n is
// not a multiple of the width (recomputing values with the same arithmetic). Returns -1 when
// the vectors are done or n is below one vector (the caller then goes scalar).
template <int kLanes>
inline int VectorStart(int i, int n) {
  if (i >= n) return -1;
  if (i + kLanes <= n) return i;
  return n < kLanes ? -1 : n - kLanes;
}

template <typename VF>
[[gnu::always_inline]] inline void ProductsBody(const float* p, const float* q,
                                                const float* shift_p, const float* shift_q, int n,
                                                float* out) {
  constexpr int kLanes = sizeof(VF) / sizeof(float);
  float* ox = out;
  float* oy = out + n;
  float* oss = out + 2 * n;
  float* oxy = out + 3 * n;
  int i = 0;
  for (; (i = VectorStart<kLanes>(i, n)) >= 0; i += kLanes) {
    const VF a = REPHOTO_LOAD(VF, p + i) - REPHOTO_LOAD(VF, shift_p + i);
    const VF b = REPHOTO_LOAD(VF, q + i) - REPHOTO_LOAD(VF, shift_q + i);
    REPHOTO_STORE(ox + i, a);
    REPHOTO_STORE(oy + i, b);
    REPHOTO_STORE(oss + i, a * a + b * b);
    REPHOTO_STORE(oxy + i, a * b);
  }
  for (int j = 0; j < (n < kLanes ? n : 0); ++j) {
    const float a = p[j] - shift_p[j], b = q[j] - shift_q[j];
    ox[j] = a;
    oy[j] = b;
    oss[j] = a * a + b * b;
    oxy[j] = a * b;
  }
}

// acc[t] = the vertical sum of output row t in [0, B) of one quantity at element offset `off`:
// rows[t + r + k], k in [-r, r]. kRadius > 0: the radius is a compile-time constant, every row
// is loaded once into a register and used by all B outputs, `w` holds the weights w[k] =
// weights[r + k] for k in [0, r] as vectors; kRadius == 0: runtime radius r, each output from
// its own loads of `weights`. The same operations per value either way (w[0] * centre, then
// acc += w[k] * (top + bottom) for k = 1..r).
template <typename VF, int B, int kRadius>
[[gnu::always_inline]] inline void VerticalSums(const float* const* rows, const VF* w,
                                                const float* weights, int r, size_t off, VF* acc) {
  if constexpr (kRadius > 0) {
    constexpr int kRows = 2 * kRadius + B;
    VF v[kRows];
    for (int j = 0; j < kRows; ++j) v[j] = REPHOTO_LOAD(VF, rows[j] + off);
    for (int t = 0; t < B; ++t) acc[t] = w[0] * v[t + kRadius];
    for (int k = 1; k <= kRadius; ++k) {
      for (int t = 0; t < B; ++t) acc[t] += w[k] * (v[t + kRadius - k] + v[t + kRadius + k]);
    }
  } else {
    for (int t = 0; t < B; ++t) {
      const float* const* rt = rows + t;
      acc[t] = (VF{} + weights[r]) * REPHOTO_LOAD(VF, rt[r] + off);
      for (int k = 1; k <= r; ++k) {
        acc[t] += (VF{} + weights[r + k]) *
                  (REPHOTO_LOAD(VF, rt[r - k] + off) + REPHOTO_LOAD(VF, rt[r + k] + off));
      }
    }
  }
}

// VerticalSums stored at out[t] + off (B must be 1 for a runtime radius: VerticalBody's use).
template <typename VF, int B, int kRadius>
[[gnu::always_inline]] inline void VerticalQuantity(const float* const* rows, const VF* w,
                                                    const float* weights, int r, size_t off,
                                                    float* const* out) {
  static_assert(kRadius > 0 || B == 1);
  VF acc[B];
  VerticalSums<VF, B, kRadius>(rows, w, weights, r, off, acc);
  for (int t = 0; t < B; ++t) REPHOTO_STORE(out[t] + off, acc[t]);
}

template <typename VF, int B, int kRadius>
[[gnu::always_inline]] inline void VerticalBlockBody(const float* const* rows, const float* weights,
                                                     int r, int n, float* const* out) {
  constexpr int kLanes = sizeof(VF) / sizeof(float);
  // Local copies for a constant radius: the stores (memcpy) could otherwise alias the pointers
  // and weights, which the compiler would then reload for every vector. (A runtime radius uses
  // the caller's arrays.)
  constexpr int kRows = kRadius > 0 ? 2 * kRadius + B : 1;
  const float* rp[kRows];
  float* op[B];
  VF w[kRadius + 1];
  const float* const* row_ptrs = rows;
  float* const* out_ptrs = out;
  if constexpr (kRadius > 0) {
    for (int j = 0; j < kRows; ++j) rp[j] = rows[j];
    for (int t = 0; t < B; ++t) op[t] = out[t];
    for (int k = 0; k <= kRadius; ++k) w[k] = VF{} + weights[kRadius + k];
    row_ptrs = rp;
    out_ptrs = op;
  }
  int i = 0;
  for (; (i = VectorStart<kLanes>(i, n)) >= 0; i += kLanes) {
    for (int q = 0; q < kSsimQuantities; ++q) {
      VerticalQuantity<VF, B, kRadius>(row_ptrs, w, weights, r, static_cast<size_t>(q) * n + i,
                                       out_ptrs);
    }
  }
  if (n >= kLanes) return;
  for (int t = 0; t < B; ++t) {  // same arithmetic, one value at a time
    for (int q = 0; q < kSsimQuantities; ++q) {
      for (int j = 0; j < n; ++j) {
        const size_t off = static_cast<size_t>(q) * n + j;
        float acc = weights[r] * rows[t + r][off];
        for (int k = 1; k <= r; ++k) {
          acc += weights[r + k] * (rows[t + r - k][off] + rows[t + r + k][off]);
        }
        out[t][off] = acc;
      }
    }
  }
}

// Blocks of B rows for the radii with a compile-time kernel, else one row at a time.
template <typename VF, int B>
[[gnu::always_inline]] inline void VerticalBody(const float* const* rows, const float* weights,
                                                int r, int n, int count, float* const* out) {
  int t = 0;
  if (r == 5) {
    for (; t + B <= count; t += B) VerticalBlockBody<VF, B, 5>(rows + t, weights, r, n, out + t);
    for (; t < count; ++t) VerticalBlockBody<VF, 1, 5>(rows + t, weights, r, n, out + t);
  } else if (r == 3) {
    for (; t + B <= count; t += B) VerticalBlockBody<VF, B, 3>(rows + t, weights, r, n, out + t);
    for (; t < count; ++t) VerticalBlockBody<VF, 1, 3>(rows + t, weights, r, n, out + t);
  } else {
    for (; t < count; ++t) VerticalBlockBody<VF, 1, 0>(rows + t, weights, r, n, out + t);
  }
}

// Horizontal filter by loads at each tap, for the output elements [a, b) (3r <= a, b <= n - 3r).
template <typename VF>
[[gnu::always_inline]] inline void HorizontalRange(const float* in, const float* weights, int r,
                                                   int a, int b, float* out) {
  constexpr int kLanes = sizeof(VF) / sizeof(float);
  const int len = b - a;
  for (int o = 0; (o = VectorStart<kLanes>(o, len)) >= 0; o += kLanes) {
    const int i = a + o;
    VF acc = (VF{} + weights[r]) * REPHOTO_LOAD(VF, in + i);
    for (int k = 1; k <= r; ++k) {
      acc += (VF{} + weights[r + k]) *
             (REPHOTO_LOAD(VF, in + i - 3 * k) + REPHOTO_LOAD(VF, in + i + 3 * k));
    }
    REPHOTO_STORE(out + i, acc);
  }
  for (int j = a; j < (len < kLanes ? b : a); ++j) {
    float acc = weights[r] * in[j];
    for (int k = 1; k <= r; ++k) acc += weights[r + k] * (in[j - 3 * k] + in[j + 3 * k]);
    out[j] = acc;
  }
}

constexpr int FloorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// *out = the kLanes values at offset O from the first value of block 0, where v[j] holds block
// j + kLo (blocks of kLanes consecutive values): one register or a shuffle of two.
template <typename VF, int O, int kLo, size_t... I>
[[gnu::always_inline]] inline void WindowAt(const VF* v, VF* out, std::index_sequence<I...>) {
  constexpr int kLanes = sizeof(VF) / sizeof(float);
  constexpr int block = FloorDiv(O, kLanes), shift = O - block * kLanes;
  if constexpr (shift == 0) {
    *out = v[block - kLo];
  } else {
    *out = __builtin_shufflevector(v[block - kLo], v[block - kLo + 1],
                                   (shift + static_cast<int>(I))...);
  }
}

template <typename VF, int kRadius, int kLo, int... K>
[[gnu::always_inline]] inline void ShuffledTaps(const VF* v, const VF* w, VF* acc,
                                                std::integer_sequence<int, K...>) {
  constexpr int kLanes = sizeof(VF) / sizeof(float);
  const auto lanes = std::make_index_sequence<kLanes>();
  *acc = w[0] * v[-kLo];
  (
      [&] {
        VF left, right;
        WindowAt<VF, -3 * (K + 1), kLo>(v, &left, lanes);
        WindowAt<VF, 3 * (K + 1), kLo>(v, &right, lanes);
        *acc += w[K + 1] * (left + right);
      }(),
      ...);
}

// The same filter with one load per output vector: the tap windows are shuffled out of the
// blocks of kLanes values around it, which slide along the row in registers (loads at every
// tap made the filter load-bound; loading some taps and shuffling the others measured no faster
// than shuffling all). Same arithmetic as HorizontalRange. Edges by HorizontalRange.
template <typename VF, int kRadius>
[[gnu::always_inline]] inline void HorizontalShuffled(const float* in, const float* weights, int n,
                                                      float* out) {
  constexpr int kLanes = sizeof(VF) / sizeof(float);
  constexpr int kSpan = 3 * kRadius;
  constexpr int kLo = FloorDiv(-kSpan, kLanes);
  constexpr int kHi = FloorDiv(kSpan, kLanes) + (kSpan % kLanes != 0 ? 1 : 0);
  constexpr int kBlocks = kHi - kLo + 1;
  const int begin = kSpan, end = n - kSpan;
  // Output vectors at i need blocks [i + kLo * kLanes, i + (kHi + 1) * kLanes) inside the row.
  int i = begin + kLanes;
  if (end - begin < 2 * kLanes || i + kLo * kLanes < 0) {
    return HorizontalRange<VF>(in, weights, kRadius, begin, end, out);
  }
  HorizontalRange<VF>(in, weights, kRadius, begin, i, out);
  VF w[kRadius + 1];  // local: the stores could otherwise alias `weights`
  for (int k = 0; k <= kRadius; ++k) w[k] = VF{} + weights[kRadius + k];
  VF v[kBlocks];
  for (int j = 0; j < kBlocks - 1; ++j) v[j] = REPHOTO_LOAD(VF, in + i + (kLo + j) * kLanes);
  for (; i + kLanes <= end && i + (kHi + 1) * kLanes <= n; i += kLanes) {
    v[kBlocks - 1] = REPHOTO_LOAD(VF, in + i + kHi * kLanes);
    VF acc;
    ShuffledTaps<VF, kRadius, kLo>(v, w, &acc, std::make_integer_sequence<int, kRadius>());
    REPHOTO_STORE(out + i, acc);
    for (int j = 0; j + 1 < kBlocks; ++j) v[j] = v[j + 1];
  }
  // The rest, its first vector overlapping the last one done here when it is short.
  if (i < end) {
    HorizontalRange<VF>(in, weights, kRadius, std::max(begin, std::min(i, end - kLanes)), end, out);
  }
}

template <typename VF>
[[gnu::always_inline]] inline void HorizontalBody(const float* in, const float* weights, int r,
                                                  int n, float* out) {
  if (r == 5) return HorizontalShuffled<VF, 5>(in, weights, n, out);
  if (r == 3) return HorizontalShuffled<VF, 3>(in, weights, n, out);
  HorizontalRange<VF>(in, weights, r, 3 * r, n - 3 * r, out);
}

// The horizontal filter on transposed data (value i of row t at tin[8 i + t]; kernels.h
// SsimVerticalHorizontalTransposed8): the filter with one load per tap and no shuffle. On
// transposed data the horizontal taps of value i are the vectors at i + 3k,
// which is the vertical filter's layout with "rows" 3 values (24 floats) apart, so it is
// VerticalQuantity itself: per channel phase, the outputs i + c + 3t (t < 4) share their
// 2r + 4 loaded taps, and the arithmetic is that of every other filter pass (w[0] * centre,
// then acc += w[k] * (left + right) for k = 1..r, contracted alike).
template <int kRadius>
[[gnu::always_inline]] inline void FilterTransposed(const float* tin, const float* weights, int r,
                                                    int n, float* out) {
  const int radius = kRadius > 0 ? kRadius : r;
  // Taps of the value at offset `off` from tin[0 .. 24 * (2 radius + B)): rows[j] = tin + 24 j;
  // its output at out + 24 (t + radius) + off, i.e. value off / 8 + 3 radius + 3 t.
  constexpr int kRows = kRadius > 0 ? 2 * kRadius + 4 : 1;
  const float* fixed_rows[kRows];
  std::vector<const float*> runtime_rows(kRadius > 0 ? 0 : 2 * r + 1);
  const float** rows = kRadius > 0 ? fixed_rows : runtime_rows.data();
  for (int j = 0; j < (kRadius > 0 ? kRows : 2 * r + 1); ++j) rows[j] = tin + 24 * j;
  float* outs[4];
  for (int t = 0; t < 4; ++t) outs[t] = out + 24 * (t + radius);
  V8f w[kRadius + 1];
  if constexpr (kRadius > 0) {
    for (int k = 0; k <= kRadius; ++k) w[k] = V8f{} + weights[kRadius + k];
  }
  int i = 3 * radius;
  if constexpr (kRadius > 0) {
    for (; i + 12 <= n - 3 * kRadius; i += 12) {
      for (int c = 0; c < 3; ++c) {
        VerticalQuantity<V8f, 4, kRadius>(rows, w, weights, r,
                                          static_cast<size_t>(i + c - 3 * kRadius) * 8, outs);
      }
    }
  }
  for (; i < n - 3 * radius; ++i) {
    VerticalQuantity<V8f, 1, kRadius>(rows, w, weights, r,
                                      static_cast<size_t>(i - 3 * radius) * 8, outs);
  }
}

// SsimVerticalHorizontalTransposed8 (kernels.h): per plane, the vertical filter of the 8
// output rows for each block of 8 values (two blocks of 4 rows for a compile-time radius, as in
// Vertical8; the last block overlapping its predecessor), transposed in registers into tin,
// then FilterTransposed: the vertical rows are never stored and loaded again.
template <int kRadius>
[[gnu::always_inline]] inline void VerticalHorizontalTransposed8Radius(const float* const* rows,
                                                                       const float* weights, int r,
                                                                       int n, float* tin,
                                                                       float* out) {
  // Local copies for a constant radius: the stores could otherwise alias the row pointers.
  constexpr int kRows = kRadius > 0 ? 2 * kRadius + 8 : 1;
  const float* fixed_rows[kRows];
  const float* const* rp = rows;
  V8f w[kRadius + 1];
  if constexpr (kRadius > 0) {
    for (int j = 0; j < kRows; ++j) fixed_rows[j] = rows[j];
    rp = fixed_rows;
    for (int k = 0; k <= kRadius; ++k) w[k] = V8f{} + weights[kRadius + k];
  }
  for (int q = 0; q < kSsimQuantities; ++q) {
    const size_t plane = static_cast<size_t>(q) * n;
    // (n < 8 has no output value: n is a multiple of 3 and outputs need n > 6r >= 6.)
    for (int i = 0; (i = VectorStart<8>(i, n)) >= 0; i += 8) {
      const size_t off = plane + i;
      V8f v[8], tv[8];
      if constexpr (kRadius > 0) {
        VerticalSums<V8f, 4, kRadius>(rp, w, weights, r, off, v);
        VerticalSums<V8f, 4, kRadius>(rp + 4, w, weights, r, off, v + 4);
      } else {
        VerticalSums<V8f, 8, 0>(rp, w, weights, r, off, v);
      }
      Transpose8(v, tv);
      for (int j = 0; j < 8; ++j) REPHOTO_STORE(tin + static_cast<size_t>(i + j) * 8, tv[j]);
    }
    FilterTransposed<kRadius>(tin, weights, r, n, out + plane * 8);
  }
}

[[gnu::always_inline]] inline void VerticalHorizontalTransposed8Body(const float* const* rows,
                                                                     const float* weights, int r,
                                                                     int n, float* tin,
                                                                     float* out) {
  if (r == 5) return VerticalHorizontalTransposed8Radius<5>(rows, weights, r, n, tin, out);
  if (r == 3) return VerticalHorizontalTransposed8Radius<3>(rows, weights, r, n, tin, out);
  VerticalHorizontalTransposed8Radius<0>(rows, weights, r, n, tin, out);
}
REPHOTO_ISA_DISPATCH_AVX2(void, VerticalHorizontalTransposed8,
                          (const float* const* rows, const float* weights, int r, int n, float* tin,
                           float* out),
                          (rows, weights, r, n, tin, out))

// Rows per vertical block (each loaded row feeds every output row of the block). AVX-512's 32
// registers hold the 2r + 4 rows, 4 sums and the weights. AVX2's 16 do not, but 4 rows with some
// values spilled or re-read from L1 measured ~15 % faster for the vertical filter (r = 5,
// 12 MP, share of the profile) than 2 rows without: fewer row loads from L2 per output.
constexpr int kBlock8 = 4;
#ifdef REPHOTO_HAVE_AVX512_KERNELS
constexpr int kBlock16 = 4;
#endif

[[gnu::always_inline]] inline void Products8Body(const float* p, const float* q,
                                                 const float* shift_p, const float* shift_q, int n,
                                                 float* out) {
  ProductsBody<V8f>(p, q, shift_p, shift_q, n, out);
}
REPHOTO_ISA_DISPATCH_AVX2(void, Products8,
                          (const float* p, const float* q, const float* shift_p,
                           const float* shift_q, int n, float* out),
                          (p, q, shift_p, shift_q, n, out))

[[gnu::always_inline]] inline void Vertical8Body(const float* const* rows, const float* weights,
                                                 int r, int n, int count, float* const* out) {
  VerticalBody<V8f, kBlock8>(rows, weights, r, n, count, out);
}
REPHOTO_ISA_DISPATCH_AVX2(void, Vertical8,
                          (const float* const* rows, const float* weights, int r, int n, int count,
                           float* const* out),
                          (rows, weights, r, n, count, out))

[[gnu::always_inline]] inline void Horizontal8Body(const float* in, const float* weights, int r,
                                                   int n, float* out) {
  for (int q = 0; q < kSsimQuantities; ++q) {
    HorizontalBody<V8f>(in + q * n, weights, r, n, out + q * n);
  }
}
REPHOTO_ISA_DISPATCH_AVX2(void, Horizontal8,
                          (const float* in, const float* weights, int r, int n, float* out),
                          (in, weights, r, n, out))

#ifdef REPHOTO_HAVE_AVX512_KERNELS
REPHOTO_TARGET_AVX512 void Products16(const float* p, const float* q, const float* shift_p,
                                      const float* shift_q, int n, float* out) {
  ProductsBody<V16f>(p, q, shift_p, shift_q, n, out);
}

REPHOTO_TARGET_AVX512 void Vertical16(const float* const* rows, const float* weights, int r, int n,
                                      int count, float* const* out) {
  VerticalBody<V16f, kBlock16>(rows, weights, r, n, count, out);
}

REPHOTO_TARGET_AVX512 void Horizontal16(const float* in, const float* weights, int r, int n,
                                        float* out) {
  for (int q = 0; q < kSsimQuantities; ++q) {
    HorizontalBody<V16f>(in + q * n, weights, r, n, out + q * n);
  }
}
#endif

}  // namespace

void SsimProducts(const float* p, const float* q, const float* shift_p, const float* shift_q, int n,
                  float* out) {
#ifdef REPHOTO_HAVE_AVX512_KERNELS
  if (HasAvx512()) return Products16(p, q, shift_p, shift_q, n, out);
#endif
  Products8(p, q, shift_p, shift_q, n, out);
}

void SsimVerticalRows(const float* const* rows, const float* weights, int r, int n, int count,
                      float* const* out) {
#ifdef REPHOTO_HAVE_AVX512_KERNELS
  if (HasAvx512()) return Vertical16(rows, weights, r, n, count, out);
#endif
  Vertical8(rows, weights, r, n, count, out);
}

void SsimVerticalHorizontalTransposed8(const float* const* rows, const float* weights, int r, int n,
                                       float* tin, float* out) {
  VerticalHorizontalTransposed8(rows, weights, r, n, tin, out);
}

void SsimHorizontalFused(const float* in, const float* weights, int r, int n, float* out) {
#ifdef REPHOTO_HAVE_AVX512_KERNELS
  if (HasAvx512()) return Horizontal16(in, weights, r, n, out);
#endif
  Horizontal8(in, weights, r, n, out);
}

}  // namespace rephoto::metrics::internal
