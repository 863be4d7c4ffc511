#include "rephoto/splat/gaussians.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/testing/testing.h"

namespace rephoto::splat {
namespace {

using ::testing::HasSubstr;

std::string ErrorOf(const std::string& text, bool splat = false) {
  std::istringstream in(text);
  return testing::ErrorOf([&] { ReadGaussians(in, "model.ply", splat); });
}

// An ascii Inria-layout PLY with the properties in an unusual order, normals, an unknown
// property and SH degree 1 (9 f_rest).
std::string AsciiPly(const std::string& opacity = "0") {
  std::string header =
      "ply\nformat ascii 1.0\ncomment test\nelement vertex 1\nproperty float opacity\n"
      "property float nx\nproperty float ny\nproperty float nz\nproperty float x\n"
      "property float y\nproperty float z\nproperty float extra\n";
  for (int i = 0; i < 9; ++i) header += "property float f_rest_" + std::to_string(i) + "\n";
  header +=
      "property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n"
      "property float scale_0\nproperty float scale_1\nproperty float scale_2\n"
      "property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\n"
      "end_header\n";
  return header + opacity +
         " 0 0 1 1 2 3 99 10 11 12 20 21 22 30 31 32 0.1 0.2 0.3 0 -1 0.5 2 0 0 0\n";
}

TEST(ReadGaussians, InriaLayoutByPropertyName) {
  std::istringstream in(AsciiPly());
  GaussianFormat format;
  const GaussianModel model = ReadGaussians(in, "model.ply", false, &format);
  EXPECT_EQ(format, GaussianFormat::kInriaPly);
  ASSERT_EQ(model.size(), 1u);
  EXPECT_EQ(model.sh_degree, 1);
  EXPECT_EQ(model.positions[0], Eigen::Vector3f(1, 2, 3));
  EXPECT_NEAR(model.opacities[0], 0.5f, 1e-7f);  // sigmoid(0)
  EXPECT_NEAR(model.scales[0][0], 1.0f, 1e-6f);  // exp(0)
  EXPECT_NEAR(model.scales[0][1], std::exp(-1.0f), 1e-6f);
  EXPECT_TRUE(model.rotations[0].isApprox(Eigen::Vector4f(1, 0, 0, 0)));  // (2,0,0,0) normalised
  // Coefficient k of channel c is f_rest_{c * 3 + k - 1}: red 10 11 12, green 20 21 22, ...
  const float expected[] = {0.1f, 0.2f, 0.3f, 10, 20, 30, 11, 21, 31, 12, 22, 32};
  for (int i = 0; i < 12; ++i) EXPECT_FLOAT_EQ(model.sh[i], expected[i]) << i;
}

TEST(ReadGaussians, BinaryRoundTripAndMipFilterAndColourOnly) {
  GaussianModel model;
  model.sh_degree = 3;
  model.positions = {Eigen::Vector3f(1, -2, 3), Eigen::Vector3f(0, 0, 1)};
  model.scales = {Eigen::Vector3f(0.1f, 0.2f, 0.3f), Eigen::Vector3f(1, 1, 1)};
  model.rotations = {Eigen::Vector4f(0.5f, 0.5f, 0.5f, 0.5f), Eigen::Vector4f(0, 1, 0, 0)};
  model.opacities = {0.25f, 0.9f};
  for (int i = 0; i < 2 * 48; ++i) model.sh.push_back(0.01f * i - 0.3f);
  std::stringstream stream;
  WriteInriaPly(stream, model);
  EXPECT_TRUE(IsGaussianPlyHeader(stream));
  stream.seekg(0);
  const GaussianModel read = ReadGaussians(stream, "rt.ply", false);
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read.sh_degree, 3);
  for (size_t g = 0; g < 2; ++g) {
    EXPECT_TRUE(read.positions[g].isApprox(model.positions[g]));
    EXPECT_TRUE(read.scales[g].isApprox(model.scales[g], 1e-5f));
    EXPECT_TRUE(read.rotations[g].isApprox(model.rotations[g], 1e-6f));
    EXPECT_NEAR(read.opacities[g], model.opacities[g], 1e-6f);
  }
  for (size_t i = 0; i < model.sh.size(); ++i) EXPECT_FLOAT_EQ(read.sh[i], model.sh[i]);

  // Mip-Splatting's filter_3D: scale' = sqrt(s^2 + f^2), opacity' = o sqrt(prod s^2 / s'^2).
  const std::string mip =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nproperty float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n"
      "property float opacity\nproperty float scale_0\nproperty float scale_1\n"
      "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\n"
      "property float rot_3\nproperty float filter_3D\nend_header\n"
      "0 0 0 0 0 0 0 0 0 0 1 0 0 0 1\n";
  std::istringstream mip_in(mip);
  const GaussianModel filtered = ReadGaussians(mip_in, "mip.ply", false);
  EXPECT_NEAR(filtered.scales[0][0], std::sqrt(2.0f), 1e-6f);
  EXPECT_NEAR(filtered.opacities[0], 0.5f * std::sqrt(1.0f / 8.0f), 1e-6f);

  // splatfacto colour-only export: uchar red green blue.
  const std::string color =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
      "property float opacity\nproperty float scale_0\nproperty float scale_1\n"
      "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\n"
      "property float rot_3\nend_header\n0 0 0 255 0 51 0 0 0 0 1 0 0 0\n";
  std::istringstream color_in(color);
  GaussianFormat format;
  const GaussianModel colors = ReadGaussians(color_in, "color.ply", false, &format);
  EXPECT_EQ(format, GaussianFormat::kColorPly);
  EXPECT_EQ(colors.sh_degree, 0);
  EXPECT_NEAR(colors.sh[0] * kShC0 + 0.5f, 1.0f, 1e-6f);
  EXPECT_NEAR(colors.sh[1] * kShC0 + 0.5f, 0.0f, 1e-6f);
  EXPECT_NEAR(colors.sh[2] * kShC0 + 0.5f, 0.2f, 1e-6f);
}

TEST(ReadGaussians, OneLineErrors) {
  // More Gaussians claimed than the file holds: refused before allocating.
  GaussianModel model;
  model.positions = {Eigen::Vector3f::Zero()};
  model.scales = {Eigen::Vector3f::Ones()};
  model.rotations = {Eigen::Vector4f(1, 0, 0, 0)};
  model.opacities = {0.5f};
  model.sh = {0, 0, 0};
  std::stringstream stream;
  WriteInriaPly(stream, model);
  std::string text = stream.str();
  const size_t at = text.find("element vertex 1");
  text.replace(at, 16, "element vertex 1000000000");
  EXPECT_THAT(ErrorOf(text), HasSubstr("model.ply: element 'vertex' claims 1000000000 records"));
  // Truncated ascii.
  std::string truncated = AsciiPly();
  truncated.resize(truncated.size() - 20);
  EXPECT_THAT(ErrorOf(truncated), HasSubstr("unexpected end of file"));
  // NaN / inf parameters.
  EXPECT_THAT(ErrorOf(AsciiPly("nan")),
              HasSubstr("model.ply: Gaussian 0: property 'opacity' is not finite"));
  std::string inf = AsciiPly();
  inf.replace(inf.find(" 1 2 3 99"), 9, " 1 inf 3 99");
  EXPECT_THAT(ErrorOf(inf), HasSubstr("property 'y' is not finite"));
  // Unknown SH count.
  std::string rest = AsciiPly();
  rest.replace(rest.find("property float f_rest_8\n"), 24, "");
  EXPECT_THAT(ErrorOf(rest), HasSubstr("8 f_rest_* properties"));
  // Not Gaussians.
  EXPECT_THAT(ErrorOf("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n"),
              HasSubstr("no Gaussian properties"));
  EXPECT_THAT(ErrorOf("solid cube\n"), HasSubstr("not a PLY file"));
  // .splat: not a multiple of 32 bytes; empty.
  EXPECT_THAT(ErrorOf(std::string(33, '\0'), true), HasSubstr("not a whole number of 32-byte"));
  EXPECT_THAT(ErrorOf("", true), HasSubstr("no Gaussians"));
  // Compressed: fewer chunks than the Gaussians need.
  const std::string compressed =
      "ply\nformat binary_little_endian 1.0\nelement chunk 1\nproperty float min_x\n"
      "element vertex 300\nproperty uint packed_position\nproperty uint packed_rotation\n"
      "property uint packed_scale\nproperty uint packed_color\nend_header\n";
  EXPECT_THAT(ErrorOf(compressed), HasSubstr("1 chunks cannot hold 300 Gaussians"));
}

TEST(ReadGaussians, SplatRecord) {
  char record[32];
  const float values[6] = {1, 2, 3, 0.5f, 0.25f, 2};
  std::memcpy(record, values, sizeof(values));
  const uint8_t bytes[8] = {255, 0, 128, 51, 128, 128, 128, 255};  // rotation ~ (0,0,0,1)
  std::memcpy(record + 24, bytes, 8);
  std::istringstream in(std::string(record, 32));
  const GaussianModel model = ReadGaussians(in, "m.splat", true);
  ASSERT_EQ(model.size(), 1u);
  EXPECT_EQ(model.positions[0], Eigen::Vector3f(1, 2, 3));
  EXPECT_EQ(model.scales[0], Eigen::Vector3f(0.5f, 0.25f, 2));
  EXPECT_NEAR(model.sh[0] * kShC0 + 0.5f, 1.0f, 1e-6f);
  EXPECT_NEAR(model.opacities[0], 0.2f, 1e-6f);
  EXPECT_TRUE(model.rotations[0].isApprox(Eigen::Vector4f(0, 0, 0, 1), 1e-6f));
}

TEST(IsGaussianFile, DetectsByHeaderOrExtension) {
  const auto dir = testing::MakeTempDir();
  std::ofstream(dir / "mesh.ply") << "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                     "property float y\nproperty float z\nend_header\n0 0 0\n";
  std::ofstream(dir / "splats.ply") << AsciiPly();
  std::ofstream(dir / "a.splat") << "";
  EXPECT_FALSE(IsGaussianFile(dir / "mesh.ply"));
  EXPECT_TRUE(IsGaussianFile(dir / "splats.ply"));
  EXPECT_TRUE(IsGaussianFile(dir / "a.splat"));
  EXPECT_FALSE(IsGaussianFile(dir / "missing.ply"));
}

}  // namespace
}  // namespace rephoto::splat
