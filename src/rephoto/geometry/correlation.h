// Correlation coefficients between two equally long series (e.g. per-run 1-NCC and geometric
// accuracy, as the paper's Fig. 8).
// Pairs where either value is NaN are dropped first. Both return NaN when fewer than 2 pairs
// remain or when a series is constant (the coefficient is undefined). Sums in double, in index
// order. Thread safety: pure functions.
#pragma once

#include <span>

namespace rephoto::geometry {

// Pearson's r = sum (x - mean x)(y - mean y) / sqrt(sum (x - mean x)^2 sum (y - mean y)^2),
// in [-1, 1]. Throws Error when the sizes differ.
double Pearson(std::span<const double> x, std::span<const double> y);

// Spearman's rho: Pearson's r of the ranks (1-based; tied values get the mean of their ranks),
// in [-1, 1]. Throws Error when the sizes differ.
double Spearman(std::span<const double> x, std::span<const double> y);

}  // namespace rephoto::geometry
