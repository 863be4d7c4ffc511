#include "rephoto/scene/transforms_json.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <sstream>
#include <string>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/stats.h"
#include "rephoto/testing/testing.h"

namespace rephoto::scene {
namespace {

namespace fs = std::filesystem;
using camera::Camera;
using camera::CameraModel;

Scene Parse(const std::string& text, ImageSizeLookup sizes = FixedImageSize(800, 800)) {
  std::istringstream in(text);
  return ReadTransformsJson(in, "transforms.json", "/data/scene", sizes);
}

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

// NeRF-synthetic: camera_angle_x only, extensionless file paths, no w/h.
constexpr const char* kNerfSynthetic = R"({
  "camera_angle_x": 0.6911112070083618,
  "frames": [
    {"file_path": "./train/r_0", "rotation": 0.012566370614359171,
     "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]},
    {"file_path": "./train/r_1", "rotation": 0.012566370614359171,
     "transform_matrix": [[0, 0, 1, 4], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1]]}
  ]
})";

TEST(TransformsJson, NerfSyntheticByHand) {
  const Scene scene = Parse(kNerfSynthetic);
  ASSERT_EQ(scene.cameras.size(), 1u);
  const Camera& camera = scene.cameras.at(1);
  EXPECT_EQ(camera.model, CameraModel::kPinhole);
  EXPECT_EQ(camera.width, 800);  // from the image (FixedImageSize stands in for the header)
  // The Blender lego focal length: 0.5 * 800 / tan(0.5 * 0.6911112070083618).
  EXPECT_NEAR(camera.FocalLengthX(), 1111.1110311937682, 1e-9);
  EXPECT_EQ(camera.FocalLengthY(), camera.FocalLengthX());
  EXPECT_EQ(camera.PrincipalPointX(), 400);  // w/2: the image centre, corner convention
  EXPECT_EQ(camera.PrincipalPointY(), 400);
  ASSERT_EQ(scene.views.size(), 2u);
  EXPECT_EQ(scene.views[0].name, "train/r_0.png");
  EXPECT_EQ(scene.views[0].image_path, fs::path("/data/scene/train/r_0.png"));
  EXPECT_EQ(scene.image_root, fs::path("/data/scene"));

  // Frame 0: OpenGL camera at (0, 0, 4) looking down -z at the origin.
  const camera::Pose& pose = scene.views[0].cam_from_world;
  EXPECT_LT((pose.Center() - Eigen::Vector3d(0, 0, 4)).norm(), 1e-15);
  EXPECT_LT((pose.ViewDirection() - Eigen::Vector3d(0, 0, -1)).norm(), 1e-15);
  const auto centre = camera.ImgFromCam(pose.CamFromWorld({0, 0, 0}));
  ASSERT_TRUE(centre.has_value());
  EXPECT_LT((*centre - Eigen::Vector2d(400, 400)).norm(), 1e-12);
  // World +x appears to the right, world +y (OpenGL up) appears above the centre.
  EXPECT_GT(camera.ImgFromCam(pose.CamFromWorld({0.1, 0, 0}))->x(), 400);
  EXPECT_LT(camera.ImgFromCam(pose.CamFromWorld({0, 0.1, 0}))->y(), 400);
  // Frame 1: camera at (4, 0, 0); its -z axis (third column negated) is (-1, 0, 0).
  const camera::Pose& side = scene.views[1].cam_from_world;
  EXPECT_LT((side.Center() - Eigen::Vector3d(4, 0, 0)).norm(), 1e-15);
  EXPECT_LT((side.ViewDirection() - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-15);
}

TEST(TransformsJson, WidthAndHeightComeFromTheFirstExistingImage) {
  const fs::path dir = testing::MakeTempDir();
  // Frame 0 has no file; frame 1's image exists (as .jpg, found for the extensionless path).
  WriteTextFileAtomically(dir / "train" / "r_1.jpg", "not decoded: the size lookup is faked");
  std::vector<std::string> asked;
  const ImageSizeLookup sizes = [&](const std::string& name) {
    asked.push_back(name);
    return ImageSize{640, 360};
  };
  std::istringstream in(kNerfSynthetic);
  const Scene scene = ReadTransformsJson(in, "transforms.json", dir, sizes);
  ASSERT_EQ(asked.size(), 1u);
  EXPECT_EQ(asked[0], "train/r_1.jpg");
  EXPECT_EQ(scene.views[1].name, "train/r_1.jpg");
  EXPECT_EQ(scene.views[0].name, "train/r_0.png");
  EXPECT_EQ(scene.cameras.at(1).width, 640);
  EXPECT_EQ(scene.cameras.at(1).PrincipalPointY(), 180);
}

TEST(TransformsJson, InstantNgpAndNerfstudioForms) {
  const Scene scene = Parse(R"({
    "fl_x": 1375.52, "fl_y": 1374.49, "cx": 554.558, "cy": 965.268, "w": 1080.0, "h": 1920.0,
    "k1": 0.0578421, "k2": -0.0805099, "p1": -0.000980296, "p2": 0.00015575,
    "camera_angle_y": 1.2, "aabb_scale": 4, "scale": 0.33, "offset": [0.5, 0.5, 0.5],
    "frames": [
      {"file_path": "images/0001.jpg", "sharpness": 31.7,
       "transform_matrix": [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]]},
      {"file_path": "images/0002.jpg", "mask_path": "masks/0002.png", "fl_x": 1000, "fl_y": 1000,
       "camera_model": "OPENCV_FISHEYE", "k3": 0.001, "k4": -0.0001, "p1": 0, "p2": 0,
       "transform_matrix": [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]]},
      {"file_path": "images/0003.jpg", "k3": 0.002,
       "transform_matrix": [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3]]}
    ]})");
  ASSERT_EQ(scene.cameras.size(), 3u);
  const Camera& shared = scene.CameraOf(scene.views[0]);
  EXPECT_EQ(shared.model, CameraModel::kOpenCv);
  EXPECT_EQ(shared.params, (std::vector<double>{1375.52, 1374.49, 554.558, 965.268, 0.0578421,
                                                -0.0805099, -0.000980296, 0.00015575}));
  EXPECT_EQ(shared.width, 1080);
  EXPECT_EQ(shared.height, 1920);
  // Per-frame override: fisheye with its own focal length, shared principal point.
  const Camera& fisheye = scene.CameraOf(scene.views[1]);
  EXPECT_EQ(fisheye.model, CameraModel::kOpenCvFisheye);
  EXPECT_EQ(fisheye.params, (std::vector<double>{1000, 1000, 554.558, 965.268, 0.0578421,
                                                 -0.0805099, 0.001, -0.0001}));
  EXPECT_EQ(scene.views[1].mask_path, fs::path("/data/scene/masks/0002.png"));
  EXPECT_FALSE(scene.views[0].mask_path.has_value());
  // k3 makes it FULL_OPENCV (k3 is its r^6 numerator term; k4..k6 = 0).
  const Camera& full = scene.CameraOf(scene.views[2]);
  EXPECT_EQ(full.model, CameraModel::kFullOpenCv);
  EXPECT_EQ(full.params[8], 0.002);
  EXPECT_EQ(full.params[9], 0);
  // scale/offset are not applied: the centre is the file's translation.
  EXPECT_LT((scene.views[0].cam_from_world.Center() - Eigen::Vector3d(1, 2, 3)).norm(), 1e-15);

  // instant-ngp's is_fisheye.
  const Scene ngp_fisheye = Parse(R"({"fl_x": 500, "w": 1000, "h": 800, "is_fisheye": true,
    "k1": 0.01, "frames": [{"file_path": "a.png",
    "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]})");
  EXPECT_EQ(ngp_fisheye.cameras.at(1).model, CameraModel::kOpenCvFisheye);
  EXPECT_EQ(ngp_fisheye.cameras.at(1).params,
            (std::vector<double>{500, 500, 500, 400, 0.01, 0, 0, 0}));
  // nerfstudio's RADIAL name reads k1, k2 like OPENCV.
  const Scene radial = Parse(R"({"fl_x": 500, "w": 1000, "h": 800, "camera_model": "RADIAL",
    "k1": 0.01, "k2": -0.002, "frames": [{"file_path": "a.png",
    "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]})");
  EXPECT_EQ(radial.cameras.at(1).model, CameraModel::kOpenCv);
  EXPECT_EQ(radial.cameras.at(1).params,
            (std::vector<double>{500, 500, 500, 400, 0.01, -0.002, 0, 0}));
}

TEST(TransformsJson, ErrorsNameTheField) {
  const std::string frame_ok =
      R"({"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})";
  const auto with_frame = [](const std::string& frame, const std::string& top = "") {
    return R"({"fl_x": 500, "w": 640, "h": 480, )" + top + R"("frames": [)" + frame + "]}";
  };
  ExpectError([&] { Parse("{\"frames\": [}"); }, {"transforms.json: invalid JSON"});
  ExpectError([&] { Parse("{\"fl_x\": NaN, \"frames\": []}"); }, {"transforms.json: invalid JSON"});
  ExpectError([&] { Parse("[]"); }, {"transforms.json", "object"});
  ExpectError([&] { Parse("{\"fl_x\": 500}"); }, {"transforms.json: no \"frames\" array"});
  ExpectError([&] { Parse(with_frame(frame_ok, R"("fl_y": "x", )")); },
              {"transforms.json.fl_y: expected a number"});
  ExpectError([&] { Parse(with_frame(frame_ok, R"("camera_model": "EQUIRECTANGULAR", )")); },
              {"transforms.json: frames[0]", "unsupported camera_model 'EQUIRECTANGULAR'"});
  ExpectError([&] { Parse(with_frame(frame_ok, R"("k4": 0.1, )")); },
              {"frames[0]", "k4 = 0.1", "no COLMAP camera model"});
  ExpectError([&] { Parse(with_frame(frame_ok, R"("fl_x": 0, )")); },
              {"frames[0]", "focal length"});
  ExpectError([&] { Parse(R"({"w": 640, "h": 480, "frames": [)" + frame_ok + "]}"); },
              {"frames[0]: no focal length"});
  ExpectError(
      [&] {
        Parse(with_frame(
            R"({"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1.1,0,0],[0,0,1,0],[0,0,0,1]]})"));
      },
      {"transforms.json: frames[0].transform_matrix", "not a rotation"});
  ExpectError(
      [&] {
        Parse(with_frame(
            R"({"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,-1,0],[0,0,0,1]]})"));
      },
      {"frames[0].transform_matrix", "reflection"});
  ExpectError(
      [&] {
        Parse(with_frame(
            R"({"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,1]]})"));
      },
      {"frames[0].transform_matrix", "last row"});
  ExpectError(
      [&] { Parse(with_frame(R"({"file_path": "a.png", "transform_matrix": [[1,0,0]]})")); },
      {"frames[0].transform_matrix"});
  ExpectError([&] { Parse(with_frame(R"({"transform_matrix": []})")); },
              {"frames[0]: no file_path"});
  ExpectError([&] { Parse(with_frame(R"({"file_path": 3, "transform_matrix": []})")); },
              {"frames[0].file_path: expected a non-empty string"});
  ExpectError([&] { Parse(with_frame(frame_ok + "," + frame_ok)); },
              {"frames[1]", "'a.png' appears twice"});
  ExpectError([&] { Parse(with_frame(frame_ok, R"("w": 640.5, )")); }, {"w = 640.5"});
}

Scene MakeScene(std::mt19937_64& rng, const fs::path& root, std::vector<Camera> cameras) {
  Scene scene;
  scene.image_root = root;
  for (size_t i = 0; i < cameras.size(); ++i) scene.cameras.emplace(i + 1, cameras[i]);
  std::normal_distribution<double> normal;
  for (int i = 0; i < 9; ++i) {
    View view;
    view.name = fmt::format("images/frame_{:04d}.jpg", i);
    view.image_path = root / view.name;
    if (i % 3 == 0) view.mask_path = root / fmt::format("masks/frame_{:04d}.png", i);
    view.camera_id = 1 + i % static_cast<int>(cameras.size());
    view.cam_from_world.rotation =
        Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng))
            .normalized()
            .toRotationMatrix();
    view.cam_from_world.translation = {normal(rng), normal(rng), normal(rng)};
    scene.views.push_back(view);
  }
  return scene;
}

void ExpectScenesEqual(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.cameras, b.cameras);
  ASSERT_EQ(a.views.size(), b.views.size());
  for (size_t i = 0; i < a.views.size(); ++i) {
    EXPECT_EQ(a.views[i].name, b.views[i].name);
    EXPECT_EQ(a.views[i].image_path, b.views[i].image_path);
    EXPECT_EQ(a.views[i].mask_path, b.views[i].mask_path);
    EXPECT_EQ(a.views[i].camera_id, b.views[i].camera_id);
    const camera::Pose& pa = a.views[i].cam_from_world;
    const camera::Pose& pb = b.views[i].cam_from_world;
    EXPECT_LT((pa.rotation - pb.rotation).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_LT((pa.translation - pb.translation).norm(), 1e-14);
  }
}

TEST(TransformsJson, RoundTripSharedCamera) {
  std::mt19937_64 rng = testing::MakeRng();
  const fs::path dir = testing::MakeTempDir();
  const Scene scene = MakeScene(
      rng, dir,
      {Camera{CameraModel::kOpenCv,
              1080,
              1920,
              {1375.52, 1374.49, 554.558, 965.268, 0.0578, -0.0805, -0.00098, 0.000156}}});
  WriteTransformsJson(scene, dir / "transforms.json");
  const Scene back = ReadTransformsJson(dir / "transforms.json");
  EXPECT_EQ(back.image_root, dir);
  ExpectScenesEqual(scene, back);
  // One camera: intrinsics at the top level, camera_angle_x for NeRF-synthetic loaders.
  const std::string text = ReadFileToString(dir / "transforms.json");
  EXPECT_EQ(text.find("\"fl_x\""), text.rfind("\"fl_x\""));
  EXPECT_NE(text.find("\"camera_angle_x\""), std::string::npos);
}

TEST(TransformsJson, RoundTripPerFrameCameras) {
  std::mt19937_64 rng = testing::MakeRng();
  const fs::path dir = testing::MakeTempDir();
  const Scene scene =
      MakeScene(rng, dir,
                {Camera{CameraModel::kPinhole, 640, 480, {500, 501, 320.5, 239.5}},
                 Camera{CameraModel::kOpenCvFisheye,
                        1280,
                        960,
                        {600, 601, 640, 480, 0.05, -0.01, 0.002, -0.0003}},
                 Camera{CameraModel::kFullOpenCv,
                        800,
                        600,
                        {700, 700, 400, 300, 0.1, -0.05, 0.001, 0.002, 0.01, 0, 0, 0}}});
  WriteTransformsJson(scene, dir / "transforms.json");
  const Scene back = ReadTransformsJson(dir / "transforms.json");
  ASSERT_EQ(back.views.size(), scene.views.size());
  EXPECT_EQ(back.views[0].name, "images/frame_0000.jpg");
  for (size_t i = 0; i < back.views.size(); ++i) {
    EXPECT_EQ(fs::weakly_canonical(back.views[i].image_path),
              fs::weakly_canonical(scene.views[i].image_path));
  }
  EXPECT_EQ(back.cameras, scene.cameras);
  // Written into a subfolder, the file paths climb out of it ("../images/...", for other
  // tools); rephoto reads image names only inside the image root (scene/image_name.h).
  WriteTransformsJson(scene, dir / "split" / "transforms.json");
  try {
    ReadTransformsJson(dir / "split" / "transforms.json");
    ADD_FAILURE() << "a file_path with '..' was read";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("frames[0].file_path: image name "
                                               "'../images/frame_0000.jpg' contains '..'"));
  }
  // ... unless the user names the folder they may reach (--image-root): names relative to it.
  const Scene rooted = ReadTransformsJson(dir / "split" / "transforms.json", dir);
  EXPECT_EQ(rooted.views[0].name, "images/frame_0000.jpg");
  EXPECT_EQ(rooted.views[0].image_path, dir / "images/frame_0000.jpg");
  try {
    ReadTransformsJson(dir / "split" / "transforms.json", dir / "split");
    ADD_FAILURE() << "a file_path outside --image-root was read";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("contains '..'"));
  }
}

TEST(TransformsJson, EquivalentModelsAreWrittenWithIdenticalProjections) {
  std::mt19937_64 rng = testing::MakeRng();
  const fs::path dir = testing::MakeTempDir();
  for (const Camera& camera :
       {Camera{CameraModel::kSimpleRadial, 640, 480, {500, 320, 240, -0.05}},
        Camera{CameraModel::kRadial, 640, 480, {500, 320, 240, -0.05, 0.01}},
        Camera{CameraModel::kSimplePinhole, 640, 480, {500, 320, 240}},
        Camera{CameraModel::kSimpleRadialFisheye, 640, 480, {300, 320, 240, 0.02}},
        Camera{CameraModel::kRadialFisheye, 640, 480, {300, 320, 240, 0.02, -0.003}}}) {
    SCOPED_TRACE(std::string(camera::CameraModelName(camera.model)));
    const Scene scene = MakeScene(rng, dir, {camera});
    WriteTransformsJson(scene, dir / "transforms.json");
    const Camera written = ReadTransformsJson(dir / "transforms.json").cameras.at(1);
    std::uniform_real_distribution<double> u(-0.6, 0.6);
    for (int n = 0; n < 100; ++n) {
      const Eigen::Vector3d x(u(rng), u(rng), 1);
      EXPECT_LT((*written.ImgFromCam(x) - *camera.ImgFromCam(x)).norm(), 1e-9);
    }
  }
  const Scene fov =
      MakeScene(rng, dir, {Camera{CameraModel::kFov, 640, 480, {300, 300, 320, 240, 0.9}}});
  ExpectError([&] { TransformsJsonFromScene(fov, dir); }, {"FOV cameras cannot be written"});
}

// The point closest (least squares) to all optical axes, and each axis's distance from it.
Eigen::Vector3d ConvergencePoint(const Scene& scene, std::vector<double>* distances) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const View& view : scene.views) {
    const Eigen::Vector3d d = view.cam_from_world.ViewDirection();
    const Eigen::Matrix3d projector = Eigen::Matrix3d::Identity() - d * d.transpose();
    a += projector;
    b += projector * view.cam_from_world.Center();
  }
  const Eigen::Vector3d point = a.ldlt().solve(b);
  for (const View& view : scene.views) {
    const Eigen::Vector3d d = view.cam_from_world.ViewDirection();
    const Eigen::Vector3d offset = point - view.cam_from_world.Center();
    distances->push_back((offset - offset.dot(d) * d).norm());
  }
  return point;
}

TEST(TransformsJsonRealData, FoxLoadsAndCameraAxesConvergeOnTheObject) {
  REPHOTO_REQUIRE_DATA("instant_ngp_fox/transforms.json");
  const fs::path root = testing::SharedDataDir() / "instant_ngp_fox";
  const Scene scene = ReadTransformsJson(root / "transforms.json");
  ASSERT_EQ(scene.views.size(), 67u);
  ASSERT_EQ(scene.cameras.size(), 1u);
  const Camera& camera = scene.cameras.at(1);
  EXPECT_EQ(camera.model, CameraModel::kOpenCv);
  EXPECT_EQ(camera.params, (std::vector<double>{1375.52, 1374.49, 554.558, 965.268, 0.0578421,
                                                -0.0805099, -0.000980296, 0.00015575}));
  EXPECT_EQ(camera.width, 1080);
  EXPECT_EQ(camera.height, 1920);
  EXPECT_EQ(scene.views[0].name, "images/0001.jpg");
  int existing = 0;
  for (const View& view : scene.views) existing += fs::exists(view.image_path) ? 1 : 0;
  EXPECT_EQ(existing, 50);  // SOURCE.txt: 17 frames have no image in the repository

  std::vector<double> distances;
  const Eigen::Vector3d target = ConvergencePoint(scene, &distances);
  double mean_camera_distance = 0;
  for (const View& view : scene.views) {
    const Eigen::Vector3d in_camera = view.cam_from_world.CamFromWorld(target);
    // In front of every camera (a wrong y/z flip puts it behind) and inside every image.
    ASSERT_GT(in_camera.z(), 0) << view.name;
    const auto pixel = camera.ImgFromCam(in_camera);
    ASSERT_TRUE(pixel.has_value());
    EXPECT_GT(pixel->x(), 0) << view.name;
    EXPECT_LT(pixel->x(), camera.width) << view.name;
    EXPECT_GT(pixel->y(), 0) << view.name;
    EXPECT_LT(pixel->y(), camera.height) << view.name;
    mean_camera_distance += in_camera.norm() / scene.views.size();
  }
  // Handheld phone photos are aimed only roughly: measure how far (in degrees) each optical
  // axis passes from the common point, seen from the camera.
  std::vector<double> angles;
  for (size_t i = 0; i < scene.views.size(); ++i) {
    const double range = (target - scene.views[i].cam_from_world.Center()).norm();
    angles.push_back(std::asin(std::min(1.0, distances[i] / range)) * 180 / M_PI);
  }
  const Summary summary = Summarize(angles);
  RecordProperty("mean_camera_distance", fmt::format("{:.3f}", mean_camera_distance));
  RecordProperty("median_axis_offset_deg", fmt::format("{:.2f}", summary.median));
  RecordProperty("max_axis_offset_deg", fmt::format("{:.2f}", summary.max));
  // Half the narrower field of view is atan(540 / 1375.5) = 21.4 degrees.
  EXPECT_LT(summary.median, 10);
  EXPECT_LT(summary.max, 21.4);
}

}  // namespace
}  // namespace rephoto::scene
