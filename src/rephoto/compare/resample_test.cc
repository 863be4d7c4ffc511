#include "rephoto/compare/resample.h"

#include <gtest/gtest.h>

#include <random>

#include "rephoto/core/error.h"
#include "rephoto/testing/testing.h"

namespace rephoto::compare {
namespace {

Image Row(std::vector<float> values) {
  Image image(static_cast<int>(values.size()), 1, 1);
  for (size_t i = 0; i < values.size(); ++i) image.data()[i] = values[i];
  return image;
}

TEST(Resample, SameSizeIsACopy) {
  auto rng = testing::MakeRng();
  std::uniform_real_distribution<float> value(0.f, 1.f);
  Image image(7, 5, 3);
  for (size_t i = 0; i < image.size(); ++i) image.data()[i] = value(rng);
  Image out;
  ResizeImage(image, 7, 5, &out);
  ASSERT_EQ(out.size(), image.size());
  for (size_t i = 0; i < image.size(); ++i) EXPECT_EQ(out.data()[i], image.data()[i]);
}

TEST(Resample, HalvingAveragesTwoByTwoBlocks) {
  Image image(4, 2, 1);
  const float values[8] = {1, 2, 3, 4, 5, 6, 7, 8};
  for (int i = 0; i < 8; ++i) image.data()[i] = values[i];
  Image out;
  ResizeImage(image, 2, 1, &out);
  EXPECT_FLOAT_EQ(out.at(0, 0), (1 + 2 + 5 + 6) / 4.f);
  EXPECT_FLOAT_EQ(out.at(1, 0), (3 + 4 + 7 + 8) / 4.f);
}

TEST(Resample, FractionalShrinkWeighsCoveredArea) {
  // 3 -> 2: output footprints [0, 1.5) and [1.5, 3) in source pixels.
  Image out;
  ResizeImage(Row({3, 6, 12}), 2, 1, &out);
  EXPECT_FLOAT_EQ(out.at(0, 0), (3 * 1.0f + 6 * 0.5f) / 1.5f);
  EXPECT_FLOAT_EQ(out.at(1, 0), (6 * 0.5f + 12 * 1.0f) / 1.5f);
}

TEST(Resample, EnlargingIsBilinearBetweenPixelCentres) {
  // 2 -> 4: output centres at source x = -0.25, 0.25, 0.75, 1.25 (clamped at the borders).
  Image out;
  ResizeImage(Row({2, 10}), 4, 1, &out);
  EXPECT_FLOAT_EQ(out.at(0, 0), 2);
  EXPECT_FLOAT_EQ(out.at(1, 0), 0.75f * 2 + 0.25f * 10);
  EXPECT_FLOAT_EQ(out.at(2, 0), 0.25f * 2 + 0.75f * 10);
  EXPECT_FLOAT_EQ(out.at(3, 0), 10);
}

TEST(Resample, ConstantStaysConstantAndMeanIsKeptByAreaShrink) {
  auto rng = testing::MakeRng();
  std::uniform_real_distribution<float> value(0.f, 1.f);
  for (auto [w, h] : {std::pair{13, 9}, std::pair{5, 17}, std::pair{40, 3}}) {
    Image constant(w, h, 3, 0.3f);
    Image out;
    ResizeImage(constant, 11, 7, &out);
    for (size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(out.data()[i], 0.3f, 1e-6f);
  }
  Image image(12, 9, 1);
  double sum = 0;
  for (size_t i = 0; i < image.size(); ++i) sum += image.data()[i] = value(rng);
  Image out;
  ResizeImage(image, 4, 3, &out);  // exact factor 3: every source pixel counts once
  double out_sum = 0;
  for (size_t i = 0; i < out.size(); ++i) out_sum += out.data()[i];
  EXPECT_NEAR(out_sum / out.size(), sum / image.size(), 1e-6);
}

TEST(Resample, MaskIsConservative) {
  Mask mask(4, 4, 1, 1);
  mask.at(3, 0) = 0;
  Mask out;
  ResizeMask(mask, 2, 2, &out);
  EXPECT_EQ(out.at(0, 0), 1);
  EXPECT_EQ(out.at(1, 0), 0);  // covers the invalid pixel
  EXPECT_EQ(out.at(0, 1), 1);
  EXPECT_EQ(out.at(1, 1), 1);
  // 3 -> 2 with the middle pixel invalid: both footprints touch it.
  Mask row(3, 1, 1, 1);
  row.at(1, 0) = 0;
  ResizeMask(row, 2, 1, &out);
  EXPECT_EQ(out.at(0, 0), 0);
  EXPECT_EQ(out.at(1, 0), 0);
  // Enlarging 2 -> 4 with pixel 1 invalid: outputs 1-3 interpolate from it, output 0 does not.
  Mask two(2, 1, 1, 1);
  two.at(1, 0) = 0;
  ResizeMask(two, 4, 1, &out);
  EXPECT_EQ(out.at(0, 0), 1);
  EXPECT_EQ(out.at(1, 0), 0);
  EXPECT_EQ(out.at(3, 0), 0);
}

TEST(Resample, BadTargetSizeThrows) {
  Image out;
  EXPECT_THROW(ResizeImage(Image(2, 2, 1), 0, 2, &out), Error);
}

}  // namespace
}  // namespace rephoto::compare
