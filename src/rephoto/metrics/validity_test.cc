#include "rephoto/metrics/validity.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/testing/testing.h"

namespace rephoto::metrics {
namespace {

TEST(Validity, PhotoExposureAndUserMask) {
  Image photo(3, 1, 3, 0.5f);
  photo.at(0, 0, 1) = 0.0f;  // dark channel
  photo.at(1, 0, 2) = 1.0f;  // saturated channel
  Mask v = PhotoValidity(photo, {});
  EXPECT_EQ(v.at(0, 0), 0);
  EXPECT_EQ(v.at(1, 0), 0);
  EXPECT_EQ(v.at(2, 0), 1);
  Mask user(3, 1, 1, 1);
  user.at(2, 0) = 0;
  EXPECT_EQ(PhotoValidity(photo, user).at(2, 0), 0);
  ExposureOptions off;
  off.dark_threshold = -1;
  off.saturated_threshold = 2;
  Mask all = PhotoValidity(photo, {}, off);
  EXPECT_EQ(all.at(0, 0) + all.at(1, 0) + all.at(2, 0), 3);
  EXPECT_THROW(PhotoValidity(photo, Mask(2, 1, 1, 1)), Error);
}

TEST(Validity, RephotoAlphaBlackAndExplicit) {
  Image rgb(2, 1, 3, 0.0f);
  rgb.at(1, 0, 2) = 0.1f;
  Mask v = RephotoValidity(rgb);
  EXPECT_EQ(v.at(0, 0), 0);  // pure black
  EXPECT_EQ(v.at(1, 0), 1);
  Image rgba(2, 1, 4, 0.0f);
  rgba.at(0, 0, 3) = 0.5f;  // black but covered
  Mask va = RephotoValidity(rgba);
  EXPECT_EQ(va.at(0, 0), 1);
  EXPECT_EQ(va.at(1, 0), 0);
  Mask explicit_mask(2, 1, 1, 0);
  explicit_mask.at(0, 0) = 255;
  Mask ve = RephotoValidity(rgb, explicit_mask);
  EXPECT_EQ(ve.at(0, 0), 1);
  EXPECT_EQ(ve.at(1, 0), 0);
}

// The 8-bit masks against the rules written out here per sample (SPEC: a photo pixel is valid
// when every colour channel v / 255 lies strictly between the thresholds and the user mask is
// set; a rendering pixel when its alpha is > 0, or without alpha when a channel is not 0), for
// every channel count, thresholds on, between and beyond the 8-bit values, and every value.
TEST(Validity, EightBitMasksFollowTheRuleForEveryValue) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255), coin(0, 3);
  const float thresholds[][2] = {{0.f, 1.f},           {10 / 255.f, 245 / 255.f},
                                 {0.0391f, 0.9609f},  {-1.f, 2.f},
                                 {0.5f, 0.5f},        {254 / 255.f, 2.f},
                                 {NAN, 1.f},          {100 / 255.f, 101 / 255.f}};
  for (int channels = 1; channels <= 4; ++channels) {
    Image8 image(300, 7, channels);
    for (size_t i = 0; i < image.size(); ++i) image.data()[i] = static_cast<uint8_t>(byte(rng));
    // Every value in every channel at least once, and pure black pixels.
    for (int x = 0; x < 256; ++x)
      for (int c = 0; c < channels; ++c) image.at(x, 0, c) = static_cast<uint8_t>(x);
    for (int x = 0; x < 20; ++x)
      for (int c = 0; c < channels; ++c) image.at(x, 1, c) = 0;
    Mask user(300, 7, 1);
    for (size_t i = 0; i < user.size(); ++i) user.data()[i] = coin(rng) == 0 ? 0 : 255;
    const int colour = channels <= 2 ? 1 : 3;
    for (const auto& t : thresholds) {
      ExposureOptions o;
      o.dark_threshold = t[0];
      o.saturated_threshold = t[1];
      for (const Mask* m : std::vector<const Mask*>{nullptr, &user}) {
        const Mask got = PhotoValidity(image, m ? *m : Mask(), o);
        for (int y = 0; y < 7; ++y)
          for (int x = 0; x < 300; ++x) {
            bool ok = m == nullptr || m->at(x, y) != 0;
            for (int c = 0; c < colour; ++c) {
              const float v = static_cast<float>(image.at(x, y, c)) / 255.f;
              if (!(v > o.dark_threshold && v < o.saturated_threshold)) ok = false;
            }
            ASSERT_EQ(got.at(x, y), ok ? 1 : 0)
                << channels << " channels, thresholds " << t[0] << " " << t[1] << " at " << x;
          }
      }
    }
    const Mask got = RephotoValidity(image);
    const bool alpha = channels == 2 || channels == 4;
    for (int y = 0; y < 7; ++y)
      for (int x = 0; x < 300; ++x) {
        bool ok = false;
        if (alpha) {
          ok = image.at(x, y, channels - 1) > 0;
        } else {
          for (int c = 0; c < channels; ++c) ok = ok || image.at(x, y, c) != 0;
        }
        ASSERT_EQ(got.at(x, y), ok ? 1 : 0) << channels << " channels at " << x << "," << y;
      }
  }
}

TEST(Validity, WindowValidityMatchesNaiveLoop) {
  auto rng = testing::MakeRng();
  std::bernoulli_distribution keep(0.97);
  for (int window : {1, 3, 5, 7, 9, 11, 15, 17, 31, 33, 37, 39}) {
    Mask valid(37, 29 + window, 1);
    for (size_t i = 0; i < valid.size(); ++i) valid.data()[i] = keep(rng);
    const Mask got = WindowValidity(valid, window);
    const int r = window / 2;
    for (int y = 0; y < valid.height(); ++y) {
      for (int x = 0; x < valid.width(); ++x) {
        bool expected = x >= r && y >= r && x < valid.width() - r && y < valid.height() - r;
        for (int dy = -r; expected && dy <= r; ++dy) {
          for (int dx = -r; dx <= r; ++dx) expected = expected && valid.at(x + dx, y + dy);
        }
        ASSERT_EQ(got.at(x, y) != 0, expected) << "window " << window << " at " << x << "," << y;
      }
    }
  }
  EXPECT_THROW(WindowValidity(Mask(4, 4, 1, 1), 4), Error);
}

TEST(Validity, Completeness) {
  // 20x10, window 3: photo windows are the 18x8 interior. The rephoto misses column 10, which
  // kills the windows centred on columns 9, 10, 11: 3 * 8 of 144.
  Mask photo(20, 10, 1, 1);
  Mask rephoto(20, 10, 1, 1);
  for (int y = 0; y < 10; ++y) rephoto.at(10, y) = 0;
  const Completeness c = ComputeCompleteness(photo, rephoto, 3);
  EXPECT_EQ(c.valid_photo, 144u);
  EXPECT_EQ(c.valid_both, 120u);
  EXPECT_DOUBLE_EQ(c.value, 120.0 / 144.0);
  EXPECT_DOUBLE_EQ(ComputeCompleteness(photo, photo, 9).value, 1.0);
  EXPECT_TRUE(std::isnan(ComputeCompleteness(Mask(20, 10, 1, 0), rephoto, 3).value));
  EXPECT_DOUBLE_EQ(ComputeCompleteness(photo, rephoto, 1).value, 190.0 / 200.0);
}

}  // namespace
}  // namespace rephoto::metrics
