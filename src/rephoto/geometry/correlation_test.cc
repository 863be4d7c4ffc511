#include "rephoto/geometry/correlation.h"

#include <cmath>
#include <limits>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/testing/testing.h"

namespace rephoto::geometry {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

// x = 1..5, y = 2 4 5 4 5. Means 3 and 4; deviations dx = -2 -1 0 1 2, dy = -2 0 1 0 1;
// sum dx dy = 4 + 0 + 0 + 0 + 2 = 6, sum dx^2 = 10, sum dy^2 = 6: r = 6 / sqrt(60).
TEST(CorrelationTest, PearsonByHand) {
  const std::vector<double> x = {1, 2, 3, 4, 5}, y = {2, 4, 5, 4, 5};
  EXPECT_NEAR(Pearson(x, y), 6.0 / std::sqrt(60.0), 1e-12);
  EXPECT_NEAR(Pearson(y, x), 6.0 / std::sqrt(60.0), 1e-12);
}

// Ranks of y = 2 4 5 4 5: 1, (2+3)/2 = 2.5, (4+5)/2 = 4.5, 2.5, 4.5 (mean 3); deviations
// -2 -0.5 1.5 -0.5 1.5; sum dx dr = 4 + 0.5 + 0 - 0.5 + 3 = 7, sum dr^2 = 9, sum dx^2 = 10:
// rho = 7 / sqrt(90).
TEST(CorrelationTest, SpearmanWithTiesByHand) {
  const std::vector<double> x = {1, 2, 3, 4, 5}, y = {2, 4, 5, 4, 5};
  EXPECT_NEAR(Spearman(x, y), 7.0 / std::sqrt(90.0), 1e-12);
}

// A monotone but non-linear relation: Spearman 1, Pearson below 1. y = x^3 for x = 1 2 3:
// means 2 and 12, dy = -11 -4 15, sum dx dy = 26, sum dy^2 = 362: r = 26 / sqrt(2 * 362).
TEST(CorrelationTest, MonotoneNonLinear) {
  const std::vector<double> x = {1, 2, 3}, y = {1, 8, 27};
  EXPECT_DOUBLE_EQ(Spearman(x, y), 1.0);
  EXPECT_NEAR(Pearson(x, y), 26.0 / std::sqrt(724.0), 1e-12);
  const std::vector<double> reversed = {27, 8, 1};
  EXPECT_DOUBLE_EQ(Spearman(x, reversed), -1.0);
}

TEST(CorrelationTest, NanPairsDroppedAndUndefinedCases) {
  const std::vector<double> x = {1, kNan, 2, 3, 4, 5}, y = {2, 100, 4, 5, 4, 5};
  EXPECT_NEAR(Pearson(x, y), 6.0 / std::sqrt(60.0), 1e-12);
  const std::vector<double> one = {1}, constant = {2, 2, 2}, three = {1, 2, 3};
  EXPECT_TRUE(std::isnan(Pearson(one, one)));
  EXPECT_TRUE(std::isnan(Pearson(constant, three)));
  EXPECT_TRUE(std::isnan(Spearman(three, constant)));
  EXPECT_THROW(Pearson(one, three), Error);
}

}  // namespace
}  // namespace rephoto::geometry
