#include "rephoto/core/stats.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace rephoto {
namespace {

TEST(Stats, FiveNumberSummaryMatchesNumpyLinearQuantiles) {
  // numpy.percentile([4, 1, 3, 2, 10], [0, 25, 50, 75, 100]) = [1, 2, 3, 4, 10].
  const std::vector<double> values = {4, 1, 3, 2, 10};
  const Summary s = Summarize(values);
  EXPECT_EQ(s.count, 5u);
  EXPECT_DOUBLE_EQ(s.mean, 4.0);
  EXPECT_DOUBLE_EQ(s.min, 1);
  EXPECT_DOUBLE_EQ(s.q1, 2);
  EXPECT_DOUBLE_EQ(s.median, 3);
  EXPECT_DOUBLE_EQ(s.q3, 4);
  EXPECT_DOUBLE_EQ(s.max, 10);
}

TEST(Stats, QuantileInterpolatesBetweenOrderStatistics) {
  // numpy.percentile([1, 2, 3, 4], 25) = 1.75; 97.5 -> 3.925.
  const std::vector<double> values = {1, 2, 3, 4};
  EXPECT_DOUBLE_EQ(Quantile(values, 0.25), 1.75);
  EXPECT_NEAR(Quantile(values, 0.975), 3.925, 1e-12);
}

TEST(Stats, QuantileBySelectionEqualsTheSortedDefinition) {
  // Quantile selects (nth_element) instead of sorting: the result must be bit-identical to the
  // textbook definition on the sorted finite values, with ties, NaN and every p.
  std::vector<double> values;
  uint32_t state = 12345;
  for (int i = 0; i < 1001; ++i) {
    state = state * 1664525u + 1013904223u;
    values.push_back(i % 97 == 0 ? NAN : static_cast<double>(state >> 20) / 7.0);
  }
  values.push_back(values[3]);  // a tie
  std::vector<double> sorted;
  for (double v : values) {
    if (!std::isnan(v)) sorted.push_back(v);
  }
  std::sort(sorted.begin(), sorted.end());
  for (double p : {0.0, 0.025, 0.1, 0.25, 0.5, 0.75, 0.9, 0.975, 0.999, 1.0}) {
    const double position = p * static_cast<double>(sorted.size() - 1);
    const size_t below = static_cast<size_t>(std::floor(position));
    const size_t above = std::min(below + 1, sorted.size() - 1);
    const double t = position - static_cast<double>(below);
    const double expected = sorted[below] + t * (sorted[above] - sorted[below]);
    EXPECT_EQ(Quantile(values, p), expected) << p;
  }
}

TEST(Stats, NanIsIgnoredAndEmptyGivesNan) {
  const std::vector<double> values = {NAN, 2, NAN};
  EXPECT_DOUBLE_EQ(Summarize(values).median, 2);
  EXPECT_EQ(Summarize(values).count, 1u);
  EXPECT_TRUE(std::isnan(Summarize(std::vector<double>{}).mean));
}

}  // namespace
}  // namespace rephoto
