#include "rephoto/scene/middlebury.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/scene/scene_info.h"
#include "rephoto/testing/testing.h"

namespace rephoto::scene {
namespace {

using ::testing::HasSubstr;

constexpr const char* kTwoViews =
    "2\n"
    "a.png 1000 0 300 0 1100 200 0 0 1  1 0 0 0 1 0 0 0 1  0.1 0.2 3\n"
    "b.png 1000 0 300 0 1100 200 0 0 1  0 1 0 -1 0 0 0 0 1  0 0 2\n";

Scene Read(const std::string& text) {
  std::istringstream in(text);
  return ReadMiddlebury(in, "x_par.txt", FixedImageSize(640, 480), "/data");
}

std::string ErrorOf(const std::string& text) {
  return testing::ErrorOf([&] { Read(text); });
}

TEST(MiddleburyTest, ConvertsKRt) {
  const Scene scene = Read(kTwoViews);
  ASSERT_EQ(scene.views.size(), 2u);
  ASSERT_EQ(scene.cameras.size(), 1u);  // identical K and size are shared
  const camera::Camera& camera = scene.CameraOf(scene.views[0]);
  EXPECT_EQ(camera.model, camera::CameraModel::kPinhole);
  // Integer pixel centres in the file -> +0.5 in rephoto's corner convention.
  EXPECT_EQ(camera.params, (std::vector<double>{1000, 1100, 300.5, 200.5}));
  EXPECT_EQ(camera.width, 640);
  // x ~ K [R | t] X by hand for X = (0.2, -0.1, 1) in view 0: X_cam = (0.3, 0.1, 4),
  // pixel = (1000 * 0.3 / 4 + 300, 1100 * 0.1 / 4 + 200) = (375, 227.5) (centre convention).
  const auto pixel = camera.ImgFromCam(scene.views[0].cam_from_world.CamFromWorld({0.2, -0.1, 1}));
  ASSERT_TRUE(pixel.has_value());
  EXPECT_NEAR(pixel->x(), 375.5, 1e-12);
  EXPECT_NEAR(pixel->y(), 228.0, 1e-12);
  EXPECT_EQ(scene.views[1].image_path, std::filesystem::path("/data/b.png"));
  EXPECT_TRUE(scene.views[1].cam_from_world.rotation.isApprox(
      (Eigen::Matrix3d() << 0, 1, 0, -1, 0, 0, 0, 0, 1).finished()));
}

TEST(MiddleburyTest, BadInput) {
  std::string text = kTwoViews;
  EXPECT_THAT(ErrorOf("3\n" + text.substr(2)),
              HasSubstr("x_par.txt:4: unexpected end of file, expected image 3 of 3"));
  EXPECT_THAT(ErrorOf("1\n" + text.substr(2)),
              HasSubstr("x_par.txt:3: more lines than the 1 images announced"));
  std::string nan = text;
  nan.replace(nan.find("0.1 0.2 3"), 9, "0.1 nan 3");
  EXPECT_THAT(ErrorOf(nan), HasSubstr("x_par.txt:2: t is not finite"));
  std::string not_rotation = text;
  not_rotation.replace(not_rotation.find("0 1 0 -1 0 0"), 12, "0 1 0 -1 1 0");
  EXPECT_THAT(ErrorOf(not_rotation), AllOf(HasSubstr("x_par.txt:3"), HasSubstr("not a rotation")));
  std::string skew = text;
  skew.replace(skew.find("1000 0 300"), 10, "1000 5 300");
  EXPECT_THAT(ErrorOf(skew), HasSubstr("x_par.txt:2 (a.png): K has skew"));
  EXPECT_THAT(ErrorOf("1\na.png 1 2 3\n"),
              HasSubstr("x_par.txt:2: expected 22 values (name, K (9), R (9), t (3)), got 4"));
  EXPECT_THAT(ErrorOf("2\n" + text.substr(2, text.find('\n', 2) - 1) +
                      text.substr(2, text.find('\n', 2) - 1)),
              HasSubstr("x_par.txt:3: image 'a.png' is listed twice"));
  EXPECT_THAT(ErrorOf("two\n"), HasSubstr("x_par.txt:1: number of images: expected an integer"));
}

// The camera axes of the 16-view rings converge on the object: the point nearest to all
// optical axes is in front of every camera and inside the README's bounding box (grown by
// 20 %), and the box corners project inside the temple images (as SOURCE.txt checked).
void CheckRing(const std::string& folder, const std::string& par, const Eigen::Vector3d& box_min,
               const Eigen::Vector3d& box_max, bool corners_inside) {
  const auto root = testing::SharedDataDir() / "middlebury_temple_dino" / folder;
  const Scene scene = ReadMiddleburyScene(root / par);
  ASSERT_EQ(scene.views.size(), 16u);
  const auto meeting = PointNearestToOpticalAxes(scene);
  ASSERT_TRUE(meeting.has_value());
  const Eigen::Vector3d margin = 0.2 * (box_max - box_min);
  EXPECT_TRUE((meeting->array() >= (box_min - margin).array()).all() &&
              (meeting->array() <= (box_max + margin).array()).all())
      << meeting->transpose();
  for (const View& view : scene.views) {
    const camera::Camera& camera = scene.CameraOf(view);
    EXPECT_EQ(camera.width, 640);
    EXPECT_EQ(camera.height, 480);
    EXPECT_GT(view.cam_from_world.CamFromWorld(*meeting).z(), 0.0) << view.name;
    if (!corners_inside) continue;
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3d point((corner & 1) ? box_max.x() : box_min.x(),
                                  (corner & 2) ? box_max.y() : box_min.y(),
                                  (corner & 4) ? box_max.z() : box_min.z());
      const auto pixel = camera.ImgFromCam(view.cam_from_world.CamFromWorld(point));
      ASSERT_TRUE(pixel.has_value()) << view.name;
      EXPECT_TRUE(pixel->x() > 0 && pixel->x() < 640 && pixel->y() > 0 && pixel->y() < 480)
          << view.name << " corner " << corner << ": " << pixel->transpose();
    }
  }
}

TEST(MiddleburyTest, TempleRingConvergesOnTheObject) {
  REPHOTO_REQUIRE_DATA("middlebury_temple_dino");
  CheckRing("templeSparseRing", "templeSR_par.txt", {-0.073568, 0.021728, -0.012445},
            {0.028855, 0.181892, 0.062736}, /*corners_inside=*/true);
}

TEST(MiddleburyTest, DinoRingConvergesOnTheObject) {
  REPHOTO_REQUIRE_DATA("middlebury_temple_dino");
  // The dino is partly outside the frame in some views (README), so no corner check.
  CheckRing("dinoSparseRing", "dinoSR_par.txt", {-0.061897, -0.018874, -0.057845},
            {0.010897, 0.068227, 0.015495}, /*corners_inside=*/false);
}

}  // namespace
}  // namespace rephoto::scene
