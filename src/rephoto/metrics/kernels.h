// Internal helpers shared by the metric kernels (not part of the public API).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "rephoto/core/image.h"
#include "rephoto/core/isa.h"
#include "rephoto/metrics/metrics.h"

// Row kernels are compiled once per instruction-set path (AVX-512, AVX2+FMA, baseline;
// core/isa.h REPHOTO_ISA_DISPATCH) and each call takes the variant of core::ActiveIsa().
// Floating-point contraction is off for this library (CMakeLists.txt), so the variants compute
// bit-identical results, except the SSIM filters (ssim_filter.cc, ssim_fused.cc): their AVX-512
// and AVX2 versions agree bit for bit (FMA, the same order of operations per output value), the
// baseline without FMA rounds differently (within 1e-6 relative). REPHOTO_ISA=avx2 runs the AVX2
// code on a CPU that has AVX-512.
#if defined(REPHOTO_HAVE_ISA_TARGETS)
#define REPHOTO_HAVE_AVX512_KERNELS 1
#endif

namespace rephoto::metrics::internal {

// Per-thread scratch, reused across bands and calls (TBB workers live for the process).
template <typename T>
T* Scratch(std::vector<T>& buffer, size_t size) {
  if (buffer.size() < size) buffer.resize(size);
  return buffer.data();
}

inline constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
// Output rows per parallel chunk. Fixed (not derived from the thread count) so that ordered
// reductions give the same result on every machine.
inline constexpr int64_t kBandRows = 32;

// Masked sums of up to kSlots error images, combined in chunk order.
struct MeanSums {
  static constexpr int kSlots = 4;
  double sum[kSlots] = {};
  size_t count[kSlots] = {};
  MeanSums& operator+=(const MeanSums& other) {
    for (int i = 0; i < kSlots; ++i) {
      sum[i] += other.sum[i];
      count[i] += other.count[i];
    }
    return *this;
  }
};

// k / 255.f for the float of an 8-bit value k, without the division: k * c_hi + k * c_lo with
// c_hi = 0x1.01p-8 (9 significant bits, so k * c_hi is exact) and c_lo = 0x1.010102p-24 (the
// rest of 1/255, its product rounded off ~2^-40 of the value): the one rounding of the sum is
// that of k / 255, which lies at least ~2^-33 of the value away from a rounding boundary (255
// is odd, k / 255 is never a tie), so the result is k / 255.f bit for bit. Checked for every
// k (ByteToUnitFloatIsTheDivisionForEveryByte). Plain multiplies and an add (contraction is off
// for this library), so the same on every path, and no division on the hot path.
inline constexpr float kUnitHi = 0x1.01p-8f, kUnitLo = 0x1.010102p-24f;
[[gnu::always_inline]] inline float ByteToUnitFloat(float k) { return k * kUnitHi + k * kUnitLo; }

// Interleaved float RGB rows [first, end) of an RgbView: pointers into the image itself when it
// is float RGB, else the rows converted into per-thread scratch (8-bit v -> float(v) / 255.f,
// alpha dropped). Rows outside the image are not available.
class RgbRows {
 public:
  // Rows [first, end) as float RGB (converted into *scratch unless the image already is
  // float RGB). With floats = false an 8-bit image is only referenced (bytes_row), for callers
  // that read nothing else (iCID alone): row() must not be called then.
  void Load(const RgbView& image, int first, int end, std::vector<float>* scratch,
            bool floats = true);
  const float* row(int y) const { return base_ + static_cast<ptrdiff_t>(y - first_) * stride_; }
  // The 8-bit source row y (channels() values per pixel, RGB first) when the image is 8-bit,
  // else null; row(y)[3 x + c] == bytes_row(y)[channels() x + c] / 255.f. Any row of the image.
  const uint8_t* bytes_row(int y) const {
    return bytes_ ? bytes_ + static_cast<ptrdiff_t>(y) * byte_stride_ : nullptr;
  }
  int channels() const { return channels_; }

 private:
  const uint8_t* bytes_ = nullptr;
  ptrdiff_t byte_stride_ = 0;
  int channels_ = 3;
  const float* base_ = nullptr;
  int first_ = 0;
  ptrdiff_t stride_ = 0;
};

// Where a band's error rows go: row(y) for the band's rows (a whole image with first = 0, or a
// band buffer whose first row is image row `first`).
struct ErrorRows {
  float* data = nullptr;
  int first = 0;
  int width = 0;
  float* row(int y) const { return data + static_cast<ptrdiff_t>(y - first) * width; }
};

// The photo/rendering rows of a band and the joint validity.
struct BandInputs {
  const RgbRows& photo;
  const RgbRows& rephoto;
  const Mask& valid;  // may be empty
  int width;
  int height;
  // Identifies the call these inputs belong to (NewCallId; 0: none). Bands of one call on one
  // thread may reuse each other's per-pixel values (IcidBand); bands of different calls never.
  uint64_t call = 0;
};

// A number no earlier call got (thread-safe; never 0).
uint64_t NewCallId();

// iCID of the output rows [y0, y1) (icid.cc); needs source rows [y0 - r, y1 + r).
MeanSums IcidBand(const BandInputs& in, int window, const std::vector<double>& weights,
                  const ErrorRows* error, int64_t y0, int64_t y1);

// Produces, for consecutive centre rows y, the row of window validity: out[x] = 1 where the
// (2r+1)^2 window centred at (x, y) is inside the image and all valid. `valid` may be empty
// (everything valid). Column counts slide from row to row (O(width) per row); the row test
// takes log2(2r+1) vectorised byte passes.
class WindowValidityRows {
 public:
  WindowValidityRows(const Mask& valid, int width, int height, int radius);
  // Centre row y in [radius, height - radius). Returns `width` bytes.
  const uint8_t* Row(int y);

 private:
  const Mask& valid_;
  int width_, height_, radius_;
  int last_y_ = -1000000;
  std::vector<int> column_invalid_;
  std::vector<uint8_t> row_;
  std::vector<uint8_t> span_;
};

// Normalised 1-D weights of length 2r+1: Gaussian exp(-k^2 / (2 sigma^2)), or uniform if
// sigma <= 0.
std::vector<float> FilterWeights(int radius, double sigma);

// The five-quantity kernel's SSIM filters (SsimKernel::kFiveQuantities) on interleaved RGB rows
// of n = 3 * width values (ssim_filter.cc).
// Vertical: out[q * n + i] for q = x, y, x^2, y^2, xy of the values shifted by -0.5 = weighted
// sum over the 2r+1 rows.
void SsimVertical(const float* const* p_rows, const float* const* q_rows, const float* weights,
                  int r, int n, float* out);
// Horizontal, for the 5 planes of n values of SsimVertical's output: out[q * n + i] = weighted
// sum of in[q * n + i + 3k], k in [-r, r], for i in [3r, n - 3r).
void SsimHorizontal(const float* in, const float* weights, int r, int n, float* out);

// The fused SSIM filters (ssim_fused.cc) on interleaved RGB rows of n = 3 * width values, each
// image's values shifted by a row of n values (variances and covariances do not change; the
// shift keeps the squares small, see ssim.cc): four quantities x, y, x^2 + y^2 and xy, each a
// plane of n values.
inline constexpr int kSsimQuantities = 4;
// out[q * n + i] = product q of p[i] - shift_p[i] and q[i] - shift_q[i] (the input row of the
// vertical filter).
void SsimProducts(const float* p, const float* q, const float* shift_p, const float* shift_q, int n,
                  float* out);
// Vertical filter of `count` output rows at once: out[t][q * n + i] = sum over k in [-r, r] of
// weights[r + k] * rows[t + r + k][q * n + i], for t in [0, count); rows holds the product rows
// (SsimProducts) of 2r + count consecutive input rows.
void SsimVerticalRows(const float* const* rows, const float* weights, int r, int n, int count,
                      float* const* out);
// Horizontal filter of the 4 planes of n values of SsimVerticalRows' output: out[q * n + i] =
// weighted sum of in[q * n + i + 3k], k in [-r, r], for i in [3r, n - 3r).
void SsimHorizontalFused(const float* in, const float* weights, int r, int n, float* out);
// SsimVerticalRows of 8 rows followed by the horizontal filter of each of them, in one pass on
// transposed data (the path without AVX-512, where the taps of one row vector are shuffles
// across 128-bit halves): rows holds the 2r + 8 product rows; tin (n x 8 floats, scratch)
// receives each plane's 8 vertical rows transposed in registers, value i of row t at
// tin[8 i + t], so that every horizontal tap is a whole vector; out[(q * n + i) * 8 + t] = the
// filtered value i of plane q of row t, for i in [3r, n - 3r). The same arithmetic per value as
// SsimVerticalRows and SsimHorizontalFused, so the same bits.
void SsimVerticalHorizontalTransposed8(const float* const* rows, const float* weights, int r, int n,
                                       float* tin, float* out);

// The SSIM settings of a call.
struct SsimSetup {
  int window = 0;
  std::vector<float> weights;  // FilterWeights(window / 2, ...)
  float cov_norm = 1;          // 1 (Gaussian) or N / (N - 1) (uniform, sample covariance)
};

// The SSIM kernels: kFused (default; ssim_fused.cc) and the earlier kFiveQuantities
// (ssim_filter.cc: x, y, x^2, y^2 and xy filtered separately, the window's rows re-read for
// each output row), kept so benchmarks and tests can compare the two. Process-wide; change it
// only while no metrics are being computed (benchmarks, tests). Reading it is thread-safe.
enum class SsimKernel { kFused, kFiveQuantities };
void SetSsimKernel(SsimKernel kernel);
SsimKernel GetSsimKernel();

// SSIM and DSSIM of the output rows [y0, y1) (ssim.cc) with the kernel GetSsimKernel() names;
// needs source rows [y0 - r, y1 + r). Sums: slot 0 SSIM, slot 1 DSSIM.
MeanSums SsimBand(const BandInputs& in, const SsimSetup& setup, const ErrorRows* ssim,
                  const ErrorRows* dssim, int64_t y0, int64_t y1);

// out[x] = values[x] where ok[x], else NaN, for x in [begin, end); returns the sum of the
// copied values. `ok` must be 0 where the window leaves the image (WindowValidityRows rows
// are).
double MaskRange(const float* values, const uint8_t* ok, int begin, int end, float* out);

// Whether the kernels that have a separate AVX-512 (x86-64-v4) version take it now: the active
// path is AVX-512 (core::ActiveIsa()). Thread-safe.
inline bool HasAvx512() { return core::ActiveIsa() == core::Isa::kAvx512; }

// Census keys (issue 29). Census compares luma Y = 0.299 R + 0.587 G + 0.114 B in fixed point:
// key = floor((255000 Y + 0.5) / 4), with 255000 Y clamped to [0, 255000] (NaN: 0), i.e. 0 to
// 63750, stored as key - 32768 in int16 so that the compares run 16 (AVX2) or 32 (AVX-512) lanes
// wide. For 8-bit values R, G, B (k / 255) it is exactly (299 R + 587 G + 114 B) >> 2: the
// integer luma Y1000 in steps of 4 (4 / 255000 = 1 / 63750 of the range, 250 steps per 8-bit
// level). For floats, t = 255000 Y is computed in float as below, whose rounding error is below
// 0.05 for values k / 255.f (every 8-bit value's float), while every integer Y1000 lies 0.5 away
// from a key boundary (t = 4 k - 0.5): an 8-bit image and its float conversion give the same
// keys (checked for all 2^24 colours in metrics_test). The map is monotonic: a census bit
// differs from a compare of exact luma only for two lumas less than 1/63750 apart that share a
// key.
inline int16_t CensusKey(float r, float g, float b) {
  float t = 76245.f * r + 149685.f * g + 29070.f * b;  // 255 (299 r + 587 g + 114 b)
  t = t >= 0.f ? (t <= 255000.f ? t : 255000.f) : 0.f;
  return static_cast<int16_t>(static_cast<int>((t + 0.5f) * 0.25f) - 32768);
}
// The key of 8-bit values: (299 r + 587 g + 114 b) >> 2 = a + (b' >> 2) with a = 74 r + 146 g +
// 28 b and b' = 3 r + 3 g + 2 b (299 = 4 * 74 + 3, ...), every step in 16 bits.
inline int16_t CensusKeyOfBytes(uint8_t r, uint8_t g, uint8_t b) {
  const uint16_t a = static_cast<uint16_t>(74 * r + 146 * g + 28 * b);
  const uint16_t low = static_cast<uint16_t>(3 * r + 3 * g + 2 * b);
  return static_cast<int16_t>(static_cast<uint16_t>(a + (low >> 2) - 32768));
}

// Census of a row of centres (census.cc): values[x] for x in [r, end) = the number of the
// (2r+1)^2 - 1 window neighbours whose "darker than the centre" bit (key < centre key) differs
// between the two key images, times inv_bits; `photo_rows` / `rephoto_rows` point to the 2r+1
// key rows of the window (each of width w). end = w - r when the row holds at least one block
// of 32 (AVX2, baseline) or 64 (AVX-512) centres and the window has at most 32767 neighbours,
// else r; returns end (the caller does the rest). The same values on every target.
int CensusValues(const int16_t* const* photo_rows, const int16_t* const* rephoto_rows, int r,
                 int w, float inv_bits, float* values);

// Fills a whole error row with NaN.
void FillNaN(float* row, int width);

}  // namespace rephoto::metrics::internal
