#include "rephoto/metrics/metrics.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <string>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/metrics/icid.h"
#include "rephoto/metrics/kernels.h"

namespace rephoto::metrics {
namespace {

using internal::FillNaN;
using internal::kBandRows;
using internal::kNaN;
using internal::MeanSums;
using internal::WindowValidityRows;

struct Inputs {
  const Image& photo;
  const Image& rephoto;
  const Mask& valid;  // may be empty
  int width;
  int height;
};

// Per-thread scratch, reused across bands and calls (TBB workers live for the process).
template <typename T>
T* Scratch(std::vector<T>& buffer, size_t size) {
  if (buffer.size() < size) buffer.resize(size);
  return buffer.data();
}

// ---------------------------------------------------------------------------------------------
// 1-NCC and ZSSD: box sums of x, y, x^2, y^2, xy per channel in double. Column sums slide down
// the band; row sums come from prefix sums, so the cost does not depend on the window.

REPHOTO_SIMD_CLONES
void AddBoxRows(const float* __restrict p, const float* __restrict q, int n,
                double* __restrict cols) {
  double* __restrict sx = cols;
  double* __restrict sy = cols + n;
  double* __restrict sxx = cols + 2 * n;
  double* __restrict syy = cols + 3 * n;
  double* __restrict sxy = cols + 4 * n;
  for (int i = 0; i < n; ++i) {
    const double a = p[i], b = q[i];
    sx[i] += a;
    sy[i] += b;
    sxx[i] += a * a;
    syy[i] += b * b;
    sxy[i] += a * b;
  }
}

REPHOTO_SIMD_CLONES
void SlideBoxRows(const float* __restrict p_add, const float* __restrict q_add,
                  const float* __restrict p_sub, const float* __restrict q_sub, int n,
                  double* __restrict cols) {
  double* __restrict sx = cols;
  double* __restrict sy = cols + n;
  double* __restrict sxx = cols + 2 * n;
  double* __restrict syy = cols + 3 * n;
  double* __restrict sxy = cols + 4 * n;
  for (int i = 0; i < n; ++i) {
    const double a = p_add[i], b = q_add[i], c = p_sub[i], d = q_sub[i];
    sx[i] += a - c;
    sy[i] += b - d;
    sxx[i] += a * a - c * c;
    syy[i] += b * b - d * d;
    sxy[i] += a * b - c * d;
  }
}

// prefix_q[i + 3] = prefix_q[i] + cols_q[i] (stride 3 = per channel), for the 5 quantities.
void BoxPrefix(const double* cols, int n, double* prefix) {
  const int m = n + 3;
  for (int q = 0; q < 5; ++q) {
    for (int i = 0; i < 3; ++i) prefix[q * m + i] = 0;
  }
  for (int i = 0; i < n; ++i) {
    for (int q = 0; q < 5; ++q) prefix[q * m + i + 3] = prefix[q * m + i] + cols[q * n + i];
  }
}

// Per element (pixel x channel): summed squared deviations and co-deviation of the window.
REPHOTO_SIMD_CLONES
void BoxMoments(const double* __restrict prefix, int n, int r, double inv_count,
                double* __restrict var_x, double* __restrict var_y, double* __restrict cov) {
  const int m = n + 3;
  const double* __restrict px = prefix;
  const double* __restrict py = prefix + m;
  const double* __restrict pxx = prefix + 2 * m;
  const double* __restrict pyy = prefix + 3 * m;
  const double* __restrict pxy = prefix + 4 * m;
  const int lo = 3 * r, hi = n - 3 * r, ahead = 3 * r + 3, behind = 3 * r;
  for (int i = lo; i < hi; ++i) {
    const double sx = px[i + ahead] - px[i - behind];
    const double sy = py[i + ahead] - py[i - behind];
    const double sxx = pxx[i + ahead] - pxx[i - behind];
    const double syy = pyy[i + ahead] - pyy[i - behind];
    const double sxy = pxy[i + ahead] - pxy[i - behind];
    var_x[i] = sxx - sx * sx * inv_count;
    var_y[i] = syy - sy * sy * inv_count;
    cov[i] = sxy - sx * sy * inv_count;
  }
}

MeanSums BoxBand(const Inputs& in, int window, double flat, Image* ncc, Image* zssd, int64_t y0,
                 int64_t y1) {
  const int w = in.width, h = in.height, r = window / 2, n = 3 * w;
  MeanSums sums;
  const int64_t c0 = std::max<int64_t>(y0, r), c1 = std::min<int64_t>(y1, h - r);
  for (int64_t y = y0; y < y1; ++y) {
    if (y >= c0 && y < c1) continue;
    if (ncc) FillNaN(ncc->row(static_cast<int>(y)), w);
    if (zssd) FillNaN(zssd->row(static_cast<int>(y)), w);
  }
  if (c0 >= c1 || w < window) {
    for (int64_t y = c0; y < c1; ++y) {
      if (ncc) FillNaN(ncc->row(static_cast<int>(y)), w);
      if (zssd) FillNaN(zssd->row(static_cast<int>(y)), w);
    }
    return sums;
  }
  thread_local std::vector<double> buffer;
  double* cols = Scratch(buffer, static_cast<size_t>(5 * n + 5 * (n + 3) + 3 * n));
  double* prefix = cols + 5 * n;
  double* var_x = prefix + 5 * (n + 3);
  double* var_y = var_x + n;
  double* cov = var_y + n;
  std::fill(cols, cols + 5 * n, 0.0);
  for (int64_t j = c0 - r; j <= c0 + r; ++j) {
    AddBoxRows(in.photo.row(static_cast<int>(j)), in.rephoto.row(static_cast<int>(j)), n, cols);
  }
  WindowValidityRows validity(in.valid, w, h, r);
  const double count = static_cast<double>(window) * window;
  const double inv_count = 1.0 / count;
  for (int64_t y = c0; y < c1; ++y) {
    const int yi = static_cast<int>(y);
    if (y > c0) {
      SlideBoxRows(in.photo.row(yi + r), in.rephoto.row(yi + r), in.photo.row(yi - r - 1),
                   in.rephoto.row(yi - r - 1), n, cols);
    }
    BoxPrefix(cols, n, prefix);
    BoxMoments(prefix, n, r, inv_count, var_x, var_y, cov);
    const uint8_t* ok = validity.Row(yi);
    float* ncc_row = ncc ? ncc->row(yi) : nullptr;
    float* zssd_row = zssd ? zssd->row(yi) : nullptr;
    double ncc_sum = 0, zssd_sum = 0;
    size_t evaluated = 0;
    for (int x = 0; x < w; ++x) {
      if (x < r || x >= w - r || !ok[x]) {
        if (ncc_row) ncc_row[x] = kNaN;
        if (zssd_row) zssd_row[x] = kNaN;
        continue;
      }
      const int i = 3 * x;
      const double dx = var_x[i] + var_x[i + 1] + var_x[i + 2];
      const double dy = var_y[i] + var_y[i + 1] + var_y[i + 2];
      const double dxy = cov[i] + cov[i + 1] + cov[i + 2];
      ++evaluated;
      if (ncc_row) {
        const bool flat_x = dx <= flat, flat_y = dy <= flat;
        double e;
        if (flat_x && flat_y) {
          e = 0;
        } else if (flat_x || flat_y) {
          e = 1;
        } else {
          e = std::clamp(1.0 - dxy / std::sqrt(dx * dy), 0.0, 2.0);
        }
        ncc_row[x] = static_cast<float>(e);
        ncc_sum += ncc_row[x];
      }
      if (zssd_row) {
        zssd_row[x] = static_cast<float>(std::max(0.0, dx + dy - 2 * dxy) * inv_count / 3);
        zssd_sum += zssd_row[x];
      }
    }
    sums.sum[0] += ncc_sum;
    sums.sum[1] += zssd_sum;
    sums.count[0] += evaluated;
    sums.count[1] += evaluated;
  }
  return sums;
}

// ---------------------------------------------------------------------------------------------
// Census on luma.

REPHOTO_SIMD_CLONES
void LumaRow(const float* __restrict rgb, int width, float* __restrict luma) {
  for (int x = 0; x < width; ++x) {
    luma[x] = 0.299f * rgb[3 * x] + 0.587f * rgb[3 * x + 1] + 0.114f * rgb[3 * x + 2];
  }
}

typedef float V8f __attribute__((vector_size(32)));
typedef int V8i __attribute__((vector_size(32)));

// counts[x - r] for x in [r, r + 16 * blocks): number of window neighbours whose census bit
// differs. `photo_rows` / `rephoto_rows` point to the 2r+1 luma rows of the window.
REPHOTO_SIMD_CLONES
void CensusCounts(const float* const* photo_rows, const float* const* rephoto_rows, int r,
                  int blocks, int* counts) {
  for (int b = 0; b < blocks; ++b) {
    const int x = r + 16 * b;
    V8f cp0, cp1, cr0, cr1;
    __builtin_memcpy(&cp0, photo_rows[r] + x, 32);
    __builtin_memcpy(&cp1, photo_rows[r] + x + 8, 32);
    __builtin_memcpy(&cr0, rephoto_rows[r] + x, 32);
    __builtin_memcpy(&cr1, rephoto_rows[r] + x + 8, 32);
    V8i n0 = {}, n1 = {};
    for (int dy = 0; dy <= 2 * r; ++dy) {
      const float* pr = photo_rows[dy] + x;
      const float* rr = rephoto_rows[dy] + x;
      for (int dx = -r; dx <= r; ++dx) {
        // The centre compares false with itself in both images and adds nothing.
        V8f p0, p1, q0, q1;
        __builtin_memcpy(&p0, pr + dx, 32);
        __builtin_memcpy(&p1, pr + dx + 8, 32);
        __builtin_memcpy(&q0, rr + dx, 32);
        __builtin_memcpy(&q1, rr + dx + 8, 32);
        n0 -= (p0 < cp0) ^ (q0 < cr0);
        n1 -= (p1 < cp1) ^ (q1 < cr1);
      }
    }
    __builtin_memcpy(counts + 16 * b, &n0, 32);
    __builtin_memcpy(counts + 16 * b + 8, &n1, 32);
  }
}

MeanSums CensusBand(const Inputs& in, int window, Image* census, int64_t y0, int64_t y1) {
  const int w = in.width, h = in.height, r = window / 2;
  MeanSums sums;
  const int64_t c0 = std::max<int64_t>(y0, r), c1 = std::min<int64_t>(y1, h - r);
  for (int64_t y = y0; y < y1; ++y) {
    if (y < c0 || y >= c1 || w < window) FillNaN(census->row(static_cast<int>(y)), w);
  }
  if (c0 >= c1 || w < window) return sums;
  // Luma rows [c0 - r, c1 + r) of both images.
  const int rows = static_cast<int>(c1 - c0) + 2 * r;
  thread_local std::vector<float> luma_buffer;
  float* luma = Scratch(luma_buffer, static_cast<size_t>(2 * rows) * w);
  for (int j = 0; j < rows; ++j) {
    const int y = static_cast<int>(c0) - r + j;
    LumaRow(in.photo.row(y), w, luma + static_cast<size_t>(j) * w);
    LumaRow(in.rephoto.row(y), w, luma + static_cast<size_t>(rows + j) * w);
  }
  thread_local std::vector<int> count_buffer;
  int* counts = Scratch(count_buffer, static_cast<size_t>(w));
  std::vector<const float*> photo_rows(2 * r + 1), rephoto_rows(2 * r + 1);
  WindowValidityRows validity(in.valid, w, h, r);
  const int inner = w - 2 * r;
  const int blocks = inner / 16;
  const float inv = 1.0f / static_cast<float>(window * window - 1);
  for (int64_t y = c0; y < c1; ++y) {
    const int j0 = static_cast<int>(y - c0);
    for (int k = 0; k <= 2 * r; ++k) {
      photo_rows[k] = luma + static_cast<size_t>(j0 + k) * w;
      rephoto_rows[k] = luma + static_cast<size_t>(rows + j0 + k) * w;
    }
    CensusCounts(photo_rows.data(), rephoto_rows.data(), r, blocks, counts);
    for (int x = r + 16 * blocks; x < w - r; ++x) {  // tail
      int n = 0;
      const float cp = photo_rows[r][x], cr = rephoto_rows[r][x];
      for (int k = 0; k <= 2 * r; ++k) {
        for (int dx = -r; dx <= r; ++dx) {
          n += (photo_rows[k][x + dx] < cp) != (rephoto_rows[k][x + dx] < cr);
        }
      }
      counts[x - r] = n;
    }
    const uint8_t* ok = validity.Row(static_cast<int>(y));
    float* out = census->row(static_cast<int>(y));
    double s = 0;
    size_t evaluated = 0;
    for (int x = 0; x < w; ++x) {
      if (x < r || x >= w - r || !ok[x]) {
        out[x] = kNaN;
      } else {
        out[x] = static_cast<float>(counts[x - r]) * inv;
        s += out[x];
        ++evaluated;
      }
    }
    sums.sum[0] += s;
    sums.count[0] += evaluated;
  }
  return sums;
}

// ---------------------------------------------------------------------------------------------
// Pixel metrics: Cb+Cr and the squared error of PSNR.

MeanSums PixelBand(const Inputs& in, Image* cbcr, Image* squared, int64_t y0, int64_t y1) {
  MeanSums sums;
  const int w = in.width;
  for (int64_t y = y0; y < y1; ++y) {
    const int yi = static_cast<int>(y);
    const float* p = in.photo.row(yi);
    const float* q = in.rephoto.row(yi);
    const uint8_t* ok = in.valid.empty() ? nullptr : in.valid.row(yi);
    float* cbcr_row = cbcr ? cbcr->row(yi) : nullptr;
    float* sq_row = squared ? squared->row(yi) : nullptr;
    double cbcr_sum = 0, sq_sum = 0;
    size_t evaluated = 0;
    for (int x = 0; x < w; ++x) {
      if (ok && !ok[x]) {
        if (cbcr_row) cbcr_row[x] = kNaN;
        if (sq_row) sq_row[x] = kNaN;
        continue;
      }
      ++evaluated;
      const float dr = p[3 * x] - q[3 * x];
      const float dg = p[3 * x + 1] - q[3 * x + 1];
      const float db = p[3 * x + 2] - q[3 * x + 2];
      if (cbcr_row) {
        // Full-range BT.601 (JPEG): Cb = -0.168736 R - 0.331264 G + 0.5 B,
        // Cr = 0.5 R - 0.418688 G - 0.081312 B (the +0.5 offsets cancel in the difference).
        const float dcb = -0.168736f * dr - 0.331264f * dg + 0.5f * db;
        const float dcr = 0.5f * dr - 0.418688f * dg - 0.081312f * db;
        cbcr_row[x] = std::abs(dcb) + std::abs(dcr);
        cbcr_sum += cbcr_row[x];
      }
      if (sq_row) {
        // Double, so the masked MSE keeps full precision for nearly identical images.
        const double e = (static_cast<double>(dr) * dr + static_cast<double>(dg) * dg +
                          static_cast<double>(db) * db) /
                         3.0;
        sq_row[x] = static_cast<float>(e);
        sq_sum += e;
      }
    }
    sums.sum[0] += cbcr_sum;
    sums.sum[1] += sq_sum;
    sums.count[0] += evaluated;
    sums.count[1] += evaluated;
  }
  return sums;
}

// ---------------------------------------------------------------------------------------------
// SSIM / DSSIM: separable weighted window of x, y, x^2, y^2, xy per channel on interleaved
// rows (filtering is element-wise, so channel interleaving does not matter; horizontal taps
// step by 3). Values are shifted by -0.5 before squaring, which halves their magnitude and
// the cancellation in E[x^2] - E[x]^2; the shift cancels in variances and covariances.

constexpr int kBlock = 512;

REPHOTO_SIMD_CLONES
void SsimVertical(const float* const* p_rows, const float* const* q_rows,
                  const float* __restrict weights, int r, int n, float* __restrict out) {
  float* __restrict vx = out;
  float* __restrict vy = out + n;
  float* __restrict vxx = out + 2 * n;
  float* __restrict vyy = out + 3 * n;
  float* __restrict vxy = out + 4 * n;
  for (int b0 = 0; b0 < n; b0 += kBlock) {
    const int b1 = std::min(n, b0 + kBlock);
    const float w0 = weights[r];
    const float* __restrict pc = p_rows[r];
    const float* __restrict qc = q_rows[r];
    for (int i = b0; i < b1; ++i) {
      const float a = pc[i] - 0.5f, b = qc[i] - 0.5f;
      vx[i] = w0 * a;
      vy[i] = w0 * b;
      vxx[i] = w0 * (a * a);
      vyy[i] = w0 * (b * b);
      vxy[i] = w0 * (a * b);
    }
    for (int k = 1; k <= r; ++k) {
      const float wk = weights[r + k];
      const float* __restrict p1 = p_rows[r - k];
      const float* __restrict p2 = p_rows[r + k];
      const float* __restrict q1 = q_rows[r - k];
      const float* __restrict q2 = q_rows[r + k];
      for (int i = b0; i < b1; ++i) {
        const float a1 = p1[i] - 0.5f, a2 = p2[i] - 0.5f;
        const float b1v = q1[i] - 0.5f, b2v = q2[i] - 0.5f;
        vx[i] += wk * (a1 + a2);
        vy[i] += wk * (b1v + b2v);
        vxx[i] += wk * (a1 * a1 + a2 * a2);
        vyy[i] += wk * (b1v * b1v + b2v * b2v);
        vxy[i] += wk * (a1 * b1v + a2 * b2v);
      }
    }
  }
}

REPHOTO_SIMD_CLONES
void SsimHorizontal(const float* __restrict in, const float* __restrict weights, int r, int n,
                    float* __restrict out) {
  // out[i] for i in [3r, n - 3r).
  for (int b0 = 3 * r; b0 < n - 3 * r; b0 += kBlock) {
    const int b1 = std::min(n - 3 * r, b0 + kBlock);
    const float w0 = weights[r];
    for (int i = b0; i < b1; ++i) out[i] = w0 * in[i];
    for (int k = 1; k <= r; ++k) {
      const float wk = weights[r + k];
      const float* __restrict left = in - 3 * k;
      const float* __restrict right = in + 3 * k;
      for (int i = b0; i < b1; ++i) out[i] += wk * (left[i] + right[i]);
    }
  }
}

REPHOTO_SIMD_CLONES
void SsimFormula(const float* __restrict moments, int r, int n, float cov_norm,
                 float* __restrict ssim) {
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

struct SsimSetup {
  int window;
  std::vector<float> weights;
  float cov_norm;
};

MeanSums SsimBand(const Inputs& in, const SsimSetup& setup, Image* ssim, Image* dssim, int64_t y0,
                  int64_t y1) {
  const int w = in.width, h = in.height, r = setup.window / 2, n = 3 * w;
  MeanSums sums;
  for (int64_t y = y0; y < y1; ++y) {
    const int yi = static_cast<int>(y);
    if (y >= r && y < h - r && w >= setup.window) continue;
    if (ssim) FillNaN(ssim->row(yi), w);
    if (dssim) FillNaN(dssim->row(yi), w);
  }
  const int64_t c0 = std::max<int64_t>(y0, r), c1 = std::min<int64_t>(y1, h - r);
  if (c0 >= c1 || w < setup.window) return sums;
  thread_local std::vector<float> buffer;
  float* vertical = Scratch(buffer, static_cast<size_t>(11) * n);
  float* moments = vertical + 5 * n;
  float* element = moments + 5 * n;
  std::vector<const float*> p_rows(2 * r + 1), q_rows(2 * r + 1);
  WindowValidityRows validity(in.valid, w, h, r);
  for (int64_t y = c0; y < c1; ++y) {
    const int yi = static_cast<int>(y);
    for (int k = 0; k <= 2 * r; ++k) {
      p_rows[k] = in.photo.row(yi - r + k);
      q_rows[k] = in.rephoto.row(yi - r + k);
    }
    SsimVertical(p_rows.data(), q_rows.data(), setup.weights.data(), r, n, vertical);
    for (int q = 0; q < 5; ++q) {
      SsimHorizontal(vertical + q * n, setup.weights.data(), r, n, moments + q * n);
    }
    SsimFormula(moments, r, n, setup.cov_norm, element);
    const uint8_t* ok = validity.Row(yi);
    float* ssim_row = ssim ? ssim->row(yi) : nullptr;
    float* dssim_row = dssim ? dssim->row(yi) : nullptr;
    double ssim_sum = 0, dssim_sum = 0;
    size_t evaluated = 0;
    for (int x = 0; x < w; ++x) {
      if (x < r || x >= w - r || !ok[x]) {
        if (ssim_row) ssim_row[x] = kNaN;
        if (dssim_row) dssim_row[x] = kNaN;
        continue;
      }
      const float* e = element + 3 * x;
      const float s = (e[0] + e[1] + e[2]) / 3.0f;
      ++evaluated;
      if (ssim_row) {
        ssim_row[x] = s;
        ssim_sum += s;
      }
      if (dssim_row) {
        dssim_row[x] = (1.0f - s) * 0.5f;
        dssim_sum += dssim_row[x];
      }
    }
    sums.sum[0] += ssim_sum;
    sums.sum[1] += dssim_sum;
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
  }
  return "unknown";
}

const std::vector<Metric>& AllMetrics() {
  static const std::vector<Metric> all = {Metric::kOneMinusNcc, Metric::kCbCr,   Metric::kZssd,
                                          Metric::kDssim,       Metric::kCensus, Metric::kIcid,
                                          Metric::kPsnr,        Metric::kSsim};
  return all;
}

std::optional<Metric> ParseMetric(std::string_view name) {
  std::string lower(name);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (Metric m : AllMetrics()) {
    if (MetricName(m) == lower) return m;
  }
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
        ThrowError("--metrics: unknown metric '{}' (known: {}, all)", item, known);
      }
      if (std::find(out.begin(), out.end(), *m) == out.end()) out.push_back(*m);
    }
    start = end + 1;
  }
  return out;
}

bool HigherIsBetter(Metric metric) { return metric == Metric::kPsnr || metric == Metric::kSsim; }

void ComputeMetrics(const Image& photo, const Image& rephoto, const Mask& valid,
                    const std::vector<Metric>& metrics, const MetricOptions& options,
                    std::vector<MetricResult>* results) {
  REPHOTO_CHECK(photo.channels() == 3 && rephoto.channels() == 3,
                "metrics: need 3-channel RGB images, got {} (photo) and {} (rendering) channels",
                photo.channels(), rephoto.channels());
  REPHOTO_CHECK(photo.SameSize(rephoto), "metrics: photo is {}x{} but the rendering is {}x{}",
                photo.width(), photo.height(), rephoto.width(), rephoto.height());
  REPHOTO_CHECK(valid.empty() || (valid.SameSize(photo) && valid.channels() == 1),
                "metrics: validity mask is {}x{}x{} but the images are {}x{}", valid.width(),
                valid.height(), valid.channels(), photo.width(), photo.height());
  CheckOptions(options);
  const int w = photo.width(), h = photo.height();
  const Inputs in{photo, rephoto, valid, w, h};

  for (size_t i = 0; i < metrics.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      REPHOTO_CHECK(metrics[i] != metrics[j], "metrics: {} requested twice",
                    MetricName(metrics[i]));
    }
  }
  results->resize(metrics.size());
  Image* slot[8] = {};
  for (size_t i = 0; i < metrics.size(); ++i) {
    MetricResult& res = (*results)[i];
    res.metric = metrics[i];
    res.error.Resize(w, h, 1);
    res.mean = std::numeric_limits<double>::quiet_NaN();
    res.evaluated = 0;
    slot[static_cast<int>(metrics[i])] = &res.error;
  }
  auto image = [&](Metric m) { return slot[static_cast<int>(m)]; };
  auto finish = [&](Metric m, const MeanSums& sums, int s) {
    for (MetricResult& res : *results) {
      if (res.metric == m) {
        res.mean = MeanOf(sums, s);
        res.evaluated = sums.count[s];
      }
    }
  };

  if (image(Metric::kOneMinusNcc) || image(Metric::kZssd)) {
    const MeanSums sums = ParallelSum<MeanSums>(0, h, kBandRows, [&](int64_t y0, int64_t y1) {
      return BoxBand(in, options.window, options.ncc_flat_threshold, image(Metric::kOneMinusNcc),
                     image(Metric::kZssd), y0, y1);
    });
    finish(Metric::kOneMinusNcc, sums, 0);
    finish(Metric::kZssd, sums, 1);
  }
  if (image(Metric::kCensus)) {
    const MeanSums sums = ParallelSum<MeanSums>(0, h, kBandRows, [&](int64_t y0, int64_t y1) {
      return CensusBand(in, options.window, image(Metric::kCensus), y0, y1);
    });
    finish(Metric::kCensus, sums, 0);
  }
  if (image(Metric::kCbCr) || image(Metric::kPsnr)) {
    const MeanSums sums = ParallelSum<MeanSums>(0, h, kBandRows, [&](int64_t y0, int64_t y1) {
      return PixelBand(in, image(Metric::kCbCr), image(Metric::kPsnr), y0, y1);
    });
    finish(Metric::kCbCr, sums, 0);
    finish(Metric::kPsnr, sums, 1);
    for (MetricResult& res : *results) {
      if (res.metric == Metric::kPsnr && res.evaluated > 0) {
        // mean currently holds the masked MSE.
        res.mean = res.mean > 0 ? 10.0 * std::log10(1.0 / res.mean)
                                : std::numeric_limits<double>::infinity();
      }
    }
  }
  if (image(Metric::kSsim) || image(Metric::kDssim)) {
    SsimSetup setup;
    setup.window = options.ssim_window;
    setup.weights = internal::FilterWeights(options.ssim_window / 2,
                                            options.ssim_gaussian ? options.ssim_sigma : 0);
    const double n = static_cast<double>(options.ssim_window) * options.ssim_window;
    setup.cov_norm = options.ssim_gaussian ? 1.0f : static_cast<float>(n / (n - 1));
    const MeanSums sums = ParallelSum<MeanSums>(0, h, kBandRows, [&](int64_t y0, int64_t y1) {
      return SsimBand(in, setup, image(Metric::kSsim), image(Metric::kDssim), y0, y1);
    });
    finish(Metric::kSsim, sums, 0);
    finish(Metric::kDssim, sums, 1);
  }
  if (image(Metric::kIcid)) {
    IcidOptions icid;
    icid.window = options.icid_window;
    icid.sigma = options.icid_sigma;
    double mean = 0;
    size_t evaluated = 0;
    ComputeIcid(photo, rephoto, valid, icid, image(Metric::kIcid), &mean, &evaluated);
    for (MetricResult& res : *results) {
      if (res.metric == Metric::kIcid) {
        res.mean = mean;
        res.evaluated = evaluated;
      }
    }
  }
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
