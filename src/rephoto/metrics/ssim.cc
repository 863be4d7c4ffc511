// SSIM / DSSIM bands (kernels.h): separable weighted window of x, y, x^2, y^2, xy per channel on
// interleaved rows (filtering is element-wise, so channel interleaving does not matter; horizontal
// taps step by 3). Values are shifted by -0.5 before squaring, which halves their magnitude and the
// cancellation in E[x^2] - E[x]^2; the shift cancels in variances and covariances.

#include <algorithm>
#include <atomic>
#include <cstring>

#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/simd.h"

namespace rephoto::metrics::internal {
namespace {

std::atomic<int> selected_kernel{static_cast<int>(SsimKernel::kFused)};

// The SSIM of each element from the five moments of SsimHorizontal, for i in [3r, n - 3r).
[[gnu::always_inline]] inline void SsimFormulaBody(const float* __restrict moments, int r, int n,
                                                   float cov_norm, float* __restrict ssim) {
  const float* __restrict mx = moments;
  const float* __restrict my = moments + n;
  const float* __restrict mxx = moments + 2 * n;
  const float* __restrict myy = moments + 3 * n;
  const float* __restrict mxy = moments + 4 * n;
  const float c1 = 0.01f * 0.01f, c2 = 0.03f * 0.03f;
  for (int i = 3 * r; i < n - 3 * r; ++i) {
    const float ux = mx[i] + 0.5f, uy = my[i] + 0.5f;
    const float vx = cov_norm * (mxx[i] - mx[i] * mx[i]);
    const float vy = cov_norm * (myy[i] - my[i] * my[i]);
    const float vxy = cov_norm * (mxy[i] - mx[i] * my[i]);
    const float a1 = 2 * ux * uy + c1, a2 = 2 * vxy + c2;
    const float b1 = ux * ux + uy * uy + c1, b2 = vx + vy + c2;
    ssim[i] = (a1 * a2) / (b1 * b2);
  }
}
REPHOTO_ISA_DISPATCH(void, SsimFormula,
                     (const float* __restrict moments, int r, int n, float cov_norm,
                      float* __restrict ssim),
                     (moments, r, n, cov_norm, ssim))

// ssim[x] = mean of the 3 channel values e[3x..3x+2] ((e0 + e1) + e2) / 3, dssim[x] =
// (1 - ssim[x]) / 2, for x in [0, n): eight pixels at a time by Deinterleave's shuffles.
[[gnu::always_inline]] inline void ChannelMeansBody(const float* __restrict e, int n,
                                                    float* __restrict ssim,
                                                    float* __restrict dssim) {
  int x = 0;
  for (; x + 8 <= n; x += 8) {
    V8f e0, e1, e2;
    Deinterleave8(e + 3 * x, &e0, &e1, &e2);
    const V8f v = (e0 + e1 + e2) / 3.0f;
    const V8f d = (1.0f - v) * 0.5f;
    __builtin_memcpy(ssim + x, &v, 32);
    __builtin_memcpy(dssim + x, &d, 32);
  }
  for (; x < n; ++x) {
    const float v = (e[3 * x] + e[3 * x + 1] + e[3 * x + 2]) / 3.0f;
    ssim[x] = v;
    dssim[x] = (1.0f - v) * 0.5f;
  }
}
REPHOTO_ISA_DISPATCH(void, ChannelMeans,
                     (const float* __restrict e, int n, float* __restrict ssim,
                      float* __restrict dssim),
                     (e, n, ssim, dssim))

// Number of nonzero ok[x], x in [begin, end).
[[gnu::always_inline]] inline size_t CountRangeBody(const uint8_t* __restrict ok, int begin,
                                                    int end) {
  size_t n = 0;
  for (int x = begin; x < end; ++x) n += ok[x] != 0;
  return n;
}
REPHOTO_ISA_DISPATCH(size_t, CountRange, (const uint8_t* __restrict ok, int begin, int end),
                     (ok, begin, end))

// The SSIM of a value from its four fused moments (x, y, x^2 + y^2, xy of the values minus
// shift, the shift added back to the means). sigma_x^2 + sigma_y^2 = E[x^2 + y^2] - (mu_x^2 +
// mu_y^2), the squares added first: for identical images this is exactly twice sigma_xy, so
// SSIM is exactly 1. T is float or V8f (8 values at once, the same operations per value).
template <typename T>
[[gnu::always_inline]] inline void FusedSsim(const T& mx, const T& my, const T& mss, const T& mxy,
                                             float shift_p, float shift_q, float cov_norm,
                                             T* ssim) {
  const float c1 = 0.01f * 0.01f, c2 = 0.03f * 0.03f;
  const T ux = mx + shift_p, uy = my + shift_q;
  const T vsum = cov_norm * (mss - (mx * mx + my * my));
  const T vxy = cov_norm * (mxy - mx * my);
  const T a1 = 2 * ux * uy + c1, a2 = 2 * vxy + c2;
  const T b1 = ux * ux + uy * uy + c1, b2 = vsum + c2;
  *ssim = (a1 * a2) / (b1 * b2);
}

// FusedSsim of each element of the four moment planes, for i in [3r, n - 3r).
[[gnu::always_inline]] inline void SsimFormulaFusedBody(const float* __restrict moments,
                                                        const float* __restrict shift_p,
                                                        const float* __restrict shift_q, int r,
                                                        int n, float cov_norm,
                                                        float* __restrict ssim) {
  const float* __restrict mx = moments;
  const float* __restrict my = moments + n;
  const float* __restrict mss = moments + 2 * n;
  const float* __restrict mxy = moments + 3 * n;
  for (int i = 3 * r; i < n - 3 * r; ++i) {
    FusedSsim(mx[i], my[i], mss[i], mxy[i], shift_p[i], shift_q[i], cov_norm, &ssim[i]);
  }
}
REPHOTO_ISA_DISPATCH(void, SsimFormulaFused,
                     (const float* __restrict moments, const float* __restrict shift_p,
                      const float* __restrict shift_q, int r, int n, float cov_norm,
                      float* __restrict ssim),
                     (moments, shift_p, shift_q, r, n, cov_norm, ssim))

// FusedSsim and ChannelMeans for 8 rows at once on SsimVerticalHorizontalTransposed8's output
// (value i of plane q of row t at moments[(q * n + i) * 8 + t]): the SSIM of pixel x, for the
// pixels [xa, xb) whose first value is at i = 3 (x - xa) + ia, is the mean of its 3 channels'
// values; written transposed back into ssim[t][x] and dssim[t][x] = (1 - ssim) / 2. The same
// operations per value as those two kernels (this file is compiled without contraction), so the
// same bits. `pixel` is scratch of (xb - xa) x 8 floats.
[[gnu::always_inline]] inline void SsimFinishTransposed8Body(
    const float* __restrict moments, const float* __restrict shift_p,
    const float* __restrict shift_q, int n, float cov_norm, int ia, int xa, int xb,
    float* __restrict pixel, float* const* ssim, float* const* dssim) {
  const size_t plane = static_cast<size_t>(n) * 8;
  const float* mx = moments;
  const float* my = moments + plane;
  const float* mss = moments + 2 * plane;
  const float* mxy = moments + 3 * plane;
  const int pixels = xb - xa;
  for (int x = 0; x < pixels; ++x) {
    V8f e[3];
    for (int c = 0; c < 3; ++c) {
      const int i = ia + 3 * x + c;
      const size_t at = static_cast<size_t>(i) * 8;
      FusedSsim(REPHOTO_LOAD(V8f, mx + at), REPHOTO_LOAD(V8f, my + at), REPHOTO_LOAD(V8f, mss + at),
                REPHOTO_LOAD(V8f, mxy + at), shift_p[i], shift_q[i], cov_norm, &e[c]);
    }
    const V8f v = (e[0] + e[1] + e[2]) / 3.0f;
    REPHOTO_STORE(pixel + static_cast<size_t>(x) * 8, v);
  }
  float* sp[8];
  float* dp[8];
  for (int t = 0; t < 8; ++t) {
    sp[t] = ssim[t] + xa;
    dp[t] = dssim[t] + xa;
  }
  int x = 0;
  for (; x + 8 <= pixels; x += 8) {
    V8f v[8], rows[8];
    for (int j = 0; j < 8; ++j) v[j] = REPHOTO_LOAD(V8f, pixel + static_cast<size_t>(x + j) * 8);
    Transpose8(v, rows);
    for (int t = 0; t < 8; ++t) {
      REPHOTO_STORE(sp[t] + x, rows[t]);
      REPHOTO_STORE(dp[t] + x, (1.0f - rows[t]) * 0.5f);
    }
  }
  for (; x < pixels; ++x) {
    for (int t = 0; t < 8; ++t) {
      const float v = pixel[static_cast<size_t>(x) * 8 + t];
      sp[t][x] = v;
      dp[t][x] = (1.0f - v) * 0.5f;
    }
  }
}
REPHOTO_ISA_DISPATCH(void, SsimFinishTransposed8,
                     (const float* __restrict moments, const float* __restrict shift_p,
                      const float* __restrict shift_q, int n, float cov_norm, int ia, int xa,
                      int xb, float* __restrict pixel, float* const* ssim, float* const* dssim),
                     (moments, shift_p, shift_q, n, cov_norm, ia, xa, xb, pixel, ssim, dssim))

// NaN error rows where the window leaves the image; returns the centre rows [c0, c1) (empty when
// no window fits) and fills band_ok with the window validity of each of them.
bool BandStart(const BandInputs& in, int window, const ErrorRows* ssim, const ErrorRows* dssim,
               int64_t y0, int64_t y1, int64_t* c0, int64_t* c1, const uint8_t** band_ok) {
  const int w = in.width, h = in.height, r = window / 2;
  for (int64_t y = y0; y < y1; ++y) {
    const int yi = static_cast<int>(y);
    if (y >= r && y < h - r && w >= window) continue;
    if (ssim) FillNaN(ssim->row(yi), w);
    if (dssim) FillNaN(dssim->row(yi), w);
  }
  *c0 = std::max<int64_t>(y0, r);
  *c1 = std::min<int64_t>(y1, h - r);
  if (*c0 >= *c1 || w < window) return false;
  const int rows = static_cast<int>(*c1 - *c0);
  thread_local std::vector<uint8_t> validity_buffer;
  uint8_t* ok_rows = Scratch(validity_buffer, static_cast<size_t>(rows) * w);
  WindowValidityRows validity(in.valid, w, h, r);
  for (int j = 0; j < rows; ++j) {
    const uint8_t* ok = validity.Row(static_cast<int>(*c0) + j);
    std::copy(ok, ok + w, ok_rows + static_cast<size_t>(j) * w);
  }
  *band_ok = ok_rows;
  return true;
}

// The strip's pixels [x0, x1) of row y from their SSIM/DSSIM values, masked into the error rows
// and added to the sums.
void MaskStripRow(int x0, int x1, int y, const uint8_t* ok, const float* ssim_values,
                  const float* dssim_values, const ErrorRows* ssim, const ErrorRows* dssim,
                  MeanSums* sums) {
  const size_t evaluated = CountRange(ok, x0, x1);
  if (ssim) sums->sum[0] += MaskRange(ssim_values, ok, x0, x1, ssim->row(y));
  if (dssim) sums->sum[1] += MaskRange(dssim_values, ok, x0, x1, dssim->row(y));
  sums->count[0] += evaluated;
  sums->count[1] += evaluated;
}

// Per-pixel SSIM/DSSIM of the strip's pixels [x0, x1) of row y from the per-element values
// `element` (element e0 first), masked into the error rows and added to the sums.
void FinishStripRow(const float* element, int e0, int x0, int x1, int w, int r, int y,
                    const uint8_t* ok, float* ssim_values, float* dssim_values,
                    const ErrorRows* ssim, const ErrorRows* dssim, MeanSums* sums) {
  const int xa = std::max(x0, r), xb = std::min(x1, w - r);
  if (xa < xb) ChannelMeans(element + 3 * xa - e0, xb - xa, ssim_values + xa, dssim_values + xa);
  MaskStripRow(x0, x1, y, ok, ssim_values, dssim_values, ssim, dssim, sums);
}

// The earlier kernel (SsimKernel::kFiveQuantities): per output row, the vertical filter re-reads
// the window's 2r+1 input rows and forms the products again.
MeanSums SsimBandFiveQuantities(const BandInputs& in, const SsimSetup& setup, const ErrorRows* ssim,
                                const ErrorRows* dssim, int64_t y0, int64_t y1) {
  const int w = in.width, r = setup.window / 2;
  MeanSums sums;
  int64_t c0, c1;
  const uint8_t* band_ok;
  if (!BandStart(in, setup.window, ssim, dssim, y0, y1, &c0, &c1, &band_ok)) return sums;
  // The band in strips of kStripPixels columns so that the 2r+1 input rows of a strip stay in
  // cache while the strip moves down the band (whole rows would stream ~1 MB per output row
  // from memory at 4000 px).
  constexpr int kStripPixels = 256;
  const int max_elements = 3 * (kStripPixels + 2 * r);
  thread_local std::vector<float> buffer;
  float* vertical = Scratch(buffer, static_cast<size_t>(11) * max_elements);
  float* moments = vertical + 5 * max_elements;
  float* element = moments + 5 * max_elements;
  thread_local std::vector<float> value_buffer;
  float* ssim_values = Scratch(value_buffer, 2 * static_cast<size_t>(w));
  float* dssim_values = ssim_values + w;
  std::vector<const float*> p_rows(2 * r + 1), q_rows(2 * r + 1);
  for (int x0 = 0; x0 < w; x0 += kStripPixels) {
    const int x1 = std::min(w, x0 + kStripPixels);
    // Elements [e0, e1) feed the horizontal filter of pixels [max(x0, r), min(x1, w - r)).
    const int e0 = 3 * std::max(0, x0 - r), e1 = 3 * std::min(w, x1 + r), m = e1 - e0;
    for (int64_t y = c0; y < c1; ++y) {
      const int yi = static_cast<int>(y);
      for (int k = 0; k <= 2 * r; ++k) {
        p_rows[k] = in.photo.row(yi - r + k) + e0;
        q_rows[k] = in.rephoto.row(yi - r + k) + e0;
      }
      SsimVertical(p_rows.data(), q_rows.data(), setup.weights.data(), r, m, vertical);
      SsimHorizontal(vertical, setup.weights.data(), r, m, moments);
      SsimFormula(moments, r, m, setup.cov_norm, element);
      FinishStripRow(element, e0, x0, x1, w, r, yi, band_ok + static_cast<size_t>(y - c0) * w,
                     ssim_values, dssim_values, ssim, dssim, &sums);
    }
  }
  return sums;
}

// The shift of a strip's values of one image (shift[i] for its elements i in [0, e1 - e0), e0 a
// multiple of 3): per channel, the mean of the image's values in `row`. Moments of values minus
// a shift near them lose less to cancellation (E[x^2] - E[x]^2) in nearly flat windows, where
// float rounding matters most (sigma^2 ~ 1e-6 next to c2 = 9e-4): for a sky at 0.85 the squares
// are ~1e-3 instead of 0.12 with a fixed shift of 0.5. One shift per image, strip and band, so
// that every window sees one shift; it depends only on the image (identical images get the
// same shift), so the values are the same for any number of threads.
void StripShift(const float* row, int e0, int e1, float* shift) {
  double sum[3] = {};
  for (int i = e0; i < e1; i += 3) {
    sum[0] += row[i];
    sum[1] += row[i + 1];
    sum[2] += row[i + 2];
  }
  const double count = (e1 - e0) / 3;
  const float c0 = static_cast<float>(sum[0] / count), c1 = static_cast<float>(sum[1] / count),
              c2 = static_cast<float>(sum[2] / count);
  for (int i = 0; i < e1 - e0; i += 3) {
    shift[i] = c0;
    shift[i + 1] = c1;
    shift[i + 2] = c2;
  }
}

// The fused kernel: per strip, a ring of product rows (each input row's products formed once),
// the vertical filter for a block of output rows at a time, then horizontal filter and formula.
// On the AVX2 path 8 rows at a time on transposed data (SsimVerticalHorizontalTransposed8: an
// 8-wide tap window that crosses the 128-bit halves costs two shuffles on AVX2, a transpose 3 per
// vector, and same-phase outputs share their loaded taps; 0.89x the time of the row-wise pass
// for DSSIM at 12 MP, one thread, in turns), the last block's rows below 8 one row at a time.
// Per output row otherwise: AVX-512 shuffles its 16-wide windows in one instruction, and the
// baseline's emulated 8-wide vectors measured 15 % slower transposed. Same bits either way.
MeanSums SsimBandFused(const BandInputs& in, const SsimSetup& setup, const ErrorRows* ssim,
                       const ErrorRows* dssim, int64_t y0, int64_t y1) {
  const int w = in.width, r = setup.window / 2;
  MeanSums sums;
  int64_t c0, c1;
  const uint8_t* band_ok;
  if (!BandStart(in, setup.window, ssim, dssim, y0, y1, &c0, &c1, &band_ok)) return sums;
  constexpr int kQ = kSsimQuantities;
  const bool transposed = core::ActiveIsa() == core::Isa::kAvx2;
  // Strips narrow enough that the ring of 2r + row_block product rows stays in the L2 cache
  // (179 KB at r = 5 and 4 rows; 256 measured ~3 % faster than 128, blocks of 8 rows no faster
  // than 4 for the row-wise horizontal pass).
  constexpr int kStripPixels = 256;
  constexpr int kMaxRowBlock = 8;
  const int row_block = transposed ? 8 : 4;
  const int ring = 2 * r + row_block;
  const size_t plane_set = static_cast<size_t>(kQ) * 3 * (kStripPixels + 2 * r);
  thread_local std::vector<float> buffer;
  // products (ring), vertical (row_block), moments, element, shifts; transposed: tin (1/4 of a
  // plane set x 8), moments x 8, pixels x 8.
  const size_t transposed_floats = transposed ? (plane_set / kQ + plane_set + plane_set) * 8 : 0;
  float* products = Scratch(buffer, (ring + row_block + 3) * plane_set + transposed_floats);
  float* vertical = products + ring * plane_set;
  float* moments = vertical + row_block * plane_set;
  float* element = moments + plane_set;
  float* shift_p = element + plane_set;
  float* shift_q = shift_p + plane_set / 2;
  float* tin = shift_p + plane_set;
  float* moments8 = tin + plane_set / kQ * 8;
  float* pixels8 = moments8 + plane_set * 8;
  thread_local std::vector<float> value_buffer;
  const int value_rows = transposed ? 8 : 1;
  float* values = Scratch(value_buffer, 2 * static_cast<size_t>(value_rows) * w);
  float* ssim_rows[kMaxRowBlock];
  float* dssim_rows[kMaxRowBlock];
  for (int t = 0; t < value_rows; ++t) {
    ssim_rows[t] = values + static_cast<size_t>(2 * t) * w;
    dssim_rows[t] = ssim_rows[t] + w;
  }
  std::vector<const float*> rows(ring);
  float* out_rows[kMaxRowBlock];
  for (int t = 0; t < row_block; ++t) out_rows[t] = vertical + t * plane_set;
  for (int x0 = 0; x0 < w; x0 += kStripPixels) {
    const int x1 = std::min(w, x0 + kStripPixels);
    // Elements [e0, e1) feed the horizontal filter of pixels [max(x0, r), min(x1, w - r)).
    const int e0 = 3 * std::max(0, x0 - r), e1 = 3 * std::min(w, x1 + r), m = e1 - e0;
    const int xa = std::max(x0, r), xb = std::min(x1, w - r);
    // Input row j's products live in ring slot (j - (c0 - r)) % ring; `next` is the first row
    // not yet formed.
    StripShift(in.photo.row(static_cast<int>(c0)), e0, e1, shift_p);
    StripShift(in.rephoto.row(static_cast<int>(c0)), e0, e1, shift_q);
    const int64_t first_input = c0 - r;
    int64_t next = first_input;
    auto slot = [&](int64_t j) { return products + ((j - first_input) % ring) * (kQ * m); };
    for (int64_t y = c0; y < c1; y += row_block) {
      const int count = static_cast<int>(std::min<int64_t>(row_block, c1 - y));
      for (; next < y + count + r; ++next) {
        const int j = static_cast<int>(next);
        SsimProducts(in.photo.row(j) + e0, in.rephoto.row(j) + e0, shift_p, shift_q, m, slot(next));
      }
      for (int k = 0; k < 2 * r + count; ++k) rows[k] = slot(y - r + k);
      if (count == 8 && transposed) {
        SsimVerticalHorizontalTransposed8(rows.data(), setup.weights.data(), r, m, tin, moments8);
        if (xa < xb) {
          SsimFinishTransposed8(moments8, shift_p, shift_q, m, setup.cov_norm, 3 * xa - e0, xa, xb,
                                pixels8, ssim_rows, dssim_rows);
        }
        for (int t = 0; t < count; ++t) {
          const int64_t yt = y + t;
          MaskStripRow(x0, x1, static_cast<int>(yt), band_ok + static_cast<size_t>(yt - c0) * w,
                       ssim_rows[t], dssim_rows[t], ssim, dssim, &sums);
        }
        continue;
      }
      SsimVerticalRows(rows.data(), setup.weights.data(), r, m, count, out_rows);
      for (int t = 0; t < count; ++t) {
        SsimHorizontalFused(out_rows[t], setup.weights.data(), r, m, moments);
        SsimFormulaFused(moments, shift_p, shift_q, r, m, setup.cov_norm, element);
        const int64_t yt = y + t;
        FinishStripRow(element, e0, x0, x1, w, r, static_cast<int>(yt),
                       band_ok + static_cast<size_t>(yt - c0) * w, ssim_rows[0], dssim_rows[0],
                       ssim, dssim, &sums);
      }
    }
  }
  return sums;
}

}  // namespace

void SetSsimKernel(SsimKernel kernel) { selected_kernel.store(static_cast<int>(kernel)); }

SsimKernel GetSsimKernel() { return static_cast<SsimKernel>(selected_kernel.load()); }

MeanSums SsimBand(const BandInputs& in, const SsimSetup& setup, const ErrorRows* ssim,
                  const ErrorRows* dssim, int64_t y0, int64_t y1) {
  if (GetSsimKernel() == SsimKernel::kFiveQuantities) {
    return SsimBandFiveQuantities(in, setup, ssim, dssim, y0, y1);
  }
  return SsimBandFused(in, setup, ssim, dssim, y0, y1);
}

}  // namespace rephoto::metrics::internal
