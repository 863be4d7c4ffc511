#include "rephoto/metrics/kernels.h"

#include <algorithm>
#include <cmath>

namespace rephoto::metrics::internal {

WindowValidityRows::WindowValidityRows(const Mask& valid, int width, int height, int radius)
    : valid_(valid),
      width_(width),
      height_(height),
      radius_(radius),
      column_invalid_(valid.empty() ? 0 : static_cast<size_t>(width), 0),
      row_(static_cast<size_t>(width), 0) {
  if (valid_.empty()) {
    std::fill(row_.begin() + std::min(radius, width),
              row_.begin() + std::max(std::min(radius, width), width - radius), 1);
  }
}

const uint8_t* WindowValidityRows::Row(int y) {
  if (valid_.empty()) return row_.data();
  const int r = radius_;
  if (y == last_y_ + 1) {
    const uint8_t* add = valid_.row(y + r);
    const uint8_t* sub = valid_.row(y - r - 1);
    for (int x = 0; x < width_; ++x) column_invalid_[x] += (add[x] == 0) - (sub[x] == 0);
  } else {
    std::fill(column_invalid_.begin(), column_invalid_.end(), 0);
    for (int j = y - r; j <= y + r; ++j) {
      const uint8_t* row = valid_.row(j);
      for (int x = 0; x < width_; ++x) column_invalid_[x] += row[x] == 0;
    }
  }
  last_y_ = y;
  if (width_ < 2 * r + 1) return row_.data();
  int run = 0;
  for (int x = 0; x < 2 * r + 1; ++x) run += column_invalid_[x];
  row_[r] = run == 0;
  for (int x = r + 1; x < width_ - r; ++x) {
    run += column_invalid_[x + r] - column_invalid_[x - r - 1];
    row_[x] = run == 0;
  }
  return row_.data();
}

std::vector<float> FilterWeights(int radius, double sigma) {
  std::vector<double> w(static_cast<size_t>(2 * radius + 1));
  double total = 0;
  for (int k = -radius; k <= radius; ++k) {
    const double v = sigma > 0 ? std::exp(-0.5 * k * k / (sigma * sigma)) : 1.0;
    w[k + radius] = v;
    total += v;
  }
  std::vector<float> out(w.size());
  for (size_t i = 0; i < w.size(); ++i) out[i] = static_cast<float>(w[i] / total);
  return out;
}

void FillNaN(float* row, int width) { std::fill(row, row + width, kNaN); }

}  // namespace rephoto::metrics::internal
