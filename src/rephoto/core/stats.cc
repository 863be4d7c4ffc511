#include "rephoto/core/stats.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace rephoto {
namespace {

std::vector<double> SortedFinite(std::span<const double> values) {
  std::vector<double> sorted;
  sorted.reserve(values.size());
  for (double v : values) {
    if (!std::isnan(v)) sorted.push_back(v);
  }
  std::sort(sorted.begin(), sorted.end());
  return sorted;
}

double SortedQuantile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return std::numeric_limits<double>::quiet_NaN();
  const double position = p * static_cast<double>(sorted.size() - 1);
  const size_t below = static_cast<size_t>(std::floor(position));
  const size_t above = std::min(below + 1, sorted.size() - 1);
  const double t = position - static_cast<double>(below);
  return sorted[below] + t * (sorted[above] - sorted[below]);
}

}  // namespace

double Quantile(std::span<const double> values, double p) {
  // The same value as SortedQuantile on the sorted values, by selection (O(n), no full sort):
  // the element of rank `below` and the smallest one after it.
  std::vector<double> finite;
  finite.reserve(values.size());
  for (double v : values) {
    if (!std::isnan(v)) finite.push_back(v);
  }
  if (finite.empty()) return std::numeric_limits<double>::quiet_NaN();
  const double position = p * static_cast<double>(finite.size() - 1);
  const size_t below = static_cast<size_t>(std::floor(position));
  const size_t above = std::min(below + 1, finite.size() - 1);
  const double t = position - static_cast<double>(below);
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
