#include "rephoto/scene/mve.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"
#include "rephoto/scene/mvs_texturing_cam.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/testing/testing.h"

namespace rephoto::scene {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A known landscape camera: 64x48 image, fx = 80, fy = 88 (pixel aspect 1.1), principal point
// (30, 26) in pixel-corner coordinates. MVE normalizes by max(w, h) = 64 and by (w, h).
constexpr const char* kLandscapeMeta = R"(# MVE view meta data is stored in INI-file syntax.
[camera]
focal_length = 1.25
pixel_aspect = 1.1
principal_point = 0.46875 0.541666666666666667
radial_distortion = 0 0
rotation = 0 1 0 -1 0 0 0 0 1
translation = 1 2 3

[view]
id = 7
name = IMG_0007.JPG
)";

std::string ErrorOf(const std::string& text) {
  std::istringstream in(text);
  return testing::ErrorOf([&] { ReadMveMetaIni(in, "meta.ini"); });
}

void WriteBlankPng(const fs::path& path, int width, int height) {
  io::WritePng(path, Image(width, height, 3));
}

TEST(MveTest, MetaIniToCamera) {
  std::istringstream in(kLandscapeMeta);
  const MveViewMeta meta = ReadMveMetaIni(in, "meta.ini");
  EXPECT_EQ(meta.id, 7);
  EXPECT_EQ(meta.name, "IMG_0007.JPG");
  ASSERT_TRUE(meta.intrinsics.has_value());
  const camera::Camera camera = MveCamera(*meta.intrinsics, 64, 48, false, "meta.ini");
  EXPECT_EQ(camera.model, camera::CameraModel::kPinhole);
  ASSERT_EQ(camera.params.size(), 4u);
  EXPECT_DOUBLE_EQ(camera.params[0], 80.0);
  EXPECT_DOUBLE_EQ(camera.params[1], 88.0);
  EXPECT_DOUBLE_EQ(camera.params[2], 30.0);
  EXPECT_DOUBLE_EQ(camera.params[3], 26.0);
  EXPECT_TRUE(meta.cam_from_world.rotation.isApprox(
      (Eigen::Matrix3d() << 0, 1, 0, -1, 0, 0, 0, 0, 1).finished()));
  EXPECT_EQ(meta.cam_from_world.translation, Eigen::Vector3d(1, 2, 3));
}

TEST(MveTest, PortraitAndDistortion) {
  // Portrait 48x64, f normalized by 64: fy = f * height (MVE's fill_calibration).
  MveIntrinsics intrinsics;
  intrinsics.focal_length = 1.0;
  intrinsics.radial_distortion = {-0.1, 0.02};
  const camera::Camera camera = MveCamera(intrinsics, 48, 64, true, "test");
  EXPECT_EQ(camera.model, camera::CameraModel::kRadial);
  EXPECT_EQ(camera.params, (std::vector<double>{64, 24, 32, -0.1, 0.02}));
  // Pixel aspect 1.25: 48 / 64 * 1.25 < 1 is still portrait, fy = 64, fx = fy / 1.25.
  intrinsics.pixel_aspect = 1.25;
  const camera::Camera opencv = MveCamera(intrinsics, 48, 64, true, "test");
  EXPECT_EQ(opencv.model, camera::CameraModel::kOpenCv);
  EXPECT_DOUBLE_EQ(opencv.params[0], 51.2);
  EXPECT_EQ(std::vector<double>(opencv.params.begin() + 1, opencv.params.end()),
            (std::vector<double>{64, 24, 32, -0.1, 0.02, 0, 0}));
  // Pixel aspect 2: 48 / 64 * 2 >= 1 counts as landscape in MVE: fx = f * width, fy = 2 fx.
  intrinsics.pixel_aspect = 2.0;
  const camera::Camera wide = MveCamera(intrinsics, 48, 64, true, "test");
  EXPECT_EQ(wide.params, (std::vector<double>{48, 96, 24, 32, -0.1, 0.02, 0, 0}));
}

TEST(MveTest, BadMetaIni) {
  EXPECT_THAT(
      ErrorOf(testing::Replace(kLandscapeMeta, "focal_length = 1.25", "focal_length = nan")),
      HasSubstr("meta.ini:3: camera.focal_length is not finite"));
  EXPECT_THAT(ErrorOf(testing::Replace(kLandscapeMeta, "0 1 0 -1 0 0 0 0 1", "0 1 0 -1 0 0 0 0 2")),
              AllOf(HasSubstr("meta.ini:7"), HasSubstr("not a rotation")));
  EXPECT_THAT(ErrorOf(testing::Replace(kLandscapeMeta, "translation = 1 2 3", "translation = 1 2")),
              HasSubstr("meta.ini:8: expected 3 values (camera.translation), got 2"));
  EXPECT_THAT(ErrorOf(testing::Replace(kLandscapeMeta, "translation = 1 2 3\n", "")),
              HasSubstr("meta.ini: [camera] has no translation"));
  EXPECT_THAT(ErrorOf(testing::Replace(kLandscapeMeta, "[view]", "[view")),
              HasSubstr("meta.ini:10: malformed section header"));
  EXPECT_THAT(ErrorOf(testing::Replace(kLandscapeMeta, "id = 7", "id 7")),
              HasSubstr("meta.ini:11: expected 'key = value'"));
  EXPECT_THAT(ErrorOf(testing::Replace(kLandscapeMeta, "pixel_aspect = 1.1", "pixel_aspect = 0")),
              HasSubstr("not positive"));
}

TEST(MveTest, ReadsSceneFolder) {
  const fs::path root = testing::MakeTempDir();
  const fs::path view0 = root / "views" / "view_0000.mve";
  const fs::path view1 = root / "views" / "view_0001.mve";
  const fs::path view2 = root / "views" / "view_0002.mve";
  WriteTextFileAtomically(view0 / "meta.ini", kLandscapeMeta);
  WriteBlankPng(view0 / "undistorted.png", 64, 48);
  WriteBlankPng(view0 / "original.png", 64, 48);
  WriteTextFileAtomically(view1 / "meta.ini", "[view]\nid = 1\nname = unregistered\n");
  WriteTextFileAtomically(
      view2 / "meta.ini",
      testing::Replace(kLandscapeMeta, "radial_distortion = 0 0", "radial_distortion = -0.2 0.05"));
  WriteBlankPng(view2 / "original.png", 64, 48);
  const Scene scene = ReadMveScene(root);
  ASSERT_EQ(scene.views.size(), 2u);
  EXPECT_EQ(scene.image_root, root / "views");
  EXPECT_EQ(scene.views[0].name, "view_0000.mve/undistorted.png");
  EXPECT_EQ(scene.views[0].image_path, view0 / "undistorted.png");
  EXPECT_EQ(scene.CameraOf(scene.views[0]).model, camera::CameraModel::kPinhole);
  EXPECT_EQ(scene.views[1].name, "view_0002.mve/original.png");
  const camera::Camera& distorted = scene.CameraOf(scene.views[1]);
  EXPECT_EQ(distorted.model, camera::CameraModel::kOpenCv);  // pixel aspect 1.1
  EXPECT_DOUBLE_EQ(distorted.params[4], -0.2);

  // Detected by the one entry point from the scene folder, the views folder or a meta.ini.
  for (const fs::path& path : {root, root / "views", view2 / "meta.ini"}) {
    SceneSource source;
    EXPECT_EQ(ReadScene(path, {}, &source).views.size(), 2u) << path;
    EXPECT_EQ(source.format, SceneFormat::kMve);
    EXPECT_EQ(source.path, root);
  }
}

// mvs-texturing .cam: the same intrinsics, written as "f d0 d1 paspect ppx ppy".
TEST(MvsTexturingCamTest, ReadsCamFilesNextToImages) {
  const fs::path root = testing::MakeTempDir();
  WriteTextFileAtomically(root / "a.cam",
                          "1 2 3 0 1 0 -1 0 0 0 0 1\n1.25 0 0 1.1 0.46875 0.541666666666666667\n");
  WriteBlankPng(root / "a.png", 64, 48);
  const Scene scene = ReadMvsTexturingScene(root);
  ASSERT_EQ(scene.views.size(), 1u);
  EXPECT_EQ(scene.views[0].name, "a.png");
  const camera::Camera& camera = scene.CameraOf(scene.views[0]);
  EXPECT_EQ(camera.model, camera::CameraModel::kPinhole);
  EXPECT_DOUBLE_EQ(camera.params[0], 80.0);
  EXPECT_DOUBLE_EQ(camera.params[1], 88.0);
  EXPECT_DOUBLE_EQ(camera.params[2], 30.0);
  EXPECT_DOUBLE_EQ(camera.params[3], 26.0);
  EXPECT_EQ(scene.views[0].cam_from_world.translation, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(scene.views[0].cam_from_world.Center(), Eigen::Vector3d(2, -1, -3));
}

TEST(MvsTexturingCamTest, BadInput) {
  auto error_of = [](const std::string& text) -> std::string {
    try {
      std::istringstream in(text);
      ReadMvsTexturingCam(in, "a.cam");
    } catch (const Error& e) {
      return e.what();
    }
    return "(no error)";
  };
  EXPECT_THAT(error_of("1 2 3 1 0 0 0 1 0 0 0 1\n"),
              HasSubstr("a.cam:2: unexpected end of file, expected the intrinsics line"));
  EXPECT_THAT(error_of("1 2 3 1 0 0 0 1 0 0 0\n1 0 0 1 0.5 0.5\n"),
              HasSubstr("a.cam:1: expected 12 values"));
  EXPECT_THAT(error_of("1 2 3 1 0 0 0 1 0 0 0 1\n-1 0 0 1 0.5 0.5\n"),
              HasSubstr("a.cam:2: focal length -1 is not positive"));
  EXPECT_THAT(error_of("1 2 3 1 0 0 0 1 0 0 0 1\n1 0 0 1 inf 0.5\n"),
              HasSubstr("a.cam:2: intrinsics is not finite"));
  EXPECT_THAT(error_of("1 2 3 2 0 0 0 1 0 0 0 1\n1 0 0 1 0.5 0.5\n"),
              AllOf(HasSubstr("a.cam:1"), HasSubstr("not a rotation")));
  EXPECT_THAT(error_of("1 2 3 1 0 0 0 1 0 0 0 1\n1 0 0 1 0.5 0.5\n7\n"),
              HasSubstr("a.cam:3: unexpected data"));
}

}  // namespace
}  // namespace rephoto::scene
