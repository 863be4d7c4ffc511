#include "rephoto/compare/compat_compare.h"

#include <gtest/gtest.h>

#include <cmath>

#include "rephoto/core/error.h"

namespace rephoto::compare {
namespace {

TEST(CompatCompareTest, CompositesThePhotoDropsRenderAlphaAndCountsEveryPixel) {
  // Photo: RGBA, fully transparent red; over a white background it is white. Rendering: white
  // RGB with alpha 0 everywhere, which --compat ignores (the scripts drop it), so the images
  // are identical under compositing with white and differ with black.
  Image photo(12, 10, 4), render(12, 10, 4);
  for (size_t i = 0; i < photo.pixel_count(); ++i) {
    photo.data()[4 * i] = 1, photo.data()[4 * i + 1] = 0, photo.data()[4 * i + 2] = 0;
    photo.data()[4 * i + 3] = 0;
    for (int c = 0; c < 3; ++c) render.data()[4 * i + c] = 1;
    render.data()[4 * i + 3] = 0;
  }
  CompareOptions options;
  options.metrics = {metrics::Metric::kSsim, metrics::Metric::kPsnr};
  options.compat_background = {1, 1, 1};
  const ImageResult white =
      CompareCompat(options, metrics::CompatPreset::k3dgs, "a", "p.png", "r.png", photo, render);
  ASSERT_EQ(white.metrics.size(), 2u);
  EXPECT_NEAR(white.metrics[0].mean, 1.0, 1e-12);
  EXPECT_TRUE(std::isinf(white.metrics[1].mean));
  EXPECT_EQ(white.metrics[0].evaluated, 120u);
  EXPECT_EQ(white.completeness.valid_both, 0u);  // reported, but not used by the metrics
  options.compat_background = {0, 0, 0};
  const ImageResult black = CompareCompat(options, metrics::CompatPreset::kNerfstudio, "a", "p.png",
                                          "r.png", photo, render);
  EXPECT_NEAR(black.metrics[1].mean, 0.0, 1e-12);  // MSE 1: PSNR 0 dB
}

TEST(CompatCompareTest, RejectsOtherMetricsAndSizeMismatches) {
  CompareOptions options;
  options.metrics = {metrics::Metric::kOneMinusNcc};
  EXPECT_THROW(CompareCompat(options, metrics::CompatPreset::k3dgs, "a", "p", "r", Image(8, 8, 3),
                             Image(8, 8, 3)),
               UsageError);
  options.metrics = {metrics::Metric::kPsnr};
  try {
    CompareCompat(options, metrics::CompatPreset::k3dgs, "a", "p.png", "r.png", Image(8, 8, 3),
                  Image(9, 8, 3));
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "r.png: rendering is 9x8 but its photo p.png is 8x8");
  }
}

}  // namespace
}  // namespace rephoto::compare
