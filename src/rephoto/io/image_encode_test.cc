#include "rephoto/io/image_encode.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "rephoto/core/error.h"
#include "rephoto/io/image_io.h"
#include "rephoto/testing/testing.h"

namespace rephoto::io {
namespace {

std::vector<uint8_t> RandomPixels(size_t count, std::mt19937_64& rng) {
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<uint8_t> pixels(count);
  for (uint8_t& p : pixels) p = static_cast<uint8_t>(byte(rng));
  return pixels;
}

TEST(EncodePngToMemory, RoundTripsEveryChannelCountExactly) {
  std::mt19937_64 rng = testing::MakeRng();
  for (int channels = 1; channels <= 4; ++channels) {
    const int width = 13, height = 7;
    const std::vector<uint8_t> pixels = RandomPixels(width * height * channels, rng);
    const std::vector<uint8_t> png = EncodePngToMemory(pixels, width, height, channels);
    ASSERT_GT(png.size(), 8u);
    EXPECT_EQ(png[1], 'P');
    Image decoded;
    DecodeImage(png, "memory.png", &decoded);
    ASSERT_EQ(decoded.width(), width);
    ASSERT_EQ(decoded.height(), height);
    ASSERT_EQ(decoded.channels(), channels);
    for (size_t i = 0; i < pixels.size(); ++i) {
      ASSERT_EQ(std::lround(decoded.data()[i] * 255.f), pixels[i]) << "channels " << channels;
    }
  }
}

TEST(EncodeJpegToMemory, DecodesCloseToTheInput) {
  // A smooth gradient survives JPEG at quality 95 within a few levels.
  const int width = 32, height = 24;
  std::vector<uint8_t> rgb(width * height * 3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      uint8_t* p = &rgb[(y * width + x) * 3];
      p[0] = static_cast<uint8_t>(x * 8);
      p[1] = static_cast<uint8_t>(y * 10);
      p[2] = 128;
    }
  }
  const std::vector<uint8_t> jpeg = EncodeJpegToMemory(rgb, width, height, 3, 95);
  ASSERT_GT(jpeg.size(), 2u);
  EXPECT_EQ(jpeg[0], 0xFF);
  EXPECT_EQ(jpeg[1], 0xD8);
  Image decoded;
  DecodeImage(jpeg, "memory.jpg", &decoded);
  ASSERT_EQ(decoded.width(), width);
  ASSERT_EQ(decoded.height(), height);
  ASSERT_EQ(decoded.channels(), 3);
  double max_difference = 0;
  for (size_t i = 0; i < rgb.size(); ++i) {
    max_difference = std::max(max_difference, std::abs(decoded.data()[i] * 255.0 - rgb[i]));
  }
  EXPECT_LE(max_difference, 8.0);

  const std::vector<uint8_t> grey(width * height, 77);
  DecodeImage(EncodeJpegToMemory(grey, width, height, 1), "grey.jpg", &decoded);
  ASSERT_EQ(decoded.channels(), 1);
  EXPECT_NEAR(decoded.at(5, 5) * 255.f, 77.f, 1.f);
}

TEST(EncodeToMemory, RejectsBadInput) {
  const std::vector<uint8_t> pixels(12, 0);
  EXPECT_THROW(EncodePngToMemory(pixels, 2, 2, 5), Error);
  EXPECT_THROW(EncodePngToMemory(pixels, 0, 2, 3), Error);
  EXPECT_THROW(EncodePngToMemory(pixels, 3, 3, 3), Error);  // 27 bytes needed
  EXPECT_THROW(EncodeJpegToMemory(pixels, 2, 2, 4), Error);
  EXPECT_THROW(EncodeJpegToMemory(pixels, 2, 2, 3, 0), Error);
  try {
    EncodePngToMemory(pixels, 3, 3, 3, "thumb.png");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("thumb.png"), std::string::npos);
  }
}

}  // namespace
}  // namespace rephoto::io
