#include <algorithm>

#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/simd.h"

// Compiled with -ffp-contract=fast (see CMakeLists.txt): a * b + c becomes one FMA in the AVX2
// and AVX-512 versions. Both images go through the same instruction sequence, so identical
// images still give identical moments (SSIM exactly 1); the last bits may differ between CPUs
// with and without FMA. The accumulators of a vector of consecutive values live in registers
// across all taps (GCC vector extensions). Each kernel is one template inlined into a 16-wide
// AVX-512 function and an 8-wide function cloned for AVX2 and the baseline: element-wise the
// same arithmetic, so both give the same values. (The 16-wide code alone was lowered to scalar
// operations in the AVX2 clone: DSSIM 9x slower on CPUs without AVX-512.)
namespace rephoto::metrics::internal {
namespace {

template <typename VF>
[[gnu::always_inline]] inline void VerticalBody(const float* const* p_rows,
                                                const float* const* q_rows, const float* weights,
                                                int r, int n, float* out) {
  constexpr int kLanes = sizeof(VF) / sizeof(float);
  float* vx = out;
  float* vy = out + n;
  float* vxx = out + 2 * n;
  float* vyy = out + 3 * n;
  float* vxy = out + 4 * n;
  const VF half = VF{} + 0.5f;
  // Whole vectors; the last one overlaps its predecessor when n is not a multiple of kLanes
  // (it recomputes some values, with the same arithmetic): scalar code only for n < kLanes.
  for (int i = 0; i < n; i += kLanes) {
    if (i + kLanes > n) {
      if (n < kLanes) break;
      i = n - kLanes;
    }
    const VF w0 = VF{} + weights[r];
    const VF a = REPHOTO_LOAD(VF, p_rows[r] + i) - half, b = REPHOTO_LOAD(VF, q_rows[r] + i) - half;
    VF sx = w0 * a, sy = w0 * b, sxx = w0 * (a * a), syy = w0 * (b * b), sxy = w0 * (a * b);
    for (int k = 1; k <= r; ++k) {
      const VF wk = VF{} + weights[r + k];
      const VF a1 = REPHOTO_LOAD(VF, p_rows[r - k] + i) - half,
               a2 = REPHOTO_LOAD(VF, p_rows[r + k] + i) - half;
      const VF b1 = REPHOTO_LOAD(VF, q_rows[r - k] + i) - half,
               b2 = REPHOTO_LOAD(VF, q_rows[r + k] + i) - half;
      sx += wk * (a1 + a2);
      sy += wk * (b1 + b2);
      sxx += wk * (a1 * a1 + a2 * a2);
      syy += wk * (b1 * b1 + b2 * b2);
      sxy += wk * (a1 * b1 + a2 * b2);
    }
    REPHOTO_STORE(vx + i, sx);
    REPHOTO_STORE(vy + i, sy);
    REPHOTO_STORE(vxx + i, sxx);
    REPHOTO_STORE(vyy + i, syy);
    REPHOTO_STORE(vxy + i, sxy);
  }
  for (int i = 0; i < (n < kLanes ? n : 0); ++i) {  // same arithmetic, one value at a time
    const float w0 = weights[r];
    const float a = p_rows[r][i] - 0.5f, b = q_rows[r][i] - 0.5f;
    float sx = w0 * a, sy = w0 * b, sxx = w0 * (a * a), syy = w0 * (b * b), sxy = w0 * (a * b);
    for (int k = 1; k <= r; ++k) {
      const float wk = weights[r + k];
      const float a1 = p_rows[r - k][i] - 0.5f, a2 = p_rows[r + k][i] - 0.5f;
      const float b1 = q_rows[r - k][i] - 0.5f, b2 = q_rows[r + k][i] - 0.5f;
      sx += wk * (a1 + a2);
      sy += wk * (b1 + b2);
      sxx += wk * (a1 * a1 + a2 * a2);
      syy += wk * (b1 * b1 + b2 * b2);
      sxy += wk * (a1 * b1 + a2 * b2);
    }
    vx[i] = sx;
    vy[i] = sy;
    vxx[i] = sxx;
    vyy[i] = syy;
    vxy[i] = sxy;
  }
}

template <typename VF>
[[gnu::always_inline]] inline void HorizontalBody(const float* in, const float* weights, int r,
                                                  int n, float* out) {
  constexpr int kLanes = sizeof(VF) / sizeof(float);
  const int begin = 3 * r, end = n - 3 * r;
  // As in VerticalBody, the last vector overlaps its predecessor.
  for (int i = begin; i < end; i += kLanes) {
    if (i + kLanes > end) {
      if (end - begin < kLanes) break;
      i = end - kLanes;
    }
    VF acc = (VF{} + weights[r]) * REPHOTO_LOAD(VF, in + i);
    for (int k = 1; k <= r; ++k) {
      acc += (VF{} + weights[r + k]) *
             (REPHOTO_LOAD(VF, in + i - 3 * k) + REPHOTO_LOAD(VF, in + i + 3 * k));
    }
    REPHOTO_STORE(out + i, acc);
  }
  for (int i = begin; i < (end - begin < kLanes ? end : begin); ++i) {
    float acc = weights[r] * in[i];
    for (int k = 1; k <= r; ++k) acc += weights[r + k] * (in[i - 3 * k] + in[i + 3 * k]);
    out[i] = acc;
  }
}

[[gnu::always_inline]] inline void Vertical8Body(const float* const* p_rows,
                                                 const float* const* q_rows, const float* weights,
                                                 int r, int n, float* out) {
  VerticalBody<V8f>(p_rows, q_rows, weights, r, n, out);
}
REPHOTO_ISA_DISPATCH_AVX2(void, Vertical8,
                          (const float* const* p_rows, const float* const* q_rows,
                           const float* weights, int r, int n, float* out),
                          (p_rows, q_rows, weights, r, n, out))

[[gnu::always_inline]] inline void Horizontal8Body(const float* in, const float* weights, int r,
                                                   int n, float* out) {
  for (int q = 0; q < 5; ++q) HorizontalBody<V8f>(in + q * n, weights, r, n, out + q * n);
}
REPHOTO_ISA_DISPATCH_AVX2(void, Horizontal8,
                          (const float* in, const float* weights, int r, int n, float* out),
                          (in, weights, r, n, out))

#ifdef REPHOTO_HAVE_AVX512_KERNELS
REPHOTO_TARGET_AVX512 void Vertical16(const float* const* p_rows, const float* const* q_rows,
                                      const float* weights, int r, int n, float* out) {
  VerticalBody<V16f>(p_rows, q_rows, weights, r, n, out);
}

REPHOTO_TARGET_AVX512 void Horizontal16(const float* in, const float* weights, int r, int n,
                                        float* out) {
  for (int q = 0; q < 5; ++q) HorizontalBody<V16f>(in + q * n, weights, r, n, out + q * n);
}
#endif

}  // namespace

void SsimVertical(const float* const* p_rows, const float* const* q_rows, const float* weights,
                  int r, int n, float* out) {
#ifdef REPHOTO_HAVE_AVX512_KERNELS
  if (HasAvx512()) return Vertical16(p_rows, q_rows, weights, r, n, out);
#endif
  Vertical8(p_rows, q_rows, weights, r, n, out);
}

void SsimHorizontal(const float* in, const float* weights, int r, int n, float* out) {
#ifdef REPHOTO_HAVE_AVX512_KERNELS
  if (HasAvx512()) return Horizontal16(in, weights, r, n, out);
#endif
  Horizontal8(in, weights, r, n, out);
}

}  // namespace rephoto::metrics::internal
