#include "rephoto/scene/colmap.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/stats.h"
#include "rephoto/io/image_io.h"
#include "rephoto/scene/bundler.h"
#include "rephoto/testing/testing.h"

namespace rephoto::scene {
namespace {

namespace fs = std::filesystem;
using camera::Camera;
using camera::CameraModel;

// A small model written by hand in COLMAP's text layout.
constexpr const char* kCamerasText = R"(# Camera list with one line of data per camera:
#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]
# Number of cameras: 2
1 PINHOLE 640 480 500 510 320 240
3 SIMPLE_RADIAL 800 600 700 400.5 299.5 -0.05
)";

// Image 7: identity rotation, translation (0, 0, 5). Image 2: 90 degrees about y.
constexpr const char* kImagesText = R"(# Image list with two lines of data per image:
#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME
#   POINTS2D[] as (X, Y, POINT3D_ID)
7 1 0 0 0 0 0 5 1 a.jpg
100.5 200.25 -1 320 240 11
2 0.70710678118654752 0 0.70710678118654752 0 1 2 3 3 sub dir/b c.png

)";

constexpr const char* kPointsText = R"(# 3D point list with one line of data per point:
#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)
11 0 0 1 255 128 0 0.5 7 1
12 1 2 3 1 2 3 -1
)";

ColmapModel ParseTextModel(const std::string& cameras, const std::string& images,
                           const std::string& points) {
  std::istringstream cameras_in(cameras), images_in(images), points_in(points);
  ColmapModel model;
  model.cameras = ReadColmapCamerasText(cameras_in, "cameras.txt");
  model.images = ReadColmapImagesText(images_in, "images.txt");
  model.points = ReadColmapPoints3DText(points_in, "points3D.txt");
  return model;
}

// Expects an Error whose message contains every part.
template <typename F>
void ExpectError(F&& f, std::initializer_list<std::string> parts) {
  try {
    f();
    ADD_FAILURE() << "no error; expected: " << *parts.begin();
  } catch (const Error& error) {
    const std::string message = error.what();
    for (const std::string& part : parts) {
      EXPECT_NE(message.find(part), std::string::npos) << "message: " << message;
    }
    EXPECT_EQ(message.find('\n'), std::string::npos) << "one line: " << message;
  }
}

TEST(ColmapText, ParsesHandWrittenModel) {
  const ColmapModel model = ParseTextModel(kCamerasText, kImagesText, kPointsText);
  ASSERT_EQ(model.cameras.size(), 2u);
  EXPECT_EQ(model.cameras.at(3).model, CameraModel::kSimpleRadial);
  EXPECT_EQ(model.cameras.at(3).params, (std::vector<double>{700, 400.5, 299.5, -0.05}));
  ASSERT_EQ(model.images.size(), 2u);
  EXPECT_EQ(model.images[0].image_id, 7u);
  EXPECT_EQ(model.images[0].points2d.size(), 2u);
  EXPECT_EQ(model.images[0].point3d_ids[0], ColmapImage::kNoPoint3D);
  EXPECT_EQ(model.images[0].point3d_ids[1], 11u);
  EXPECT_EQ(model.images[1].name, "sub dir/b c.png");  // the rest of the line
  EXPECT_TRUE(model.images[1].points2d.empty());
  ASSERT_EQ(model.points.size(), 2u);
  EXPECT_EQ(model.points[0].track.size(), 1u);
  EXPECT_TRUE(model.points[1].track.empty());

  const Scene scene = SceneFromColmap(model, "/data/images");
  ASSERT_EQ(scene.views.size(), 2u);
  EXPECT_EQ(scene.views[0].name, "a.jpg");
  EXPECT_EQ(scene.views[0].image_path, fs::path("/data/images/a.jpg"));
  EXPECT_EQ(scene.views[1].camera_id, 3);
  // Image 2: R = rotation of 90 degrees about y: x_cam = (z, y, -x) + (1, 2, 3).
  const Eigen::Vector3d x_cam = scene.views[1].cam_from_world.CamFromWorld({1, 0, 0});
  EXPECT_LT((x_cam - Eigen::Vector3d(1, 2, 2)).norm(), 1e-15);
  // Point 11 at (0, 0, 1) seen by image 7 at (320, 240): its camera is at z = -5, so the point
  // is 6 in front on the optical axis, at the principal point.
  ASSERT_EQ(scene.points[0].track.size(), 1u);
  EXPECT_EQ(scene.points[0].track[0].view_index, 0);
  EXPECT_EQ(scene.points[0].track[0].pixel, Eigen::Vector2d(320, 240));
  const auto pixel =
      scene.CameraOf(scene.views[0])
          .ImgFromCam(scene.views[0].cam_from_world.CamFromWorld(scene.points[0].position));
  ASSERT_TRUE(pixel.has_value());
  EXPECT_LT((*pixel - scene.points[0].track[0].pixel).norm(), 1e-12);
  EXPECT_EQ(scene.points[0].color, (Eigen::Matrix<uint8_t, 3, 1>(255, 128, 0)));
}

// A scene with every camera model, views, and points with tracks.
Scene MakeRichScene(std::mt19937_64& rng) {
  Scene scene;
  scene.image_root = "/photos";
  const std::vector<std::pair<CameraModel, std::vector<double>>> models = {
      {CameraModel::kSimplePinhole, {500, 320, 240}},
      {CameraModel::kPinhole, {500.1, 501.2, 320.3, 240.4}},
      {CameraModel::kSimpleRadial, {500, 320, 240, 0.01}},
      {CameraModel::kRadial, {500, 320, 240, 0.01, -0.002}},
      {CameraModel::kOpenCv, {500, 501, 320, 240, 0.01, -0.002, 1e-4, -2e-4}},
      {CameraModel::kOpenCvFisheye, {300, 301, 320, 240, 0.01, -0.002, 3e-4, -1e-5}},
      {CameraModel::kFullOpenCv,
       {500, 501, 320, 240, 0.1, -0.02, 1e-4, 2e-4, 0.001, 0.1, 0.01, 0.001}},
      {CameraModel::kFov, {300, 301, 320, 240, 0.9}},
      {CameraModel::kSimpleRadialFisheye, {300, 320, 240, 0.02}},
      {CameraModel::kRadialFisheye, {300, 320, 240, 0.02, -0.001}},
      {CameraModel::kThinPrismFisheye,
       {300, 301, 320, 240, 0.02, -0.001, 1e-4, 2e-4, 1e-5, 2e-6, 3e-4, -1e-4}},
  };
  int id = 5;
  for (const auto& [model, params] : models) {
    Camera camera;
    camera.model = model;
    camera.width = 640;
    camera.height = 480;
    camera.params = params;
    scene.cameras.emplace(id, camera);
    id += 2;
  }
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(0, 640);
  for (int i = 0; i < 13; ++i) {
    View view;
    view.name = i == 3 ? "nested/dir/view 3.jpg" : "IMG_" + std::to_string(1000 + i) + ".JPG";
    view.image_path = scene.image_root / view.name;
    view.camera_id = 5 + 2 * (i % 11);
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
    view.cam_from_world.rotation = q.toRotationMatrix();
    view.cam_from_world.translation = {normal(rng), normal(rng), normal(rng)};
    scene.views.push_back(view);
  }
  for (int p = 0; p < 50; ++p) {
    Point3D point;
    point.position = {normal(rng) * 10, normal(rng), normal(rng) / 3};
    point.color = {static_cast<uint8_t>(p * 5), static_cast<uint8_t>(255 - p), 7};
    for (int k = 0; k < p % 5; ++k) {
      point.track.push_back({(p + 3 * k) % 13, {uniform(rng), uniform(rng) * 0.75}});
    }
    scene.points.push_back(point);
  }
  return scene;
}

void ExpectScenesEqual(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.cameras, b.cameras);
  EXPECT_EQ(a.image_root, b.image_root);
  ASSERT_EQ(a.views.size(), b.views.size());
  for (size_t i = 0; i < a.views.size(); ++i) {
    EXPECT_EQ(a.views[i].name, b.views[i].name);
    EXPECT_EQ(a.views[i].image_path, b.views[i].image_path);
    EXPECT_EQ(a.views[i].camera_id, b.views[i].camera_id);
    // Through the quaternion and back: rounding level.
    EXPECT_LT((a.views[i].cam_from_world.rotation - b.views[i].cam_from_world.rotation)
                  .cwiseAbs()
                  .maxCoeff(),
              1e-15);
    EXPECT_EQ(a.views[i].cam_from_world.translation, b.views[i].cam_from_world.translation);
  }
  ASSERT_EQ(a.points.size(), b.points.size());
  for (size_t p = 0; p < a.points.size(); ++p) {
    EXPECT_EQ(a.points[p].position, b.points[p].position);
    EXPECT_EQ(a.points[p].color, b.points[p].color);
    ASSERT_EQ(a.points[p].track.size(), b.points[p].track.size());
    for (size_t k = 0; k < a.points[p].track.size(); ++k) {
      EXPECT_EQ(a.points[p].track[k].view_index, b.points[p].track[k].view_index);
      EXPECT_EQ(a.points[p].track[k].pixel, b.points[p].track[k].pixel);
    }
  }
}

TEST(Colmap, TextRoundTripKeepsEverything) {
  std::mt19937_64 rng = testing::MakeRng();
  const Scene scene = MakeRichScene(rng);
  const fs::path dir = testing::MakeTempDir() / "sparse" / "0";
  WriteColmap(scene, dir, ColmapFormat::kText);
  EXPECT_EQ(DetectColmapFormat(dir), ColmapFormat::kText);
  ExpectScenesEqual(scene, ReadColmap(dir, {.image_root = fs::path("/photos")}));
  // The default image folder of <project>/sparse/0 is <project>/images.
  EXPECT_EQ(ReadColmap(dir).image_root, (dir.parent_path().parent_path() / "images"));
}

TEST(Colmap, BinaryRoundTripKeepsEverything) {
  std::mt19937_64 rng = testing::MakeRng();
  const Scene scene = MakeRichScene(rng);
  const fs::path dir = testing::MakeTempDir() / "model";
  WriteColmap(scene, dir, ColmapFormat::kBinary);
  EXPECT_EQ(DetectColmapFormat(dir), ColmapFormat::kBinary);
  ExpectScenesEqual(scene, ReadColmap(dir, {.image_root = fs::path("/photos")}));
  EXPECT_EQ(ReadColmap(dir).image_root, dir.parent_path() / "images");
  // Text and binary of the same model give the same records.
  WriteColmap(scene, dir / "text", ColmapFormat::kText);
  const ColmapModel text = ReadColmapModel(dir / "text");
  const ColmapModel binary = ReadColmapModel(dir);
  ASSERT_EQ(text.images.size(), binary.images.size());
  for (size_t i = 0; i < text.images.size(); ++i) {
    EXPECT_EQ(text.images[i].quaternion, binary.images[i].quaternion);
    EXPECT_EQ(text.images[i].points2d, binary.images[i].points2d);
    EXPECT_EQ(text.images[i].point3d_ids, binary.images[i].point3d_ids);
  }
}

TEST(ColmapBinary, ByteLayoutMatchesColmap) {
  // cameras.bin: uint64 count, then per camera uint32 id, int32 model id, uint64 width,
  // uint64 height, double params[]: 8 + 4 + 4 + 8 + 8 + 4 * 8 = 64 bytes for one PINHOLE.
  std::map<uint32_t, Camera> cameras;
  cameras[9] = Camera{CameraModel::kPinhole, 640, 480, {500, 510, 320, 240}};
  std::ostringstream out;
  WriteColmapCamerasBinary(out, cameras);
  const std::string bytes = out.str();
  ASSERT_EQ(bytes.size(), 64u);
  EXPECT_EQ(bytes[0], 1);                    // count, little-endian
  EXPECT_EQ(bytes[8], 9);                    // camera id
  EXPECT_EQ(bytes[12], 1);                   // PINHOLE = 1
  EXPECT_EQ(uint8_t(bytes[16]), 640 % 256);  // width low byte, at bytes 16..23
  double fx;
  std::memcpy(&fx, bytes.data() + 32, 8);
  EXPECT_EQ(fx, 500);
  // images.bin: id, 7 doubles, camera id, name + NUL, uint64 count, (x, y, uint64 id)*.
  ColmapImage image;
  image.image_id = 4;
  image.camera_id = 9;
  image.name = "ab";
  image.points2d = {{1.5, 2.5}};
  image.point3d_ids = {ColmapImage::kNoPoint3D};
  std::ostringstream images_out;
  WriteColmapImagesBinary(images_out, {image});
  EXPECT_EQ(images_out.str().size(), 8u + 4 + 7 * 8 + 4 + 3 + 8 + 24);
  EXPECT_EQ(images_out.str().substr(8 + 4 + 56 + 4, 3), std::string("ab\0", 3));
  // kNoPoint3D is written as all ones (COLMAP's kInvalidPoint3DId).
  EXPECT_EQ(images_out.str().substr(images_out.str().size() - 8), std::string(8, '\xff'));
}

TEST(ColmapBinary, EveryTruncationIsAnErrorNamingTheRecord) {
  std::mt19937_64 rng = testing::MakeRng();
  const ColmapModel model = ColmapFromScene(MakeRichScene(rng));
  std::ostringstream cameras, images, points;
  WriteColmapCamerasBinary(cameras, model.cameras);
  WriteColmapImagesBinary(images, model.images);
  WriteColmapPoints3DBinary(points, model.points);
  const auto check_all_prefixes = [](const std::string& full, auto read, const char* name) {
    for (size_t length = 0; length < full.size(); ++length) {
      std::istringstream in(full.substr(0, length));
      try {
        read(in, name);
        ADD_FAILURE() << name << " truncated to " << length << " bytes was accepted";
      } catch (const Error& error) {
        const std::string message = error.what();
        ASSERT_NE(message.find("truncated"), std::string::npos) << message;
        ASSERT_EQ(message.rfind(name, 0), 0u) << message;
        if (length >= 8) {
          ASSERT_NE(message.find("record"), std::string::npos) << message;
        }
      }
    }
    std::istringstream in(full);
    EXPECT_NO_THROW(read(in, name));
  };
  check_all_prefixes(cameras.str(), ReadColmapCamerasBinary, "cameras.bin");
  check_all_prefixes(images.str(), ReadColmapImagesBinary, "images.bin");
  check_all_prefixes(points.str(), ReadColmapPoints3DBinary, "points3D.bin");
}

TEST(ColmapBinary, RejectsBadRecords) {
  std::map<uint32_t, Camera> cameras;
  cameras[1] = Camera{CameraModel::kPinhole, 640, 480, {500, 510, 320, 240}};
  std::ostringstream out;
  WriteColmapCamerasBinary(out, cameras);
  std::string bytes = out.str();
  bytes[12] = 42;  // model id
  std::istringstream bad_model(bytes);
  ExpectError([&] { ReadColmapCamerasBinary(bad_model, "cameras.bin"); },
              {"cameras.bin: record 0 of 1", "unknown camera model id 42"});
  bytes = out.str();
  const double nan = std::nan("");
  std::memcpy(bytes.data() + 40, &nan, 8);  // fy
  std::istringstream nan_param(bytes);
  ExpectError([&] { ReadColmapCamerasBinary(nan_param, "cameras.bin"); },
              {"cameras.bin: record 0", "NaN"});

  ColmapImage image;
  image.image_id = 4;
  image.camera_id = 1;
  image.name = "a.png";
  image.quaternion = {1, 0, 0.1, 0};  // norm 1.005
  std::ostringstream images;
  WriteColmapImagesBinary(images, {image});
  std::istringstream images_in(images.str());
  ExpectError([&] { ReadColmapImagesBinary(images_in, "images.bin"); },
              {"images.bin: record 0 of 1", "image 4 'a.png'", "norm 1.00498756"});
}

TEST(ColmapText, ErrorsNameFileAndLine) {
  const auto cameras = [](const std::string& text) {
    std::istringstream in(text);
    return ReadColmapCamerasText(in, "cameras.txt");
  };
  ExpectError([&] { cameras("# c\n1 PINHOLE 640 480 500 500 320\n"); },
              {"cameras.txt:2:", "PINHOLE camera has 3 parameters, expected 4"});
  ExpectError([&] { cameras("1 FISHEYE_X 640 480 1 2 3\n"); },
              {"cameras.txt:1:", "unknown camera model 'FISHEYE_X'"});
  ExpectError([&] { cameras("\n\n1 PINHOLE 640 480 500 nan 320 240\n"); },
              {"cameras.txt:3:", "not finite"});
  ExpectError([&] { cameras("1 PINHOLE 640 480 0 500 320 240\n"); },
              {"cameras.txt:1:", "focal length"});
  ExpectError([&] { cameras("1 PINHOLE 640 480 5 5 3 2\n1 PINHOLE 640 480 5 5 3 2\n"); },
              {"cameras.txt:2:", "camera id 1 defined twice (first at cameras.txt:1)"});
  ExpectError([&] { cameras("1 PINHOLE 640 -480 5 5 3 2\n"); }, {"cameras.txt:1:", "HEIGHT"});

  const auto images = [](const std::string& text) {
    std::istringstream in(text);
    return ReadColmapImagesText(in, "images.txt");
  };
  ExpectError([&] { images("# x\n1 1 0 0 0 0 0 0 1\n\n"); },
              {"images.txt:2:", "expected at least 10"});
  ExpectError([&] { images("1 0.5 0 0 0 0 0 0 1 a.png\n\n"); },
              {"images.txt:1:", "quaternion (0.5, 0, 0, 0) has norm 0.5"});
  ExpectError([&] { images("1 1 0 0 0 0 nan 0 1 a.png\n\n"); }, {"images.txt:1:", "not finite"});
  ExpectError([&] { images("1 1 0 0 0 0 0 0 1 a.png\n1 2 -1 4\n"); },
              {"images.txt:2:", "not a multiple of 3"});
  // Rounded to 9 digits, a quaternion is still accepted and normalized.
  EXPECT_EQ(images("1 0.707106781 0 0.707106781 0 0 0 0 1 a.png\n").size(), 1u);

  const auto points = [](const std::string& text) {
    std::istringstream in(text);
    return ReadColmapPoints3DText(in, "points3D.txt");
  };
  ExpectError([&] { points("1 0 0 0 255 255 256 0\n"); }, {"points3D.txt:1:", "RGB"});
  ExpectError([&] { points("1 0 0 0 1 1 1 0 5\n"); }, {"points3D.txt:1:", "pairs"});
}

TEST(ColmapText, LongPoints2DLines) {
  // 50000 keypoints written with 17 digits: a POINTS2D line of about 2.5 MB, as COLMAP writes
  // with large feature settings.
  std::string text = "1 1 0 0 0 0 0 0 1 a.png\n";
  for (int i = 0; i < 50000; ++i) {
    text += fmt::format("{} {} {} ", 1000.0 + i / 7.0, 2000.0 - i / 3.0, i % 2 ? -1 : i);
  }
  text += "\n";
  std::istringstream in(text);
  const std::vector<ColmapImage> images = ReadColmapImagesText(in, "images.txt");
  ASSERT_EQ(images.size(), 1u);
  ASSERT_EQ(images[0].points2d.size(), 50000u);
  EXPECT_EQ(images[0].points2d[49999].x(), 1000.0 + 49999 / 7.0);
  EXPECT_EQ(images[0].point3d_ids[49998], 49998u);
  EXPECT_EQ(images[0].point3d_ids[49999], ColmapImage::kNoPoint3D);
}

TEST(Colmap, LinkingErrorsNameTheRecord) {
  // An image referring to a camera id that cameras.txt does not define.
  ExpectError(
      [&] {
        SceneFromColmap(ParseTextModel(kCamerasText, "5 1 0 0 0 0 0 0 2 x.png\n\n", ""), "img");
      },
      {"images.txt:1:", "camera id 2, which the cameras file does not define"});
  // A track referring to a missing image and to a missing POINT2D index.
  ExpectError(
      [&] {
        SceneFromColmap(ParseTextModel(kCamerasText, kImagesText, "1 0 0 0 1 1 1 0 8 0\n"), "i");
      },
      {"points3D.txt:1:", "image id 8, which the images file does not define"});
  ExpectError(
      [&] {
        SceneFromColmap(ParseTextModel(kCamerasText, kImagesText, "1 0 0 0 1 1 1 0 7 2\n"), "i");
      },
      {"points3D.txt:1:", "POINT2D_IDX 2 of image 7, which has 2 2D points"});
  ExpectError(
      [&] {
        SceneFromColmap(
            ParseTextModel(kCamerasText, "1 1 0 0 0 0 0 0 1 a\n\n1 1 0 0 0 0 0 0 1 b\n\n", ""),
            "i");
      },
      {"images.txt:3:", "image id 1 is used twice (first at images.txt:1)"});
}

TEST(Colmap, FolderErrors) {
  const fs::path dir = testing::MakeTempDir();
  ExpectError([&] { ReadColmap(dir); }, {dir.string(), "missing: cameras, images, points3D"});
  WriteTextFileAtomically(dir / "cameras.txt", kCamerasText);
  WriteTextFileAtomically(dir / "images.txt", kImagesText);
  WriteTextFileAtomically(dir / "points3D.txt", "11 0 0 1 255 128 0 0.5 7 1\n12 1 2 x 1 2 3 -1\n");
  ExpectError([&] { ReadColmap(dir); }, {(dir / "points3D.txt").string() + ":2:", "XYZ"});
}

// ---------------------------------------------------------------------------------------------
// Real data.

// Colour agreement of points with the photos: mean absolute difference (0-255 units, over
// RGB) between each point's colour and the bilinear-free nearest pixel at its projection.
struct ColourAgreement {
  double point_difference = 0;   // mean over projections inside the image
  double random_difference = 0;  // the same colours against random pixels of the same photo
  size_t count = 0;
};

void AddColourAgreement(const Image& photo, const Eigen::Matrix<uint8_t, 3, 1>& colour,
                        const Eigen::Vector2d& pixel, std::mt19937_64& rng,
                        ColourAgreement& agreement) {
  const int x = static_cast<int>(std::floor(pixel.x()));
  const int y = static_cast<int>(std::floor(pixel.y()));
  std::uniform_int_distribution<int> rx(0, photo.width() - 1), ry(0, photo.height() - 1);
  const int x2 = rx(rng), y2 = ry(rng);
  double d = 0, d2 = 0;
  for (int c = 0; c < 3; ++c) {
    d += std::abs(photo.at(x, y, c) * 255.0 - colour[c]);
    d2 += std::abs(photo.at(x2, y2, c) * 255.0 - colour[c]);
  }
  agreement.point_difference += d / 3;
  agreement.random_difference += d2 / 3;
  ++agreement.count;
}

TEST(ColmapRealData, SceauxLoadsAndPointsReprojectOntoTheirColours) {
  REPHOTO_REQUIRE_DATA("openmvs_sceaux/colmap_text_derived");
  const fs::path root = testing::SharedDataDir() / "openmvs_sceaux";
  const Scene scene = ReadColmap(root / "colmap_text_derived");
  EXPECT_EQ(scene.image_root, fs::absolute(root / "images").lexically_normal());
  ASSERT_EQ(scene.views.size(), 11u);
  EXPECT_EQ(scene.points.size(), 12683u);
  EXPECT_EQ(scene.views[0].name, "00000.jpg");
  const Camera& camera = scene.CameraOf(scene.views[0]);
  EXPECT_EQ(camera.model, CameraModel::kPinhole);
  EXPECT_EQ(camera.width, 2832);
  EXPECT_NEAR(camera.MeanFocalLength(), 2985.328343, 1e-6);

  // No 2D observations are stored (openMVS keeps none), so the check is photometric: points
  // projected into 3 photos land on pixels of their own colour far more than on random ones.
  std::mt19937_64 rng = testing::MakeRng();
  ColourAgreement agreement, shifted;
  size_t in_front_inside = 0;
  for (int v : {0, 4, 8}) {
    const View& view = scene.views[v];
    ASSERT_TRUE(fs::exists(view.image_path)) << view.image_path;
    const Image photo = io::ReadImage(view.image_path);
    ASSERT_EQ(photo.width(), camera.width);
    ASSERT_EQ(photo.height(), camera.height);
    Camera camera_shifted = scene.CameraOf(view);  // principal point 0.5 px lower/left
    camera_shifted.params[2] -= 0.5;
    camera_shifted.params[3] -= 0.5;
    for (const Point3D& point : scene.points) {
      const Eigen::Vector3d x = view.cam_from_world.CamFromWorld(point.position);
      const auto pixel = scene.CameraOf(view).ImgFromCam(x);
      const auto pixel_shifted = camera_shifted.ImgFromCam(x);
      if (!pixel || pixel->x() < 1 || pixel->y() < 1 || pixel->x() >= camera.width - 1 ||
          pixel->y() >= camera.height - 1) {
        continue;
      }
      ++in_front_inside;
      AddColourAgreement(photo, point.color, *pixel, rng, agreement);
      AddColourAgreement(photo, point.color, *pixel_shifted, rng, shifted);
    }
  }
  ASSERT_GT(agreement.count, 10000u);
  const double mean = agreement.point_difference / agreement.count;
  const double random = agreement.random_difference / agreement.count;
  RecordProperty("projections", static_cast<int>(in_front_inside));
  RecordProperty("mean_abs_colour_difference", fmt::format("{:.2f}", mean));
  RecordProperty("mean_abs_colour_difference_cxcy_minus_half",
                 fmt::format("{:.2f}", shifted.point_difference / shifted.count));
  RecordProperty("random_pixel_difference", fmt::format("{:.2f}", random));
  EXPECT_LT(mean, 30);
  EXPECT_GT(random, 60);
}

TEST(ColmapRealData, FernBinaryMatchesTheDerivedTextModel) {
  REPHOTO_REQUIRE_DATA("llff_fern/sparse/0");
  const fs::path root = testing::SharedDataDir() / "llff_fern";
  // images.bin is absent from the snapshot: the folder reader says so.
  ExpectError([&] { ReadColmap(root / "sparse" / "0"); }, {"missing: images"});

  std::ifstream cameras_in(root / "sparse/0/cameras.bin", std::ios::binary);
  const auto cameras = ReadColmapCamerasBinary(cameras_in, "cameras.bin");
  ASSERT_EQ(cameras.size(), 1u);
  const Camera& full = cameras.begin()->second;
  EXPECT_EQ(full.model, CameraModel::kSimpleRadial);
  EXPECT_EQ(full.width, 4032);
  EXPECT_EQ(full.height, 3024);
  // The derived text model for images_8 is the same camera scaled by 1/8.
  const Scene derived =
      ReadColmap(root / "sparse_text_images_8_derived", {.image_root = root / "images_8"});
  const Camera& small = derived.cameras.at(1);
  const Camera scaled = full.Scaled(504, 378);
  ASSERT_EQ(scaled.params.size(), small.params.size());
  for (size_t i = 0; i < small.params.size(); ++i) {
    EXPECT_NEAR(scaled.params[i], small.params[i], 1e-6 * std::abs(small.params[i]));
  }

  // Re-writing the binary files gives COLMAP's bytes back exactly.
  for (const char* file : {"cameras.bin", "points3D.bin"}) {
    const std::string original = ReadFileToString(root / "sparse/0" / file);
    std::istringstream in(original);
    std::ostringstream out;
    if (std::string(file) == "cameras.bin") {
      WriteColmapCamerasBinary(out, ReadColmapCamerasBinary(in, file));
    } else {
      WriteColmapPoints3DBinary(out, ReadColmapPoints3DBinary(in, file));
    }
    EXPECT_TRUE(out.str() == original) << file << " differs after a read/write round trip";
  }

  // points3D.bin and the derived points3D.txt hold the same points.
  std::ifstream points_in(root / "sparse/0/points3D.bin", std::ios::binary);
  const std::vector<ColmapPoint3D> points = ReadColmapPoints3DBinary(points_in, "points3D.bin");
  ASSERT_EQ(points.size(), 10091u);
  ASSERT_EQ(derived.points.size(), points.size());
  std::ifstream text_in(root / "sparse_text_images_8_derived/points3D.txt");
  const std::vector<ColmapPoint3D> text_points = ReadColmapPoints3DText(text_in, "points3D.txt");
  std::map<uint64_t, const ColmapPoint3D*> by_id;
  for (const ColmapPoint3D& point : text_points) by_id[point.point3d_id] = &point;
  size_t observations = 0;
  for (const ColmapPoint3D& point : points) {
    ASSERT_TRUE(by_id.contains(point.point3d_id));
    EXPECT_LT((by_id[point.point3d_id]->position - point.position).norm(), 1e-5);
    EXPECT_EQ(by_id[point.point3d_id]->color, point.color);
    observations += point.track.size();
  }
  EXPECT_EQ(observations, 41291u);

  // Track observations (image ids 1..20 = image000..019 as the derived images.txt numbers
  // them) project in front of and inside their photos, onto pixels of the point's colour.
  std::map<uint32_t, int> view_of_image;
  for (int i = 0; i < static_cast<int>(derived.views.size()); ++i) {
    view_of_image[i + 1] = i;
  }
  std::vector<Image> photos;
  for (const View& view : derived.views) photos.push_back(io::ReadImage(view.image_path));
  std::mt19937_64 rng = testing::MakeRng();
  ColourAgreement agreement;
  size_t outside = 0;
  for (const ColmapPoint3D& point : points) {
    for (const auto& [image_id, point2d_idx] : point.track) {
      ASSERT_TRUE(view_of_image.contains(image_id)) << image_id;
      const View& view = derived.views[view_of_image[image_id]];
      const auto pixel = small.ImgFromCam(view.cam_from_world.CamFromWorld(point.position));
      if (!pixel || pixel->x() < 0 || pixel->y() < 0 || pixel->x() >= 504 || pixel->y() >= 378) {
        ++outside;
        continue;
      }
      AddColourAgreement(photos[view_of_image[image_id]], point.color, *pixel, rng, agreement);
    }
  }
  const double mean = agreement.point_difference / agreement.count;
  const double random = agreement.random_difference / agreement.count;
  RecordProperty("observations_outside", static_cast<int>(outside));
  RecordProperty("mean_abs_colour_difference", fmt::format("{:.2f}", mean));
  RecordProperty("random_pixel_difference", fmt::format("{:.2f}", random));
  EXPECT_EQ(outside, 0u);
  EXPECT_LT(mean, 35);
  EXPECT_GT(random, 60);
}

// Kermit (Bundler) has real 2D observations: converted to COLMAP (text and binary) and read
// back, every track still points at its keypoint, and the points reproject onto them with the
// bundle adjustment's residual (the Bundler reader's test measured a median of 0.20 px).
TEST(ColmapRealData, KermitObservationsSurviveColmapAndReproject) {
  REPHOTO_REQUIRE_DATA("bundler_kermit/results.example/bundle.out");
  const Scene bundler =
      ReadBundlerScene(testing::SharedDataDir() / "bundler_kermit/results.example/bundle.out");
  for (const ColmapFormat format : {ColmapFormat::kText, ColmapFormat::kBinary}) {
    const fs::path dir = testing::MakeTempDir() / "sparse";
    WriteColmap(bundler, dir, format);
    const Scene scene = ReadColmap(dir, {.image_root = bundler.image_root});
    ExpectScenesEqual(bundler, scene);
    std::vector<double> errors;
    for (const Point3D& point : scene.points) {
      for (const Observation& observation : point.track) {
        const View& view = scene.views[observation.view_index];
        const auto pixel =
            scene.CameraOf(view).ImgFromCam(view.cam_from_world.CamFromWorld(point.position));
        ASSERT_TRUE(pixel.has_value());
        errors.push_back((*pixel - observation.pixel).norm());
      }
    }
    ASSERT_EQ(errors.size(), 2039u);
    const Summary summary = Summarize(errors);
    RecordProperty(format == ColmapFormat::kText ? "text_median_px" : "binary_median_px",
                   fmt::format("{:.3f}", summary.median));
    EXPECT_LT(summary.median, 0.3);
    EXPECT_GT(summary.median, 0.05);
  }
}

}  // namespace
}  // namespace rephoto::scene
