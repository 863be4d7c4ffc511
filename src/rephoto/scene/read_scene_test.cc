#include "rephoto/scene/read_scene.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"
#include "rephoto/testing/testing.h"

namespace rephoto::scene {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

fs::path Data(const std::string& relative) { return testing::SharedDataDir() / relative; }

using testing::ErrorOf;

TEST(ReadSceneTest, FormatNames) {
  for (SceneFormat format :
       {SceneFormat::kColmap, SceneFormat::kTransforms, SceneFormat::kCamerasJson,
        SceneFormat::kBundler, SceneFormat::kMiddlebury, SceneFormat::kStrecha, SceneFormat::kMve,
        SceneFormat::kMvsTexturing}) {
    EXPECT_EQ(ParseSceneFormat(SceneFormatName(format)), format);
  }
  EXPECT_FALSE(ParseSceneFormat("ply").has_value());
  EXPECT_EQ(SceneFormatList(),
            "colmap, transforms, cameras-json, bundler, middlebury, strecha, mve, mvs-texturing");
}

// Every dataset in ../shared/data loads through the one entry point, with the format detected
// from the folder.
TEST(ReadSceneTest, EverySharedDatasetLoads) {
  REPHOTO_REQUIRE_DATA("bundler_kermit");
  struct Case {
    std::string path;
    SceneFormat format;
    size_t views;
    size_t missing;
    std::optional<std::string> image_root;
  };
  const std::vector<Case> cases = {
      {"bundler_kermit", SceneFormat::kBundler, 9, 0, {}},
      {"instant_ngp_fox", SceneFormat::kTransforms, 67, 17, {}},
      {"llff_fern/sparse_text_images_8_derived", SceneFormat::kColmap, 20, 0, "llff_fern/images_8"},
      {"middlebury_temple_dino/templeSparseRing", SceneFormat::kMiddlebury, 16, 0, {}},
      {"middlebury_temple_dino/dinoSparseRing", SceneFormat::kMiddlebury, 16, 0, {}},
      {"openmvs_sceaux/colmap_text_derived", SceneFormat::kColmap, 11, 1, {}},
      {"strecha_fountain_p11", SceneFormat::kStrecha, 11, 0, {}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.path);
    if (!fs::exists(Data(c.path))) continue;
    ReadSceneOptions options;
    if (c.image_root) options.image_root = Data(*c.image_root);
    SceneSource source;
    const Scene scene = ReadScene(Data(c.path), options, &source);
    EXPECT_EQ(source.format, c.format);
    EXPECT_EQ(scene.views.size(), c.views);
    EXPECT_EQ(MissingImages(scene).size(), c.missing);
  }
}

TEST(ReadSceneTest, DetectsFromFilesAndSubfolders) {
  REPHOTO_REQUIRE_DATA("bundler_kermit");
  const SceneSource bundle = DetectSceneFormat(Data("bundler_kermit/results.example/bundle.out"));
  EXPECT_EQ(bundle.format, SceneFormat::kBundler);
  const SceneSource strecha = DetectSceneFormat(Data("strecha_fountain_p11"));
  EXPECT_EQ(strecha.format, SceneFormat::kStrecha);
  EXPECT_EQ(strecha.path, Data("strecha_fountain_p11/gt_dense_cameras"));
  const SceneSource par = DetectSceneFormat(Data("middlebury_temple_dino/templeSparseRing"));
  EXPECT_EQ(par.path, Data("middlebury_temple_dino/templeSparseRing/templeSR_par.txt"));
  const SceneSource colmap =
      DetectSceneFormat(Data("openmvs_sceaux/colmap_text_derived/images.txt"));
  EXPECT_EQ(colmap.format, SceneFormat::kColmap);
  EXPECT_EQ(colmap.path, Data("openmvs_sceaux/colmap_text_derived"));
}

TEST(ReadSceneTest, UndetectableFolderListsFormats) {
  const fs::path empty = testing::MakeTempDir();
  EXPECT_THAT(
      ErrorOf([&] { DetectSceneFormat(empty); }),
      AllOf(HasSubstr(empty.string() + ": cannot detect the scene format"), HasSubstr("*_par.txt"),
            HasSubstr("pass --format with one of: colmap, transforms, cameras-json, bundler")));
  EXPECT_THAT(ErrorOf([&] { DetectSceneFormat(empty / "nothing"); }),
              HasSubstr("no such file or folder"));
  EXPECT_THAT(ErrorOf([&] { ReadScene(empty, {.format = SceneFormat::kMve}); }),
              HasSubstr(": no mve scene here (looked for views/view_XXXX.mve)"));
}

TEST(ReadSceneTest, FormatOverrideWins) {
  // A folder that holds both a .cam and a *_par.txt scene: detection picks Middlebury (first
  // in order), --format mvs-texturing reads the .cam files.
  const fs::path root = testing::MakeTempDir();
  io::WritePng(root / "a.png", Image(40, 30, 3));
  WriteTextFileAtomically(root / "x_par.txt",
                          "1\na.png 50 0 20 0 50 15 0 0 1 1 0 0 0 1 0 0 0 1 0 0 1\n");
  WriteTextFileAtomically(root / "a.cam", "0 0 1 1 0 0 0 1 0 0 0 1\n1.25 0 0 1 0.5 0.5\n");
  SceneSource source;
  ReadScene(root, {}, &source);
  EXPECT_EQ(source.format, SceneFormat::kMiddlebury);
  const Scene scene = ReadScene(root, {.format = SceneFormat::kMvsTexturing}, &source);
  EXPECT_EQ(source.format, SceneFormat::kMvsTexturing);
  EXPECT_EQ(scene.CameraOf(scene.views[0]).params, (std::vector<double>{50, 50, 20, 15}));
}

TEST(ReadSceneTest, ImageSizeMismatchNamesImageAndCamera) {
  const fs::path root = testing::MakeTempDir();
  io::WritePng(root / "a.png", Image(40, 30, 3));
  WriteTextFileAtomically(root / "a.jpg.camera",
                          "50 0 20\n0 50 15\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n41 30\n");
  // The .camera file names image a.jpg, which does not exist: listed as missing, no error.
  std::filesystem::copy_file(root / "a.png", root / "b.png");
  EXPECT_THAT(ErrorOf([&] { ReadScene(root); }), HasSubstr("a.jpg of a.jpg.camera not found"));
  WriteTextFileAtomically(root / "a.png.camera",
                          "50 0 20\n0 50 15\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n41 30\n");
  fs::remove(root / "a.jpg.camera");
  EXPECT_THAT(ErrorOf([&] { ReadScene(root); }),
              HasSubstr((root / "a.png").string() + ": image is 40x30 but camera 1 of"));
  const Scene scene = ReadScene(root, {.check_image_sizes = false});
  EXPECT_EQ(scene.views.size(), 1u);
}

TEST(ReadSceneTest, ValidateSceneCatchesBrokenLinks) {
  Scene scene;
  camera::Camera camera;
  camera.model = camera::CameraModel::kPinhole;
  camera.width = 10;
  camera.height = 10;
  camera.params = {10, 10, 5, 5};
  scene.cameras[1] = camera;
  scene.views.push_back({"a.png", "a.png", std::nullopt, 1, {}});
  EXPECT_NO_THROW(ValidateScene(scene, "scene"));
  scene.views.push_back({"b.png", "b.png", std::nullopt, 2, {}});
  EXPECT_THAT(ErrorOf([&] { ValidateScene(scene, "scene"); }),
              HasSubstr("scene: view 1 (b.png): camera id 2 does not exist"));
  scene.views[1].camera_id = 1;
  scene.views[1].name = "a.png";
  EXPECT_THAT(ErrorOf([&] { ValidateScene(scene, "scene"); }),
              HasSubstr("image name used by two views"));
  scene.views[1].name = "b.png";
  scene.points.push_back({Eigen::Vector3d(0, 0, 1), {}, {{5, Eigen::Vector2d(1, 1)}}});
  EXPECT_THAT(ErrorOf([&] { ValidateScene(scene, "scene"); }),
              HasSubstr("scene: point 0 is observed in view 5, which does not exist"));
  scene.points[0].track[0].view_index = 0;
  scene.views[0].cam_from_world.rotation(0, 0) = std::nan("");
  EXPECT_THAT(ErrorOf([&] { ValidateScene(scene, "scene"); }), HasSubstr("scene: view 0 (a.png)"));
}

}  // namespace
}  // namespace rephoto::scene
