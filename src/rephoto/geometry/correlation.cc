#include "rephoto/geometry/correlation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "rephoto/core/error.h"

namespace rephoto::geometry {
namespace {

void DropNan(std::span<const double> x, std::span<const double> y, std::vector<double>* fx,
             std::vector<double>* fy) {
  REPHOTO_CHECK(x.size() == y.size(), "correlation of series of different lengths ({} and {})",
                x.size(), y.size());
  for (size_t i = 0; i < x.size(); ++i) {
    if (std::isnan(x[i]) || std::isnan(y[i])) continue;
    fx->push_back(x[i]);
    fy->push_back(y[i]);
  }
}

double PearsonOfFinite(const std::vector<double>& x, const std::vector<double>& y) {
  const size_t n = x.size();
  if (n < 2) return std::numeric_limits<double>::quiet_NaN();
  double mx = 0, my = 0;
  for (size_t i = 0; i < n; ++i) {
    mx += x[i];
    my += y[i];
  }
  mx /= static_cast<double>(n);
  my /= static_cast<double>(n);
  double sxy = 0, sxx = 0, syy = 0;
  for (size_t i = 0; i < n; ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  if (!(sxx > 0) || !(syy > 0)) return std::numeric_limits<double>::quiet_NaN();
  return std::clamp(sxy / std::sqrt(sxx * syy), -1.0, 1.0);
}

std::vector<double> Ranks(const std::vector<double>& values) {
  std::vector<size_t> order(values.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return values[a] < values[b]; });
  std::vector<double> ranks(values.size());
  for (size_t i = 0; i < order.size();) {
    size_t j = i + 1;
    while (j < order.size() && values[order[j]] == values[order[i]]) ++j;
    // Positions i..j-1 (0-based) hold ranks i+1..j: their mean.
    const double mean_rank = 0.5 * static_cast<double>(i + 1 + j);
    for (size_t k = i; k < j; ++k) ranks[order[k]] = mean_rank;
    i = j;
  }
  return ranks;
}

}  // namespace

double Pearson(std::span<const double> x, std::span<const double> y) {
  std::vector<double> fx, fy;
  DropNan(x, y, &fx, &fy);
  return PearsonOfFinite(fx, fy);
}

double Spearman(std::span<const double> x, std::span<const double> y) {
  std::vector<double> fx, fy;
  DropNan(x, y, &fx, &fy);
  return PearsonOfFinite(Ranks(fx), Ranks(fy));
}

}  // namespace rephoto::geometry
