#include "rephoto/io/png_inflate.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <bit>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/limits.h"
#include "rephoto/io/image_io.h"
#include "rephoto/testing/testing.h"

namespace rephoto::io {
namespace {

namespace fs = std::filesystem;

// A PNG written here with zlib (independent of libdeflate, libspng and io::EncodePng): every
// row filtered with the type `filter_of(y)` as the PNG specification (section 9) defines the
// filters, the zlib stream cut into IDAT chunks of the sizes `chunk_of` gives (0 allowed), a
// tEXt chunk before and after the image data.
struct TestPng {
  uint32_t width = 0, height = 0;
  int color_type = 0, bit_depth = 8;
  std::vector<uint8_t> samples;  // as stored: 16-bit samples big-endian
};

void Put32(std::vector<uint8_t>& out, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<uint8_t>(v >> s));
}

void Chunk(std::vector<uint8_t>& out, const char* type, const uint8_t* data, size_t size) {
  Put32(out, static_cast<uint32_t>(size));
  const size_t start = out.size();
  out.insert(out.end(), type, type + 4);
  out.insert(out.end(), data, data + size);
  Put32(out, static_cast<uint32_t>(crc32(0, out.data() + start, static_cast<uInt>(size + 4))));
}

int ChannelsOf(int color_type) {
  const int channels[7] = {1, 0, 3, 0, 2, 0, 4};
  return channels[color_type];
}

int PaethPredictor(int a, int b, int c) {
  const int p = a + b - c;
  const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  if (pa <= pb && pa <= pc) return a;
  if (pb <= pc) return b;
  return c;
}

template <typename FilterOf, typename ChunkOf>
std::vector<uint8_t> WriteTestPng(const TestPng& png, FilterOf filter_of, ChunkOf chunk_of) {
  const int bpp = ChannelsOf(png.color_type) * png.bit_depth / 8;
  const size_t stride = size_t{png.width} * bpp;
  std::vector<uint8_t> raw;
  for (uint32_t y = 0; y < png.height; ++y) {
    const int filter = filter_of(y);
    raw.push_back(static_cast<uint8_t>(filter));
    const uint8_t* row = png.samples.data() + stride * y;
    const uint8_t* up = y > 0 ? row - stride : nullptr;
    for (size_t i = 0; i < stride; ++i) {
      const int a = i >= static_cast<size_t>(bpp) ? row[i - bpp] : 0;
      const int b = up ? up[i] : 0;
      const int c = up && i >= static_cast<size_t>(bpp) ? up[i - bpp] : 0;
      const int predicted = filter == 0   ? 0
                            : filter == 1 ? a
                            : filter == 2 ? b
                            : filter == 3 ? (a + b) / 2
                                          : PaethPredictor(a, b, c);
      raw.push_back(static_cast<uint8_t>(row[i] - predicted));
    }
  }
  std::vector<uint8_t> z(compressBound(static_cast<uLong>(raw.size())));
  uLongf z_size = z.size();
  EXPECT_EQ(compress2(z.data(), &z_size, raw.data(), static_cast<uLong>(raw.size()), 6), Z_OK);
  z.resize(z_size);

  std::vector<uint8_t> out = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<uint8_t> ihdr;
  Put32(ihdr, png.width);
  Put32(ihdr, png.height);
  ihdr.insert(ihdr.end(), {static_cast<uint8_t>(png.bit_depth),
                           static_cast<uint8_t>(png.color_type), 0, 0, 0});
  Chunk(out, "IHDR", ihdr.data(), ihdr.size());
  const std::string text = std::string("Comment") + '\0' + "written by png_inflate_test";
  Chunk(out, "tEXt", reinterpret_cast<const uint8_t*>(text.data()), text.size());
  for (size_t pos = 0, i = 0; pos < z.size(); ++i) {
    const size_t n = std::min(z.size() - pos, chunk_of(i));
    Chunk(out, "IDAT", z.data() + pos, n);
    pos += n;
  }
  Chunk(out, "tEXt", reinterpret_cast<const uint8_t*>(text.data()), text.size());
  Chunk(out, "IEND", nullptr, 0);
  return out;
}

// Samples with long runs, smooth ramps and noise, so that every filter sees all byte values.
TestPng MakeTestPng(uint32_t width, uint32_t height, int color_type, int bit_depth,
                    std::mt19937_64& rng) {
  TestPng png{.width = width, .height = height, .color_type = color_type, .bit_depth = bit_depth};
  const size_t values = size_t{width} * height * ChannelsOf(color_type);
  std::uniform_int_distribution<int> byte(0, 255);
  for (size_t i = 0; i < values; ++i) {
    const size_t x = i / ChannelsOf(color_type) % width;
    for (int b = 0; b < bit_depth / 8; ++b) {
      const int v = i % 7 < 2 ? byte(rng) : (x < width / 3 ? 17 : static_cast<int>(x * 3 + i));
      png.samples.push_back(static_cast<uint8_t>(v));
    }
  }
  return png;
}

// The samples in the order io::internal::InflatePng gives them (16-bit in host order).
std::vector<uint8_t> HostOrder(const TestPng& png) {
  std::vector<uint8_t> s = png.samples;
  if (png.bit_depth == 16 && std::endian::native == std::endian::little) {
    for (size_t i = 0; i + 1 < s.size(); i += 2) std::swap(s[i], s[i + 1]);
  }
  return s;
}

// The floats ReadImage promises (v / 255 or v / 65535), from the samples.
Image ExpectedFloats(const TestPng& png) {
  const int channels = ChannelsOf(png.color_type);
  Image image(static_cast<int>(png.width), static_cast<int>(png.height), channels);
  const bool wide = png.bit_depth == 16;
  for (size_t i = 0; i < image.size(); ++i) {
    const int v = wide ? (png.samples[2 * i] << 8) | png.samples[2 * i + 1] : png.samples[i];
    image.data()[i] = static_cast<float>(v) / (wide ? 65535.f : 255.f);
  }
  return image;
}

void ExpectSameImage(const Image& a, const Image& b, const std::string& what) {
  ASSERT_EQ(a.width(), b.width()) << what;
  ASSERT_EQ(a.height(), b.height()) << what;
  ASSERT_EQ(a.channels(), b.channels()) << what;
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0) << what;
}

TEST(InflatePng, EveryFilterColourTypeDepthAndChunkingGivesTheSamples) {
  std::mt19937_64 rng(29);
  const fs::path dir = testing::MakeTempDir();
  for (int color_type : {0, 2, 4, 6}) {
    for (int bit_depth : {8, 16}) {
      for (uint32_t width : {1u, 2u, 37u, 130u}) {
        const TestPng png = MakeTestPng(width, 23, color_type, bit_depth, rng);
        // Each filter on its own, then a mix (the rows cycle through 0-4).
        for (int filter = 0; filter <= 5; ++filter) {
          const std::string what = "colour type " + std::to_string(color_type) + ", " +
                                   std::to_string(bit_depth) + " bit, width " +
                                   std::to_string(width) + ", filter " +
                                   (filter == 5 ? "mixed" : std::to_string(filter));
          SCOPED_TRACE(what);
          std::uniform_int_distribution<size_t> chunk(0, 700);
          const std::vector<uint8_t> file = WriteTestPng(
              png, [&](uint32_t y) { return filter == 5 ? static_cast<int>(y % 5) : filter; },
              [&](size_t i) { return i == 0 ? size_t{1} : chunk(rng); });
          const internal::PngLayout layout{.width = png.width,
                                           .height = png.height,
                                           .channels = ChannelsOf(color_type),
                                           .bit_depth = bit_depth};
          std::vector<uint8_t> out(png.samples.size());
          ASSERT_TRUE(internal::InflatePng(file, layout, out.data(), out.size()));
          EXPECT_EQ(out, HostOrder(png));

          // Through the public decoder, and against libspng alone.
          Image image, reference;
          DecodeImage(file, "test.png", &image);
          internal::DecodeImageByLibspng(file, "test.png", &reference);
          ExpectSameImage(image, ExpectedFloats(png), what + ": floats");
          ExpectSameImage(reference, image, what + ": libspng");
          if (bit_depth == 8) {
            const fs::path path = dir / "t.png";
            WriteFileAtomically(path, [&](const fs::path& tmp) {
              std::FILE* f = std::fopen(tmp.c_str(), "wb");
              ASSERT_NE(f, nullptr);
              std::fwrite(file.data(), 1, file.size(), f);
              std::fclose(f);
            });
            Image8 image8;
            Image unused;
            ASSERT_TRUE(ReadImage8(path, &image8, &unused));
            EXPECT_EQ(std::vector<uint8_t>(image8.data(), image8.data() + image8.size()),
                      png.samples);
          }
        }
      }
    }
  }
}

TEST(InflatePng, TakesOnlyTheVariantsItDecodes) {
  for (int color_type : {0, 2, 4, 6}) {
    EXPECT_TRUE(internal::InflatePngHandles(color_type, 8, 0, false));
    EXPECT_TRUE(internal::InflatePngHandles(color_type, 16, 0, false));
    EXPECT_FALSE(internal::InflatePngHandles(color_type, 8, 1, false));  // Adam7
    EXPECT_FALSE(internal::InflatePngHandles(color_type, 8, 0, true));   // tRNS
  }
  EXPECT_FALSE(internal::InflatePngHandles(3, 8, 0, false));  // palette
  for (int depth : {1, 2, 4}) EXPECT_FALSE(internal::InflatePngHandles(0, depth, 0, false));
}

// Broken files: the libdeflate path declines each one, and the public decoder then reports what
// libspng reports (an Error naming the file), as before that path existed.
TEST(InflatePng, DeclinesBrokenFilesAndLibspngReportsThem) {
  std::mt19937_64 rng(31);
  const TestPng png = MakeTestPng(64, 16, 2, 8, rng);
  const std::vector<uint8_t> good = WriteTestPng(
      png, [](uint32_t y) { return static_cast<int>(y % 5); }, [](size_t) { return size_t{200}; });
  const internal::PngLayout layout{.width = 64, .height = 16, .channels = 3, .bit_depth = 8};
  std::vector<uint8_t> out(png.samples.size());
  ASSERT_TRUE(internal::InflatePng(good, layout, out.data(), out.size()));

  // The first IDAT chunk's offset (after the signature, IHDR (25 bytes) and the tEXt chunk).
  const size_t text = 8 + 25;
  const size_t idat = text + 12 + (size_t{good[text + 2]} << 8 | good[text + 3]);
  ASSERT_EQ(std::memcmp(&good[idat + 4], "IDAT", 4), 0);

  struct Case {
    std::string name;
    std::vector<uint8_t> file;
  };
  std::vector<Case> cases;
  {
    std::vector<uint8_t> f = good;  // a CRC mismatch in the image data
    f[idat + 8 + 50] ^= 0x40;
    cases.push_back({"IDAT CRC mismatch", f});
  }
  {
    std::vector<uint8_t> f = good;  // the same damage with the CRC made to match: Adler-32
    f[idat + 8 + 50] ^= 0x40;
    const uint32_t crc = static_cast<uint32_t>(crc32(0, &f[idat + 4], 200 + 4));
    for (int b = 0; b < 4; ++b) f[idat + 8 + 200 + b] = static_cast<uint8_t>(crc >> (24 - 8 * b));
    cases.push_back({"corrupt zlib stream", f});
  }
  cases.push_back({"truncated", std::vector<uint8_t>(good.begin(), good.begin() + idat + 300)});
  {
    std::vector<uint8_t> f = good;  // a chunk length past the end of the file
    f[idat] = 0x7f;
    cases.push_back({"chunk past the end", f});
  }
  {
    TestPng one_row = png;  // a filter type that does not exist, in a valid zlib stream
    const std::vector<uint8_t> f = WriteTestPng(
        one_row, [](uint32_t y) { return y == 7 ? 5 : 0; }, [](size_t) { return size_t{1000}; });
    cases.push_back({"filter type 5", f});
  }
  {
    TestPng shorter = png;  // a stream that ends one row early
    shorter.height = 15;
    shorter.samples.resize(shorter.samples.size() - 64 * 3);
    std::vector<uint8_t> f = WriteTestPng(
        shorter, [](uint32_t) { return 2; }, [](size_t) { return size_t{1000}; });
    f[8 + 8 + 7] = 16;  // IHDR height 16 again, its CRC put right
    const uint32_t crc = static_cast<uint32_t>(crc32(0, &f[12], 17));
    for (int b = 0; b < 4; ++b) f[8 + 8 + 13 + b] = static_cast<uint8_t>(crc >> (24 - 8 * b));
    cases.push_back({"image data one row short", f});
  }
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    EXPECT_FALSE(internal::InflatePng(c.file, layout, out.data(), out.size()));
    Image image;
    try {
      DecodeImage(c.file, "broken.png", &image);
      ADD_FAILURE() << "decoded";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind("broken.png: ", 0), 0u) << e.what();
    }
  }
}

// A PNG whose floats and samples fit in --max-memory but not the libdeflate path's filtered
// copy as well still decodes (by libspng, row by row), to the same values.
TEST(InflatePng, APngThatFitsTheMemoryLimitOnlyWithoutTheFilteredCopyStillDecodes) {
  std::mt19937_64 rng(37);
  const TestPng png = MakeTestPng(300, 200, 2, 8, rng);
  const std::vector<uint8_t> file = WriteTestPng(
      png, [](uint32_t y) { return static_cast<int>(y % 5); }, [](size_t) { return size_t{4096}; });
  const uint64_t before = MaxMemoryBytes();
  SetMaxMemoryBytes(uint64_t{300} * 200 * 3 * 5);  // floats + samples, not the filtered copy
  Image image;
  try {
    DecodeImage(file, "fits.png", &image);
  } catch (...) {
    SetMaxMemoryBytes(before);
    throw;
  }
  SetMaxMemoryBytes(before);
  ExpectSameImage(image, ExpectedFloats(png), "at the memory limit");
}

// The real PNG photos of ../shared/data (written by other encoders, mostly Paeth rows): the
// same floats as libspng's.
TEST(InflatePng, SharedDataPhotosDecodeAsLibspngDecodesThem) {
  const fs::path data = testing::SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "no ../shared/data";
  int compared = 0;
  for (const auto& entry : fs::recursive_directory_iterator(data)) {
    if (entry.path().extension() != ".png") continue;
    std::FILE* f = std::fopen(entry.path().c_str(), "rb");
    ASSERT_NE(f, nullptr);
    std::vector<uint8_t> bytes(fs::file_size(entry.path()));
    ASSERT_EQ(std::fread(bytes.data(), 1, bytes.size(), f), bytes.size());
    std::fclose(f);
    Image image, reference;
    DecodeImage(bytes, entry.path().string(), &image);
    internal::DecodeImageByLibspng(bytes, entry.path().string(), &reference);
    ExpectSameImage(image, reference, entry.path().string());
    ++compared;
  }
  EXPECT_GT(compared, 0);
}

}  // namespace
}  // namespace rephoto::io
