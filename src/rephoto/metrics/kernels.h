// Internal helpers shared by the metric kernels (not part of the public API).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "rephoto/core/image.h"

// Row kernels are compiled twice, for AVX2+FMA (x86-64-v3) and for the baseline, and the
// loader picks one at start-up. Floating-point contraction stays off (ISO C++ mode), so both
// clones compute bit-identical results.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define REPHOTO_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define REPHOTO_SIMD_CLONES
#endif

namespace rephoto::metrics::internal {

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

// Produces, for consecutive centre rows y, the row of window validity: out[x] = 1 where the
// (2r+1)^2 window centred at (x, y) is inside the image and all valid. `valid` may be empty
// (everything valid). Column counts slide from row to row, so the cost is O(width) per row.
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
};

// Normalised 1-D weights of length 2r+1: Gaussian exp(-k^2 / (2 sigma^2)), or uniform if
// sigma <= 0.
std::vector<float> FilterWeights(int radius, double sigma);

// Fills a whole error row with NaN.
void FillNaN(float* row, int width);

}  // namespace rephoto::metrics::internal
