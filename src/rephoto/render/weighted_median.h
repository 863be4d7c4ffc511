// Weighted median of (value, weight) pairs, shared by the colour fusion of colorize.h (per
// vertex) and of the image-based renderers in rephoto/ibr (per pixel).
//
// Thread safety: pure function (sorts only the span it is given).
#pragma once

#include <algorithm>
#include <span>
#include <utility>

namespace rephoto::render {

// The smallest value whose cumulative weight (values in ascending order) reaches half the
// total weight: the lower weighted median. Weights must be >= 0 with a positive total; with all
// weights equal it is the lower median. `pairs` (value, weight) is reordered; it must not be
// empty. Allocates nothing (callers pass small stack arrays or reused vectors).
inline float WeightedMedian(std::span<std::pair<float, float>> pairs) {
  std::sort(pairs.begin(), pairs.end());
  double total = 0;
  for (const auto& p : pairs) total += p.second;
  double cumulative = 0;
  for (const auto& p : pairs) {
    cumulative += p.second;
    if (cumulative >= 0.5 * total) return p.first;
  }
  return pairs.back().first;
}

}  // namespace rephoto::render
