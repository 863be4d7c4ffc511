#include "rephoto/scene/cameras_json.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/testing/testing.h"

namespace rephoto::scene {
namespace {

using ::testing::HasSubstr;

// A camera at centre (1, 2, 3) looking along world +x (camera z = world x, camera x = world -y,
// camera y = world -z): camera-to-world rotation columns are the camera axes.
constexpr char kCameras[] = R"([
 {"id": 0, "img_name": "a", "width": 40, "height": 30, "position": [1, 2, 3],
  "rotation": [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], "fy": 50.5, "fx": 50},
 {"id": 1, "img_name": "b", "width": 40, "height": 30, "position": [0, 0, 0],
  "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "fy": 50.5, "fx": 50}
])";

std::string ErrorOf(const std::string& text) {
  std::istringstream in(text);
  return testing::ErrorOf([&] { ReadCamerasJson(in, "cameras.json", "/images"); });
}

TEST(CamerasJsonTest, PosesIntrinsicsAndNames) {
  std::istringstream in(kCameras);
  const Scene scene = ReadCamerasJson(in, "cameras.json", "/images");
  ASSERT_EQ(scene.views.size(), 2u);
  ASSERT_EQ(scene.cameras.size(), 1u);  // identical intrinsics are shared
  const camera::Camera& camera = scene.CameraOf(scene.views[0]);
  EXPECT_EQ(camera.model, camera::CameraModel::kPinhole);
  EXPECT_EQ(camera.params, (std::vector<double>{50, 50.5, 20, 15}));
  const camera::Pose& pose = scene.views[0].cam_from_world;
  EXPECT_TRUE(pose.Center().isApprox(Eigen::Vector3d(1, 2, 3)));
  // A point one unit ahead (world +x) is on the optical axis at depth 1.
  EXPECT_TRUE(pose.CamFromWorld(Eigen::Vector3d(2, 2, 3)).isApprox(Eigen::Vector3d(0, 0, 1)));
  // World -y is camera +x.
  EXPECT_TRUE(pose.CamFromWorld(Eigen::Vector3d(1, 1, 4)).isApprox(Eigen::Vector3d(1, -1, 0)));
  EXPECT_EQ(scene.views[0].name, "a");  // no image on disk: the name as stored
  EXPECT_EQ(scene.views[1].image_path, std::filesystem::path("/images/b"));
}

TEST(CamerasJsonTest, Errors) {
  EXPECT_THAT(ErrorOf("{}"), HasSubstr("cameras.json: expected a JSON array"));
  EXPECT_THAT(ErrorOf("[{\"img_name\": \"a\"}]"),
              HasSubstr("cameras.json: [0]: missing \"width\""));
  EXPECT_THAT(ErrorOf(R"([{"img_name": "a", "width": 4, "height": 3, "fx": 1, "fy": 1,
      "position": [0, 0, 0], "rotation": [[1, 0], [0, 1]]}])"),
              HasSubstr("[0].rotation: expected 3 rows of 3 numbers"));
  EXPECT_THAT(ErrorOf(R"([{"img_name": "a", "width": 4, "height": 3, "fx": 1, "fy": 1,
      "position": [0, 0, 0], "rotation": [[2, 0, 0], [0, 1, 0], [0, 0, 1]]}])"),
              HasSubstr("cameras.json: [0]"));
  EXPECT_THAT(ErrorOf("[1, 2"), HasSubstr("invalid JSON"));
}

// A 3DGS output folder: cameras.json + cfg_args pointing at the source images.
TEST(CamerasJsonTest, DetectedInOutputFolderWithImagesFromCfgArgs) {
  const std::filesystem::path root = testing::MakeTempDir();
  std::filesystem::create_directories(root / "data" / "images_4");
  std::filesystem::create_directories(root / "output");
  std::ofstream(root / "data" / "images_4" / "a.JPG") << "not read";
  std::ofstream(root / "output" / "cameras.json") << kCameras;
  std::ofstream(root / "output" / "cfg_args")
      << "Namespace(data_device='cuda', eval=True, images='images_4', model_path='./output', "
         "resolution=-1, sh_degree=3, source_path='"
      << (root / "data").string() << "', white_background=False)";
  SceneSource source;
  ReadSceneOptions options;
  options.check_image_sizes = false;
  const Scene scene = ReadScene(root / "output", options, &source);
  EXPECT_EQ(source.format, SceneFormat::kCamerasJson);
  EXPECT_EQ(scene.views[0].name, "a.JPG");
  EXPECT_EQ(scene.views[0].image_path, root / "data" / "images_4" / "a.JPG");
  EXPECT_EQ(scene.views[1].name, "b");
  EXPECT_TRUE(IsCamerasJsonFile(root / "output" / "cameras.json"));
  // The file itself is detected too, and a transforms.json object is not taken for it.
  EXPECT_EQ(DetectSceneFormat(root / "output" / "cameras.json").format, SceneFormat::kCamerasJson);
  std::ofstream(root / "transforms.json") << R"({"frames": []})";
  EXPECT_FALSE(IsCamerasJsonFile(root / "transforms.json"));
}

}  // namespace
}  // namespace rephoto::scene
