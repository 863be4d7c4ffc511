#include "rephoto/ibr/depth_map_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/core/limits.h"
#include "rephoto/io/image_io.h"
#include "rephoto/testing/testing.h"

namespace rephoto::ibr {
namespace {

// Bytes of a COLMAP Mat<float> file written by hand from colmap/mvs/mat.cc: the text header
// "<width>&<height>&<depth>&" followed by the raw little-endian floats, slice-major then
// row-major (index slice * width * height + row * width + col).
std::string ColmapBytes(const std::string& header, const std::vector<float>& values) {
  std::string bytes = header;
  const size_t offset = bytes.size();
  bytes.resize(offset + values.size() * 4);
  std::memcpy(bytes.data() + offset, values.data(), values.size() * 4);
  return bytes;
}

std::string ErrorOf(const std::filesystem::path& path) {
  return testing::ErrorOf([&] { ReadDepthMap(path); });
}

TEST(DepthMapIo, ReadsColmapBinRowMajorWithZeroAsUnknown) {
  // 3 x 2: row 0 = 1.5 2.5 0 (0 = unknown), row 1 = 4 5 -1 (negative = unknown).
  const auto dir = rephoto::testing::MakeTempDir();
  testing::WriteFile(dir / "a.bin", ColmapBytes("3&2&1&", {1.5f, 2.5f, 0.f, 4.f, 5.f, -1.f}));
  const Image d = ReadDepthMap(dir / "a.bin");
  ASSERT_EQ(d.width(), 3);
  ASSERT_EQ(d.height(), 2);
  ASSERT_EQ(d.channels(), 1);
  EXPECT_EQ(d.at(0, 0), 1.5f);
  EXPECT_EQ(d.at(1, 0), 2.5f);
  EXPECT_TRUE(std::isnan(d.at(2, 0)));
  EXPECT_EQ(d.at(0, 1), 4.f);
  EXPECT_EQ(d.at(1, 1), 5.f);
  EXPECT_TRUE(std::isnan(d.at(2, 1)));
}

TEST(DepthMapIo, ThreeChannelFileUsesTheFirstSlice) {
  std::vector<float> values(2 * 2 * 3);
  for (size_t i = 0; i < values.size(); ++i) values[i] = static_cast<float>(i + 1);
  std::istringstream in(ColmapBytes("2&2&3&", values));
  const Image d = ReadColmapDepthMap(in, "normals.bin");
  EXPECT_EQ(d.at(0, 0), 1.f);
  EXPECT_EQ(d.at(1, 1), 4.f);
}

TEST(DepthMapIo, WriteThenReadRoundTripsAndMatchesTheHandWrittenBytes) {
  const auto dir = rephoto::testing::MakeTempDir();
  Image depth(3, 2, 1);
  const float values[6] = {1.5f, 2.5f, std::nanf(""), 4.f, 5.f, 0.25f};
  std::copy(values, values + 6, depth.data());
  WriteColmapDepthMap(dir / "b.bin", depth);
  std::ifstream in(dir / "b.bin", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(bytes, ColmapBytes("3&2&1&", {1.5f, 2.5f, 0.f, 4.f, 5.f, 0.25f}));
  const Image back = ReadDepthMap(dir / "b.bin");
  EXPECT_EQ(back.at(1, 1), 5.f);
  EXPECT_TRUE(std::isnan(back.at(2, 0)));
}

TEST(DepthMapIo, ReadsPfmAndExrFirstChannel) {
  const auto dir = rephoto::testing::MakeTempDir();
  Image depth(4, 3, 1);
  for (size_t i = 0; i < depth.size(); ++i) depth.data()[i] = 0.5f + static_cast<float>(i);
  depth.at(3, 2) = 0;  // unknown
  io::WritePfm(dir / "d.pfm", depth);
  io::WriteExr(dir / "d.exr", depth);
  for (const char* name : {"d.pfm", "d.exr"}) {
    const Image d = ReadDepthMap(dir / name);
    ASSERT_EQ(d.width(), 4) << name;
    EXPECT_EQ(d.at(1, 2), depth.at(1, 2)) << name;
    EXPECT_TRUE(std::isnan(d.at(3, 2))) << name;
  }
}

TEST(DepthMapIo, BadFilesThrowNamingTheFile) {
  const auto dir = rephoto::testing::MakeTempDir();
  const struct {
    const char* name;
    std::string bytes;
    const char* message;
  } cases[] = {
      {"truncated.bin", ColmapBytes("3&2&1&", {1, 2, 3, 4}), "truncated"},
      {"trailing.bin", ColmapBytes("2&2&1&", {1, 2, 3, 4, 5}), "bytes after"},
      {"no_amp.bin", ColmapBytes("3 2 1", {1}), "'&' expected"},
      {"zero.bin", ColmapBytes("0&2&1&", {}), "bad size"},
      {"channels.bin", ColmapBytes("1&1&9&", {1}), "bad channel count"},
      {"huge.bin", ColmapBytes("99999999999&1&1&", {1}), "too many digits"},
      {"text.bin", "hello", "not"},
  };
  for (const auto& c : cases) {
    testing::WriteFile(dir / c.name, c.bytes);
    const std::string message = ErrorOf(dir / c.name);
    EXPECT_NE(message.find((dir / c.name).string()), std::string::npos) << message;
    EXPECT_NE(message.find(c.message), std::string::npos) << c.name << ": " << message;
  }
  EXPECT_NE(ErrorOf(dir / "missing.bin").find("missing.bin"), std::string::npos);
  Image rgb(2, 2, 3);
  EXPECT_THROW(WriteColmapDepthMap(dir / "rgb.bin", rgb), Error);
}

TEST(DepthMapIo, HugeHeaderIsRejectedBeforeAllocating) {
  // The header of a 12-byte file claimed 131072 x 131072 values: the reader allocated 64 GiB
  // before finding the payload short.
  const uint64_t pixels = MaxPixels(), memory = MaxMemoryBytes();
  const auto dir = rephoto::testing::MakeTempDir();
  const auto path = dir / "huge.bin";
  testing::WriteFile(path, ColmapBytes("131072&131072&1&", {1}));
  EXPECT_EQ(ErrorOf(path), path.string() +
                               ": COLMAP depth map image of 131072x131072 pixels (1.72e+10) "
                               "exceeds --max-pixels 268435456 (raise it with --max-pixels)");
  // Within the limits, the missing payload is found before allocating too.
  SetMaxPixels(uint64_t{1} << 40);
  SetMaxMemoryBytes(uint64_t{1} << 40);
  EXPECT_EQ(ErrorOf(path),
            path.string() + ": truncated COLMAP depth map: 4 of 68719476736 bytes of values");
  SetMaxMemoryBytes(1000);
  EXPECT_NE(ErrorOf(path).find("more than --max-memory 1000 B"), std::string::npos);
  SetMaxPixels(pixels);
  SetMaxMemoryBytes(memory);
}

}  // namespace
}  // namespace rephoto::ibr
