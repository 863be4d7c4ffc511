#include "rephoto/core/stats.h"

#include <gtest/gtest.h>

#include <cmath>
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

TEST(Stats, NanIsIgnoredAndEmptyGivesNan) {
  const std::vector<double> values = {NAN, 2, NAN};
  EXPECT_DOUBLE_EQ(Summarize(values).median, 2);
  EXPECT_EQ(Summarize(values).count, 1u);
  EXPECT_TRUE(std::isnan(Summarize(std::vector<double>{}).mean));
}

}  // namespace
}  // namespace rephoto
