#include "rephoto/splat/scalar_ply.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::splat {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A binary little-endian Inria PLY written by hand: normals, an unknown uchar property between
// the others, SH degree 0, two Gaussians. Records are 4 * 17 + 1 = 69 bytes.
std::string HandPly() {
  std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nproperty float nx\nproperty float ny\n"
      "property float nz\nproperty uchar tag\nproperty float f_dc_0\nproperty float f_dc_1\n"
      "property float f_dc_2\nproperty float opacity\nproperty float scale_0\n"
      "property float scale_1\nproperty float scale_2\nproperty float rot_0\n"
      "property float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n";
  for (int g = 0; g < 2; ++g) {
    const float before[6] = {1.0f + g, 2, 3, 0, 0, 1};
    const uint8_t tag = 7 + g;
    const float after[11] = {0.1f, 0.2f, 0.3f, 0, -1, -1, -1, 1, 0, 0, 0};
    ply.append(reinterpret_cast<const char*>(before), sizeof before);
    ply.append(reinterpret_cast<const char*>(&tag), 1);
    ply.append(reinterpret_cast<const char*>(after), sizeof after);
  }
  return ply;
}

float FloatAt(const std::string& bytes, size_t offset) {
  float value;
  std::memcpy(&value, bytes.data() + offset, 4);
  return value;
}

TEST(ScalarPly, KeepsEveryPropertyAndAppendsTheValue) {
  const std::string ply = HandPly();
  const std::string out = WithVertexFloatProperty(ply, "error", {0.25f, NAN}, "m.ply");
  const size_t body = out.find("end_header\n") + 11;
  EXPECT_THAT(out.substr(0, body),
              HasSubstr("property float rot_3\nproperty float error\nend_header\n"));
  ASSERT_EQ(out.size(), body + 2 * 73);
  const size_t old_body = ply.find("end_header\n") + 11;
  for (int g = 0; g < 2; ++g) {
    EXPECT_EQ(out.substr(body + g * 73, 69), ply.substr(old_body + g * 69, 69)) << g;
  }
  EXPECT_EQ(FloatAt(out, body + 69), 0.25f);
  EXPECT_TRUE(std::isnan(FloatAt(out, body + 73 + 69)));
  // Still the same Gaussians for a reader; the tag byte is where it was.
  std::istringstream in(out);
  const GaussianModel model = ReadGaussians(in, "out.ply", false);
  ASSERT_EQ(model.size(), 2u);
  EXPECT_EQ(model.positions[1], Eigen::Vector3f(2, 2, 3));
  EXPECT_EQ(static_cast<uint8_t>(out[body + 73 + 24]), 8);
  // Projected again: the property is overwritten, not added twice.
  const std::string again = WithVertexFloatProperty(out, "error", {1.0f, 2.0f}, "out.ply");
  EXPECT_EQ(again.size(), out.size());
  EXPECT_EQ(FloatAt(again, body + 69), 1.0f);
  EXPECT_EQ(FloatAt(again, body + 73 + 69), 2.0f);
}

TEST(ScalarPly, RefusesWhatItCannotExtend) {
  EXPECT_THAT(
      [] {
        try {
          WithVertexFloatProperty("ply\nformat ascii 1.0\nelement vertex 0\nend_header\n", "e", {},
                                  "a.ply");
        } catch (const Error& e) {
          return std::string(e.what());
        }
        return std::string();
      }(),
      HasSubstr("a.ply: PLY is not binary_little_endian"));
  EXPECT_THROW(WithVertexFloatProperty(HandPly(), "error", {1.0f}, "m.ply"), Error);
  std::string truncated = HandPly();
  truncated.resize(truncated.size() - 1);
  EXPECT_THROW(WithVertexFloatProperty(truncated, "error", {1.0f, 2.0f}, "m.ply"), Error);
}

TEST(ScalarPly, OtherLayoutsAreWrittenInTheInriaLayoutWithTheValue) {
  const fs::path dir = testing::MakeTempDir();
  char record[32] = {};
  const float values[6] = {1, 2, 3, 0.5f, 0.25f, 2};
  std::memcpy(record, values, sizeof(values));
  const uint8_t bytes[8] = {255, 0, 128, 51, 128, 128, 128, 255};
  std::memcpy(record + 24, bytes, 8);
  WriteTextFileAtomically(dir / "m.splat", std::string(record, 32));
  const GaussianModel model = ReadGaussians(dir / "m.splat");
  WriteGaussiansWithScalar(dir / "m.splat", model, "error", {0.5f}, dir / "out.ply");
  const std::string out = ReadFileToString(dir / "out.ply");
  EXPECT_THAT(out, HasSubstr("property float error\nend_header\n"));
  EXPECT_EQ(FloatAt(out, out.size() - 4), 0.5f);
  const GaussianModel back = ReadGaussians(dir / "out.ply");
  ASSERT_EQ(back.size(), 1u);
  EXPECT_TRUE(back.positions[0].isApprox(model.positions[0]));
  EXPECT_TRUE(back.scales[0].isApprox(model.scales[0], 1e-5f));
}

}  // namespace
}  // namespace rephoto::splat
