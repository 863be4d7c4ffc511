// The image-name rule of every scene format (scene/image_name.h): names are relative, normal and
// stay inside the image root; hostile names are refused by the readers with file and line.
#include "rephoto/scene/image_name.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>

#include "rephoto/core/error.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/testing/testing.h"

namespace rephoto::scene {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using testing::ErrorOf;

TEST(ImageName, NormalNamesPassUnchanged) {
  for (const char* name : {"a.jpg", "images/a.jpg", "cam0/000001.png", "a b.JPG", "..a.png",
                           "a..png", "ünïcode/ä.png", ".hidden.png"}) {
    EXPECT_EQ(CheckedImageName(name, "f:1"), name);
  }
}

TEST(ImageName, HarmlessSpellingsAreNormalised) {
  EXPECT_EQ(CheckedImageName("./train/r_0.png", "f"), "train/r_0.png");
  EXPECT_EQ(CheckedImageName("././a.png", "f"), "a.png");
  EXPECT_EQ(CheckedImageName("a//b/./c.png", "f"), "a/b/c.png");
}

TEST(ImageName, HostileNamesAreRefusedWithWhereAndWhy) {
  EXPECT_EQ(ErrorOf([] { CheckedImageName("../../../../X/secret.png", "images.txt:7"); }),
            "images.txt:7: image name '../../../../X/secret.png' contains '..'; names must stay "
            "inside the image root");
  EXPECT_THAT(ErrorOf([] { CheckedImageName("a/../b.png", "f"); }), HasSubstr("contains '..'"));
  EXPECT_THAT(ErrorOf([] { CheckedImageName("a/..", "f"); }), HasSubstr("contains '..'"));
  EXPECT_THAT(ErrorOf([] { CheckedImageName("/etc/passwd", "f"); }),
              HasSubstr("is an absolute path"));
  EXPECT_THAT(ErrorOf([] { CheckedImageName("//etc/passwd", "f"); }),
              HasSubstr("is an absolute path"));
  EXPECT_THAT(ErrorOf([] { CheckedImageName("..\\x.png", "f"); }), HasSubstr("backslash"));
  EXPECT_THAT(ErrorOf([] { CheckedImageName("images/", "f"); }), HasSubstr("ends in '/'"));
  EXPECT_THAT(ErrorOf([] { CheckedImageName("./.", "f"); }), HasSubstr("names no file"));
  EXPECT_THAT(ErrorOf([] { CheckedImageName("", "f"); }), HasSubstr("is empty"));
  const std::string with_newline = "a\nb.png";
  EXPECT_EQ(ErrorOf([&] { CheckedImageName(with_newline, "f"); }),
            "f: image name 'a\\x0ab.png' contains a control character");
  EXPECT_THAT(ErrorOf([] { CheckedImageName(std::string("a\0b", 3), "f"); }),
              HasSubstr("control character"));
}

TEST(ImageName, ColmapTextNamesAreCheckedWithFileAndLine) {
  const fs::path dir = testing::MakeTempDir();
  testing::WriteFile(dir / "sparse/cameras.txt", "1 PINHOLE 64 48 50 50 32 24\n");
  testing::WriteFile(dir / "sparse/points3D.txt", "");
  testing::WriteFile(
      dir / "sparse/images.txt",
      "# comment\n1 1 0 0 0 0 0 0 1 a.png\n\n2 1 0 0 0 0 0 0 1 ../../../../X/secret.png\n\n");
  const std::string error = ErrorOf([&] { ReadScene(dir / "sparse"); });
  EXPECT_THAT(error, HasSubstr("images.txt:4"));
  EXPECT_THAT(error, HasSubstr("image name '../../../../X/secret.png' contains '..'"));
  EXPECT_EQ(error.find('\n'), std::string::npos);
}

TEST(ImageName, TransformsJsonPathsAreCheckedBeforeAnyFileIsRead) {
  const fs::path dir = testing::MakeTempDir();
  const std::string frame = R"("transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]])";
  testing::WriteFile(dir / "transforms.json",
                     R"({"fl_x": 50, "fl_y": 50, "cx": 32, "cy": 24, "w": 64, "h": 48, "frames": [)"
                     R"({"file_path": "/etc/passwd", )" +
                         frame + "}]}");
  EXPECT_THAT(ErrorOf([&] { ReadScene(dir / "transforms.json"); }),
              HasSubstr("frames[0].file_path: image name '/etc/passwd' is an absolute path"));
  testing::WriteFile(dir / "transforms.json",
                     R"({"fl_x": 50, "fl_y": 50, "cx": 32, "cy": 24, "w": 64, "h": 48, "frames": [)"
                     R"({"file_path": "a.png", "mask_path": "../../m", )" +
                         frame + "}]}");
  EXPECT_THAT(ErrorOf([&] { ReadScene(dir / "transforms.json"); }),
              HasSubstr("frames[0].mask_path: image name '../../m' contains '..'"));
  testing::WriteFile(dir / "transforms.json",
                     R"({"fl_x": 50, "fl_y": 50, "cx": 32, "cy": 24, "w": 64, "h": 48, "frames": [)"
                     R"({"file_path": "./train/a.png", )" +
                         frame + "}]}");
  EXPECT_EQ(ReadScene(dir / "transforms.json", {.check_image_sizes = false}).views[0].name,
            "train/a.png");
}

TEST(ImageName, TwoSpellingsOfOneNameAreOneViewTwice) {
  const fs::path dir = testing::MakeTempDir();
  testing::WriteFile(dir / "sparse/cameras.txt", "1 PINHOLE 64 48 50 50 32 24\n");
  testing::WriteFile(dir / "sparse/points3D.txt", "");
  testing::WriteFile(dir / "sparse/images.txt",
                     "1 1 0 0 0 0 0 0 1 a.png\n\n2 1 0 0 0 0 0 0 1 ./a.png\n\n");
  EXPECT_THAT(ErrorOf([&] { ReadScene(dir / "sparse"); }),
              HasSubstr("image name 'a.png' is used twice"));
}

Scene SceneOf(const std::vector<std::string>& names) {
  Scene scene;
  for (const std::string& name : names) scene.views.push_back({.name = name});
  return scene;
}

TEST(ImageName, OutputStemsAreDistinct) {
  EXPECT_EQ(OutputStems(SceneOf({"images/a.jpg", "images/b.jpg"})),
            (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(OutputStems(SceneOf({"cam0/000.png", "cam1/000.png", "x.png"})),
            (std::vector<std::string>{"cam0/000", "cam1/000", "x"}));
  EXPECT_EQ(OutputStems(SceneOf({"a.jpg", "a.png", "b.png"})),
            (std::vector<std::string>{"a.jpg", "a.png", "b.png"}));
  EXPECT_EQ(OutputStems(SceneOf({"d/a.jpg", "d/a.png"})),
            (std::vector<std::string>{"d/a.jpg", "d/a.png"}));
}

TEST(ImageName, ViewIndicesByNameInTheGivenOrder) {
  const Scene scene = SceneOf({"a.png", "sub/b.png", "c.png"});
  EXPECT_EQ(ViewIndices(scene, {"c.png", "./sub/b.png", "a.png"}, "list.txt"),
            (std::vector<size_t>{2, 1, 0}));
  EXPECT_EQ(ErrorOf([&] { ViewIndices(scene, {"d.png"}, "list.txt"); }),
            "list.txt: image 'd.png' is not in the scene");
  EXPECT_THAT(ErrorOf([&] { ViewIndices(scene, {"../a.png"}, "list.txt"); }),
              HasSubstr("contains '..'"));
}

}  // namespace
}  // namespace rephoto::scene
