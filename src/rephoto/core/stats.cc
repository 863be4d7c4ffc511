#include "rephoto/core/stats.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace rephoto {
namespace {

std::vector<double> NotNan(std::span<const double> values) {
  std::vector<double> kept;
  kept.reserve(values.size());
  for (double v : values) {
    if (!std::isnan(v)) kept.push_back(v);
  }
  return kept;
}

std::vector<double> SortedFinite(std::span<const double> values) {
  std::vector<double> sorted = NotNan(values);
  std::sort(sorted.begin(), sorted.end());
  return sorted;
}

// Quantile p of n > 0 sorted values: between the values of ranks `below` and `above`, at t.
struct QuantilePosition {
  size_t below, above;
  double t;
};
QuantilePosition PositionOf(size_t n, double p) {
  const double position = p * static_cast<double>(n - 1);
  const size_t below = static_cast<size_t>(std::floor(position));
  return {below, std::min(below + 1, n - 1), position - static_cast<double>(below)};
}

double SortedQuantile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto [below, above, t] = PositionOf(sorted.size(), p);
  return sorted[below] + t * (sorted[above] - sorted[below]);
}

}  // namespace

double Quantile(std::span<const double> values, double p) {
  // The same value as SortedQuantile on the sorted values, by selection (O(n), no full sort):
  // the element of rank `below` and the smallest one after it.
  std::vector<double> finite = NotNan(values);
  if (finite.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto [below, above, t] = PositionOf(finite.size(), p);
  const auto nth = finite.begin() + static_cast<std::ptrdiff_t>(below);
  std::nth_element(finite.begin(), nth, finite.end());
  const double low = *nth;
  const double high = above > below ? *std::min_element(nth + 1, finite.end()) : low;
  return low + t * (high - low);
}

Summary Summarize(std::span<const double> values) {
  const std::vector<double> sorted = SortedFinite(values);
  Summary s;
  s.count = sorted.size();
  if (sorted.empty()) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    s.mean = s.min = s.q1 = s.median = s.q3 = s.max = nan;
    return s;
  }
  double sum = 0;
  for (double v : sorted) sum += v;
  s.mean = sum / static_cast<double>(sorted.size());
  s.min = sorted.front();
  s.q1 = SortedQuantile(sorted, 0.25);
  s.median = SortedQuantile(sorted, 0.5);
  s.q3 = SortedQuantile(sorted, 0.75);
  s.max = sorted.back();
  return s;
}

}  // namespace rephoto
