#include <algorithm>

#include "rephoto/metrics/kernels.h"

// Compiled with -ffp-contract=fast (see CMakeLists.txt): a * b + c becomes one FMA in the AVX2
// clone. Both images go through the same instruction sequence, so identical images still give
// identical moments (SSIM exactly 1); the last bits may differ between CPUs with and without
// FMA. The accumulators of 8 consecutive values live in registers across all taps (GCC vector
// extensions; the baseline clone lowers them to SSE pairs).
namespace rephoto::metrics::internal {
namespace {

typedef float V16f __attribute__((vector_size(64)));

// Macros rather than functions: passing 64-byte vectors by value to a function not compiled
// for AVX-512 changes the ABI (GCC's -Wpsabi).
#define REPHOTO_LOAD(p)                     \
  ({                                        \
    V16f v_;                                \
    __builtin_memcpy(&v_, (p), sizeof(v_)); \
    v_;                                     \
  })
#define REPHOTO_STORE(p, v)                 \
  do {                                      \
    const V16f s_ = (v);                    \
    __builtin_memcpy((p), &s_, sizeof(s_)); \
  } while (false)

}  // namespace

REPHOTO_SIMD_CLONES
void SsimVertical(const float* const* p_rows, const float* const* q_rows, const float* weights,
                  int r, int n, float* out) {
  float* vx = out;
  float* vy = out + n;
  float* vxx = out + 2 * n;
  float* vyy = out + 3 * n;
  float* vxy = out + 4 * n;
  const V16f half = V16f{} + 0.5f;
  const int vectors = n / 16 * 16;
  for (int i = 0; i < vectors; i += 16) {
    const V16f w0 = V16f{} + weights[r];
    const V16f a = REPHOTO_LOAD(p_rows[r] + i) - half, b = REPHOTO_LOAD(q_rows[r] + i) - half;
    V16f sx = w0 * a, sy = w0 * b, sxx = w0 * (a * a), syy = w0 * (b * b), sxy = w0 * (a * b);
    for (int k = 1; k <= r; ++k) {
      const V16f wk = V16f{} + weights[r + k];
      const V16f a1 = REPHOTO_LOAD(p_rows[r - k] + i) - half,
                 a2 = REPHOTO_LOAD(p_rows[r + k] + i) - half;
      const V16f b1 = REPHOTO_LOAD(q_rows[r - k] + i) - half,
                 b2 = REPHOTO_LOAD(q_rows[r + k] + i) - half;
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
  for (int i = vectors; i < n; ++i) {  // same arithmetic, one value at a time
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

REPHOTO_SIMD_CLONES
void SsimHorizontal(const float* in, const float* weights, int r, int n, float* out) {
  const int begin = 3 * r, end = n - 3 * r;
  int i = begin;
  for (; i + 16 <= end; i += 16) {
    V16f acc = (V16f{} + weights[r]) * REPHOTO_LOAD(in + i);
    for (int k = 1; k <= r; ++k) {
      acc +=
          (V16f{} + weights[r + k]) * (REPHOTO_LOAD(in + i - 3 * k) + REPHOTO_LOAD(in + i + 3 * k));
    }
    REPHOTO_STORE(out + i, acc);
  }
  for (; i < end; ++i) {
    float acc = weights[r] * in[i];
    for (int k = 1; k <= r; ++k) acc += weights[r + k] * (in[i - 3 * k] + in[i + 3 * k]);
    out[i] = acc;
  }
}

}  // namespace rephoto::metrics::internal
