#include "rephoto/scene/strecha.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/scene/scene_info.h"
#include "rephoto/testing/testing.h"

namespace rephoto::scene {
namespace {

using ::testing::HasSubstr;

// R = camera-to-world rotation (a 90 degree turn about z), C = (1, 2, 3).
constexpr const char* kCamera =
    "2000 0 1000\n0 2100 700\n0 0 1\n"
    "0 0 0\n"
    "0 -1 0\n1 0 0\n0 0 1\n"
    "1 2 3\n"
    "2048 1536\n";

std::string ErrorOf(const std::string& text) {
  std::istringstream in(text);
  return testing::ErrorOf([&] { ReadStrechaCamera(in, "0000.jpg.camera"); });
}

TEST(StrechaTest, ConvertsCameraToWorldRotationAndCentre) {
  std::istringstream in(kCamera);
  const CameraAndPose result = ReadStrechaCamera(in, "0000.jpg.camera");
  EXPECT_EQ(result.camera.width, 2048);
  EXPECT_EQ(result.camera.height, 1536);
  EXPECT_EQ(result.camera.params, (std::vector<double>{2000, 2100, 1000.5, 700.5}));
  EXPECT_TRUE(result.cam_from_world.Center().isApprox(Eigen::Vector3d(1, 2, 3)));
  // x = K R^T (X - C) by hand for X = C + (0, 1, 4): R^T (0, 1, 4) = (1, 0, 4) -> pixel
  // (2000 / 4 + 1000, 700) in the file's centre convention, +0.5 in rephoto's.
  const auto pixel =
      result.camera.ImgFromCam(result.cam_from_world.CamFromWorld(Eigen::Vector3d(1, 3, 7)));
  ASSERT_TRUE(pixel.has_value());
  EXPECT_NEAR(pixel->x(), 1500.5, 1e-9);
  EXPECT_NEAR(pixel->y(), 700.5, 1e-9);
}

TEST(StrechaTest, BadInput) {
  EXPECT_THAT(ErrorOf(testing::Replace(kCamera, "1 2 3\n", "1 inf 3\n")),
              HasSubstr("0000.jpg.camera:8: camera centre is not finite"));
  EXPECT_THAT(ErrorOf(testing::Replace(kCamera, "0 -1 0\n1 0 0", "0 -1 0\n1 0.5 0")),
              AllOf(HasSubstr("0000.jpg.camera:7"), HasSubstr("not a rotation")));
  EXPECT_THAT(ErrorOf(testing::Replace(kCamera, "0 0 1\n1 2 3", "0 0 -1\n1 2 3")),
              HasSubstr("reflection"));
  EXPECT_THAT(ErrorOf(testing::Replace(kCamera, "2048 1536\n", "")),
              HasSubstr("0000.jpg.camera:9: unexpected end of file, expected the image size"));
  EXPECT_THAT(ErrorOf(testing::Replace(kCamera, "2048 1536", "2048 0")),
              HasSubstr("0000.jpg.camera:9: height = 0 is outside"));
  EXPECT_THAT(ErrorOf(testing::Replace(kCamera, "0 0 0\n", "0.1 0 0\n")),
              HasSubstr("0000.jpg.camera:4: non-zero distortion"));
  EXPECT_THAT(ErrorOf(std::string(kCamera) + "5\n"), HasSubstr("unexpected data"));
}

// fountain-P11: 11 photos 3072x2048; the optical axes meet at a point in front of every
// camera that projects well inside every photo (the fountain is in the middle of each).
TEST(StrechaTest, FountainAxesConverge) {
  REPHOTO_REQUIRE_DATA("strecha_fountain_p11");
  const auto root = testing::SharedDataDir() / "strecha_fountain_p11";
  const Scene scene = ReadStrechaScene(root / "gt_dense_cameras");
  EXPECT_EQ(scene.image_root, root / "images");
  ASSERT_EQ(scene.views.size(), 11u);
  EXPECT_EQ(scene.views.front().name, "0000.jpg");
  EXPECT_EQ(scene.cameras.size(), 1u);  // all share K and size
  const auto meeting = PointNearestToOpticalAxes(scene);
  ASSERT_TRUE(meeting.has_value());
  for (const View& view : scene.views) {
    const camera::Camera& camera = scene.CameraOf(view);
    EXPECT_EQ(camera.width, 3072);
    EXPECT_EQ(camera.height, 2048);
    const auto pixel = camera.ImgFromCam(view.cam_from_world.CamFromWorld(*meeting));
    ASSERT_TRUE(pixel.has_value()) << view.name;
    EXPECT_TRUE(pixel->x() > 0.2 * 3072 && pixel->x() < 0.8 * 3072 && pixel->y() > 0.2 * 2048 &&
                pixel->y() < 0.8 * 2048)
        << view.name << ": " << pixel->transpose();
  }
}

}  // namespace
}  // namespace rephoto::scene
