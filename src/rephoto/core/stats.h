// Summary statistics used for every aggregate rephoto reports (per image, fold, dataset).
//
// Thread safety: pure functions.
#pragma once

#include <cstddef>
#include <span>

namespace rephoto {

// Five-number summary plus mean of a set of values. Quantiles interpolate linearly between
// order statistics (numpy's default, "type 7": q at position (n-1)*p of the sorted values),
// the convention of the paper's boxplots (min, Q1, median, Q3, max). NaN values are ignored;
// with no values every field is NaN and count is 0.
struct Summary {
  size_t count = 0;
  double mean = 0;
  double min = 0;
  double q1 = 0;
  double median = 0;
  double q3 = 0;
  double max = 0;
};

Summary Summarize(std::span<const double> values);

// Quantile p in [0,1] of `values` (linear interpolation, NaN ignored; NaN if empty).
double Quantile(std::span<const double> values, double p);

}  // namespace rephoto
