#include "rephoto/core/colormap.h"

#include <gtest/gtest.h>

#include <cmath>

namespace rephoto {
namespace {

TEST(Colormap, JetMatchesMatlabKeyColours) {
  // MATLAB jet(N) endpoints: 0 -> (0,0,0.5), 0.5 -> (0.5,1,0.5) region, 1 -> (0.5,0,0).
  auto c0 = JetColor(0.f);
  EXPECT_FLOAT_EQ(c0[0], 0.f);
  EXPECT_FLOAT_EQ(c0[1], 0.f);
  EXPECT_FLOAT_EQ(c0[2], 0.5f);
  auto c1 = JetColor(1.f);
  EXPECT_FLOAT_EQ(c1[0], 0.5f);
  EXPECT_FLOAT_EQ(c1[1], 0.f);
  EXPECT_FLOAT_EQ(c1[2], 0.f);
  auto half = JetColor(0.5f);
  EXPECT_FLOAT_EQ(half[0], 0.5f);
  EXPECT_FLOAT_EQ(half[1], 1.f);
  EXPECT_FLOAT_EQ(half[2], 0.5f);
  auto quarter = JetColor(0.25f);  // cyan-ish blue: (0, 0.5, 1)
  EXPECT_FLOAT_EQ(quarter[0], 0.f);
  EXPECT_FLOAT_EQ(quarter[1], 0.5f);
  EXPECT_FLOAT_EQ(quarter[2], 1.f);
}

TEST(Colormap, NanIsTransparent) {
  Image values(2, 1, 1);
  values.at(0, 0) = NAN;
  values.at(1, 0) = 1.f;
  Image rgba = ApplyJet(values, 0.f, 1.f);
  EXPECT_EQ(rgba.channels(), 4);
  EXPECT_FLOAT_EQ(rgba.at(0, 0, 3), 0.f);
  EXPECT_FLOAT_EQ(rgba.at(1, 0, 3), 1.f);
  EXPECT_FLOAT_EQ(rgba.at(1, 0, 0), 0.5f);
}

}  // namespace
}  // namespace rephoto
