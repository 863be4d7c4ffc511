#include "rephoto/io/image_encode.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
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

uint32_t Big32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3];
}

// Decodes a PNG written by EncodePng with zlib (an implementation independent of libdeflate and
// of libspng): every chunk's CRC-32 is checked, the IHDR fields returned, the IDAT stream
// inflated and the rows unfiltered (types 0 and 2, the ones EncodePng writes).
std::vector<uint8_t> ZlibDecode(const std::vector<uint8_t>& png, uint32_t* width, uint32_t* height,
                                int* depth, int* color_type) {
  const uint8_t signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  EXPECT_EQ(std::memcmp(png.data(), signature, 8), 0);
  std::vector<uint8_t> idat;
  size_t pos = 8;
  bool end = false;
  while (pos + 12 <= png.size()) {
    const uint32_t size = Big32(&png[pos]);
    const std::string type(reinterpret_cast<const char*>(&png[pos + 4]), 4);
    const uint8_t* body = &png[pos + 8];
    EXPECT_EQ(crc32(0, &png[pos + 4], size + 4), Big32(body + size)) << type;
    if (type == "IHDR") {
      *width = Big32(body);
      *height = Big32(body + 4);
      *depth = body[8];
      *color_type = body[9];
    } else if (type == "IDAT") {
      idat.insert(idat.end(), body, body + size);
    } else if (type == "IEND") {
      end = true;
    }
    pos += 12 + size;
  }
  EXPECT_TRUE(end);
  EXPECT_EQ(pos, png.size());
  const int channels[7] = {1, 0, 3, 0, 2, 0, 4};
  const size_t stride = size_t{*width} * channels[*color_type] * (*depth / 8);
  std::vector<uint8_t> raw((stride + 1) * *height);
  uLongf raw_size = raw.size();
  EXPECT_EQ(uncompress(raw.data(), &raw_size, idat.data(), idat.size()), Z_OK);
  EXPECT_EQ(raw_size, raw.size());
  std::vector<uint8_t> pixels(stride * *height);
  for (uint32_t y = 0; y < *height; ++y) {
    const uint8_t filter = raw[(stride + 1) * y];
    EXPECT_TRUE(filter == 0 || filter == 2);
    for (size_t i = 0; i < stride; ++i) {
      const uint8_t up = y > 0 && filter == 2 ? pixels[stride * (y - 1) + i] : 0;
      pixels[stride * y + i] = static_cast<uint8_t>(raw[(stride + 1) * y + 1 + i] + up);
    }
  }
  return pixels;
}

TEST(EncodePng, ZlibDecodesEveryLevelDepthAndChannelCount) {
  std::mt19937_64 rng = testing::MakeRng();
  const int width = 29, height = 11;
  for (int depth : {8, 16}) {
    for (int channels = 1; channels <= 4; ++channels) {
      for (int level : {0, 1, 6, 12}) {
        SCOPED_TRACE(::testing::Message()
                     << depth << " bit, " << channels << " channels, level " << level);
        const size_t samples = size_t{width} * height * channels;
        std::vector<uint8_t> bytes = RandomPixels(samples * depth / 8, rng);
        for (size_t i = 0; i < samples / 3; ++i) bytes[i] = 7;  // a run to compress
        const std::vector<uint8_t> png =
            EncodePng(bytes.data(), bytes.size(), width, height, channels, depth, level, "t");
        uint32_t w = 0, h = 0;
        int d = 0, type = 0;
        const std::vector<uint8_t> decoded = ZlibDecode(png, &w, &h, &d, &type);
        EXPECT_EQ(w, uint32_t{width});
        EXPECT_EQ(h, uint32_t{height});
        EXPECT_EQ(d, depth);
        constexpr int kColorType[5] = {0, 0, 4, 2, 6};  // grey, grey+alpha, RGB, RGBA
        EXPECT_EQ(type, kColorType[channels]);
        ASSERT_EQ(decoded.size(), bytes.size());
        for (size_t i = 0; i < samples; ++i) {
          // 16-bit samples are given in host order and stored big-endian.
          const uint32_t given =
              depth == 8 ? bytes[i] : uint32_t{bytes[2 * i]} | (uint32_t{bytes[2 * i + 1]} << 8);
          const uint32_t stored =
              depth == 8 ? decoded[i] : (uint32_t{decoded[2 * i]} << 8) | decoded[2 * i + 1];
          ASSERT_EQ(stored, given) << i;
        }
      }
    }
  }
  EXPECT_THROW(EncodePng(nullptr, 0, 0, 1, 1, 8, 1, "empty"), Error);
  std::vector<uint8_t> one(3);
  EXPECT_THROW(EncodePng(one.data(), one.size(), 1, 1, 3, 12, 1, "depth"), Error);
  EXPECT_THROW(EncodePng(one.data(), one.size(), 1, 1, 4, 8, 1, "size"), Error);
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
