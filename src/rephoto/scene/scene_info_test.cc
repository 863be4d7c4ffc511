#include "rephoto/scene/scene_info.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>

#include "rephoto/testing/testing.h"

namespace rephoto::scene {
namespace {

using ::testing::HasSubstr;

// Two cameras looking at the origin from (0, 0, -5) and (5, 0, 0), one point, one image on
// disk and one missing.
Scene MakeScene(const std::filesystem::path& root) {
  Scene scene;
  scene.image_root = root;
  camera::Camera small;
  small.model = camera::CameraModel::kPinhole;
  small.width = 40;
  small.height = 30;
  small.params = {50, 50, 20, 15};
  camera::Camera large = small;
  large.model = camera::CameraModel::kSimpleRadial;
  large.width = 80;
  large.height = 60;
  large.params = {100, 40, 30, 0.01};
  scene.cameras = {{1, small}, {2, large}};
  View front{"front.png", root / "front.png", std::nullopt, 1, {}};
  front.cam_from_world.translation = Eigen::Vector3d(0, 0, 5);  // centre (0, 0, -5)
  View side{"side.png", root / "side.png", std::nullopt, 2, {}};
  // Looks along -x from (5, 0, 0): camera z axis = world -x.
  side.cam_from_world.rotation << 0, 0, 1, 0, 1, 0, -1, 0, 0;
  side.cam_from_world.translation = -side.cam_from_world.rotation * Eigen::Vector3d(5, 0, 0);
  scene.views = {front, side};
  scene.points.push_back({Eigen::Vector3d(1, 2, 3), {}, {{0, {1, 1}}, {1, {2, 2}}}});
  return scene;
}

TEST(SceneInfoTest, SummarizesByHand) {
  const auto root = testing::MakeTempDir();
  std::ofstream(root / "front.png") << "x";
  const Scene scene = MakeScene(root);
  const SceneInfo info = ComputeSceneInfo(scene, "scene", "colmap");
  EXPECT_EQ(info.num_views, 2);
  EXPECT_EQ(info.cameras_per_model.at("PINHOLE"), 1);
  EXPECT_EQ(info.cameras_per_model.at("SIMPLE_RADIAL"), 1);
  EXPECT_EQ(info.min_width, 40);
  EXPECT_EQ(info.max_height, 60);
  ASSERT_TRUE(info.camera_centers.has_value());
  EXPECT_TRUE(info.camera_centers->min.isApprox(Eigen::Vector3d(0, 0, -5)));
  EXPECT_TRUE(info.camera_centers->max.isApprox(Eigen::Vector3d(5, 0, 0)));
  EXPECT_EQ(info.num_observations, 2u);
  // The optical axes (z axis and x axis lines) meet at the origin.
  ASSERT_TRUE(info.axes_meeting_point.has_value());
  EXPECT_LT(info.axes_meeting_point->norm(), 1e-12);
  EXPECT_EQ(info.cameras_facing_meeting_point, 2);
  EXPECT_EQ(info.missing_images, std::vector<std::string>{"side.png"});
  EXPECT_THAT(FormatSceneInfo(info),
              HasSubstr("missing:      1 of 2 images not found on disk\n  side.png"));
  const auto json = SceneInfoToJson(info);
  EXPECT_EQ(json["views"], 2);
  EXPECT_EQ(json["resolution"]["max"], nlohmann::json({80, 60}));
  EXPECT_EQ(json["missing_images"][0], "side.png");
}

TEST(SceneInfoTest, ParallelAxesHaveNoMeetingPoint) {
  Scene scene = MakeScene(testing::MakeTempDir());
  scene.views[1].cam_from_world = scene.views[0].cam_from_world;
  scene.views[1].cam_from_world.translation.x() = 1;  // same direction, shifted
  EXPECT_FALSE(PointNearestToOpticalAxes(scene).has_value());
}

}  // namespace
}  // namespace rephoto::scene
