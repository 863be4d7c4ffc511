#include "rephoto/sweep/grid.h"

#include <gtest/gtest.h>

#include <cmath>

#include "rephoto/core/error.h"

namespace rephoto::sweep {
namespace {

TEST(SweepGrid, CartesianProductLastAxisFastest) {
  const std::vector<SweepAxis> axes = {{"train_count", {8, 4, 2}},
                                       {"train_short_side", {960, 480}}};
  CheckAxes(axes, "test");
  const auto settings = ExpandGrid(axes);
  ASSERT_EQ(settings.size(), 6u);
  EXPECT_EQ(settings[0].name, "train_count-8_train_short_side-960");
  EXPECT_EQ(settings[1].name, "train_count-8_train_short_side-480");
  EXPECT_EQ(settings[2].name, "train_count-4_train_short_side-960");
  EXPECT_EQ(settings[5].name, "train_count-2_train_short_side-480");
  EXPECT_EQ(settings[3].Value("train_count"), 4);
  EXPECT_EQ(settings[3].Value("train_short_side"), 480);
  EXPECT_TRUE(std::isnan(settings[3].Value("seed")));
}

TEST(SweepGrid, NoAxesIsOneBaseSettingAndNamesUseShortNumbers) {
  const auto base = ExpandGrid({});
  ASSERT_EQ(base.size(), 1u);
  EXPECT_EQ(base[0].name, "base");
  EXPECT_EQ(ExpandGrid({{"texture_noise", {0.1, 0.25}}})[1].name, "texture_noise-0.25");
}

TEST(SweepGrid, HalvingSeriesFollowsThePaper) {
  // Section 4.2 halves |T| repeatedly from the full training set.
  EXPECT_EQ(HalvingSeries(561, 30), (std::vector<double>{561, 280, 140, 70, 35}));
  EXPECT_EQ(HalvingSeries(10, 2), (std::vector<double>{10, 5, 2}));
  EXPECT_EQ(HalvingSeries(1, 1), (std::vector<double>{1}));
  EXPECT_THROW(HalvingSeries(3, 4), Error);
  EXPECT_THROW(HalvingSeries(3, 0), Error);
}

TEST(SweepGrid, BadAxesAreErrorsNamingTheProblem) {
  auto message = [](const std::vector<SweepAxis>& axes) {
    try {
      CheckAxes(axes, "exp.toml");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message({{"blur", {1}}}).find("unknown sweep parameter 'blur'"), std::string::npos);
  EXPECT_NE(message({{"seed", {1}}, {"seed", {2}}}).find("given twice"), std::string::npos);
  EXPECT_NE(message({{"seed", {}}}).find("has no values"), std::string::npos);
  EXPECT_NE(message({{"simplify", {1.0}}}).find("below 1"), std::string::npos);
  EXPECT_NE(message({{"train_count", {2.5}}}).find("whole number"), std::string::npos);
  EXPECT_NE(message({{"texture_noise", {-0.1}}}).find(">= 0"), std::string::npos);
  EXPECT_EQ(message({{"texture_noise", {0, 0.1}}}), "");
}

}  // namespace
}  // namespace rephoto::sweep
