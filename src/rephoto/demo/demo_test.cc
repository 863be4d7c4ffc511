#include "rephoto/demo/demo.h"

#include <gtest/gtest.h>

#include "rephoto/testing/testing.h"

namespace rephoto::demo {
namespace {

TEST(Demo, SmallDemoRanksGroundTruthFirstAndWritesItsOutputs) {
  DemoOptions options;
  options.out = testing::MakeTempDir() / "demo";
  options.scene.image_width = 240;
  options.scene.image_height = 180;
  options.scene.camera_count = 4;
  options.scene.ground_cells = 120;
  options.scene.object_bands = 60;
  options.photo_samples_per_pixel = 4;
  options.metrics = {metrics::Metric::kOneMinusNcc, metrics::Metric::kCbCr};
  const DemoResult result = RunDemo(options);
  ASSERT_EQ(result.ranking.size(), 5u);
  EXPECT_EQ(result.ranking.front().name, "ground_truth");
  for (const auto& r : result.ranking) {
    EXPECT_EQ(r.result.images.size(), 4u) << r.name;
    EXPECT_TRUE(r.result.missing.empty());
    EXPECT_TRUE(std::filesystem::exists(r.model));
  }
  // The ground truth covers everything the photos show.
  EXPECT_GT(result.ranking.front().result.completeness.median, 0.99);
  EXPECT_TRUE(std::filesystem::exists(options.out / "ranking.csv"));
  EXPECT_TRUE(std::filesystem::exists(options.out / "demo.json"));
  EXPECT_TRUE(std::filesystem::exists(options.out / "scene" / "sparse" / "cameras.txt"));
}

}  // namespace
}  // namespace rephoto::demo
