#include "rephoto/split/split_writer.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/transforms_json.h"
#include "rephoto/testing/testing.h"

namespace rephoto::split {
namespace {

namespace fs = std::filesystem;
using ::testing::ElementsAre;

// Four photos on disk (8x6 PNGs), two cameras, three points:
//   point 0 seen by a, b, c; point 1 seen by a and d; point 2 without a track.
scene::Scene MakeScene(const fs::path& root) {
  scene::Scene scene;
  scene.image_root = root / "photos";
  camera::Camera pinhole;
  pinhole.model = camera::CameraModel::kPinhole;
  pinhole.width = 8;
  pinhole.height = 6;
  pinhole.params = {10, 11, 4, 3};
  camera::Camera radial = pinhole;
  radial.model = camera::CameraModel::kRadial;
  radial.params = {10, 4, 3, 0.01, -0.002};
  scene.cameras[1] = pinhole;
  scene.cameras[2] = radial;
  const char* names[] = {"a.png", "b.png", "c.png", "d.png"};
  for (int i = 0; i < 4; ++i) {
    scene::View view;
    view.name = names[i];
    view.image_path = scene.image_root / view.name;
    view.camera_id = i < 2 ? 1 : 2;
    view.cam_from_world.translation = Eigen::Vector3d(0.1 * i, 0, 2);
    io::WritePng(view.image_path, Image(8, 6, 3));
    scene.views.push_back(view);
  }
  scene.points.push_back({{0, 0, 0}, {1, 2, 3}, {{0, {1, 1}}, {1, {2, 2}}, {2, {3, 3}}}});
  scene.points.push_back({{1, 0, 0}, {4, 5, 6}, {{0, {4, 4}}, {3, {5, 5}}}});
  scene.points.push_back({{0, 1, 0}, {7, 8, 9}, {}});
  return scene;
}

TEST(SplitWriterTest, SubsetRestrictsPointsToTrainingObservations) {
  const fs::path root = testing::MakeTempDir();
  const scene::Scene scene = MakeScene(root);
  const scene::Scene train = SubsetScene(scene, {"a.png", "b.png", "d.png"}, true);
  ASSERT_EQ(train.views.size(), 3u);
  EXPECT_EQ(train.views[2].name, "d.png");
  EXPECT_EQ(train.cameras.size(), 2u);
  ASSERT_EQ(train.points.size(), 2u);                 // point 2 has no track: dropped
  EXPECT_EQ(train.points[0].track.size(), 2u);        // c.png is not a training view
  EXPECT_EQ(train.points[1].track[1].view_index, 2);  // d.png is now view 2
  const scene::Scene only_c = SubsetScene(scene, {"c.png"}, true);
  EXPECT_TRUE(only_c.points.empty());
  EXPECT_EQ(only_c.cameras.size(), 1u);
  EXPECT_THROW(SubsetScene(scene, {"x.png"}, true), Error);
}

TEST(SplitWriterTest, WritesFoldsThatExternalToolsRead) {
  const fs::path root = testing::MakeTempDir();
  const scene::Scene scene = MakeScene(root);
  std::vector<std::string> names;
  for (const auto& view : scene.views) names.push_back(view.name);
  const Split split = MakeSplit(names, ParseScheme("kfold:2:1"));
  const fs::path out = root / "split";
  const auto folders = WriteSplit(scene, split, {"scene/path", "colmap"}, out);
  ASSERT_EQ(folders.size(), 2u);
  EXPECT_EQ(folders[1], out / "fold_01");

  const auto json = nlohmann::json::parse(ReadFileToString(out / "split.json"));
  EXPECT_EQ(json["scheme"], "kfold:2:1");
  EXPECT_EQ(json["seed"], 1);
  EXPECT_EQ(json["cross_validated"], true);
  EXPECT_EQ(json["num_folds"], 2);
  EXPECT_EQ(json["image_root"], (root / "photos").string());
  EXPECT_EQ(json["transforms_json"], true);

  for (size_t f = 0; f < 2; ++f) {
    const fs::path folder = folders[f];
    std::string expected_test;
    for (const auto& name : split.folds[f].test) expected_test += name + "\n";
    EXPECT_EQ(ReadFileToString(folder / "test.txt"), expected_test);
    EXPECT_EQ(json["folds"][f]["test"], split.folds[f].test);

    // COLMAP text model of the training views, names relative to the image root.
    const scene::Scene train =
        scene::ReadColmap(folder / "train" / "sparse", {.image_root = scene.image_root});
    ASSERT_EQ(train.views.size(), split.folds[f].train.size());
    for (const auto& view : train.views) {
      EXPECT_TRUE(fs::exists(view.image_path)) << view.image_path;
      const auto& original = *std::find_if(scene.views.begin(), scene.views.end(),
                                           [&](const auto& v) { return v.name == view.name; });
      EXPECT_TRUE(view.cam_from_world.translation.isApprox(original.cam_from_world.translation));
      EXPECT_EQ(train.CameraOf(view), scene.CameraOf(original));
    }
    for (const auto& point : train.points) EXPECT_GE(point.track.size(), 2u);
    EXPECT_EQ(json["folds"][f]["train_points"], train.points.size());

    // transforms.json: file_path resolves to the original photos.
    const scene::Scene test =
        scene::ReadTransformsJson(folder / "test" / "transforms.json", scene.image_root);
    ASSERT_EQ(test.views.size(), split.folds[f].test.size());
    for (const auto& view : test.views) {
      EXPECT_EQ(fs::weakly_canonical(view.image_path),
                fs::weakly_canonical(scene.image_root / fs::path(view.image_path).filename()));
    }
    EXPECT_TRUE(scene::ReadColmap(folder / "test" / "sparse", {.image_root = scene.image_root})
                    .points.empty());
  }
}

// issue 30: the test list a "--split DIR" names: a fold folder's, the only fold's, else an
// error naming the folder and its folds.
TEST(SplitWriterTest, SplitTestListOfAFoldOrASingleFoldSplit) {
  const fs::path root = testing::MakeTempDir();
  const scene::Scene scene = MakeScene(root);
  std::vector<std::string> names;
  for (const auto& view : scene.views) names.push_back(view.name);
  WriteSplit(scene, MakeSplit(names, ParseScheme("every:2")), {"s", "colmap"}, root / "one");
  WriteSplit(scene, MakeSplit(names, ParseScheme("kfold:2")), {"s", "colmap"}, root / "two");
  EXPECT_EQ(SplitTestList(root / "one"), root / "one/fold_00/test.txt");
  EXPECT_EQ(SplitTestList(root / "one/fold_00"), root / "one/fold_00/test.txt");
  EXPECT_EQ(SplitTestList(root / "two/fold_01"), root / "two/fold_01/test.txt");
  try {
    SplitTestList(root / "two");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), (root / "two").string() +
                                         ": the split has 2 folds (fold_00 ... fold_01); name the "
                                         "fold's folder, e.g. " +
                                         (root / "two/fold_00").string());
  }
  EXPECT_THROW(SplitTestList(root / "photos"), Error);   // no split
  EXPECT_THROW(SplitTestList(root / "nothing"), Error);  // no folder
}

}  // namespace
}  // namespace rephoto::split
