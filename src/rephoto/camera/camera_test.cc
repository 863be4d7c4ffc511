#include "rephoto/camera/camera.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "rephoto/core/error.h"
#include "rephoto/testing/testing.h"

namespace rephoto::camera {
namespace {

Camera MakeCamera(CameraModel model, int width, int height, std::vector<double> params) {
  Camera camera;
  camera.model = model;
  camera.width = width;
  camera.height = height;
  camera.params = std::move(params);
  camera.Validate("test camera");
  return camera;
}

// Realistic parameters per model, the image lying inside the usable field of view. The fisheye
// ones are strong: about 150 degrees across the diagonal.
std::vector<Camera> RealisticCameras() {
  using M = CameraModel;
  return {
      MakeCamera(M::kSimplePinhole, 1280, 960, {1000, 640, 480}),
      MakeCamera(M::kPinhole, 1280, 960, {1000, 1010, 641.3, 479.2}),
      MakeCamera(M::kSimpleRadial, 1280, 960, {1000, 640, 480, -0.1}),
      MakeCamera(M::kRadial, 1280, 960, {1000, 641, 478, -0.2, 0.05}),
      MakeCamera(M::kOpenCv, 1280, 960, {1000, 1002, 640.5, 479.5, -0.25, 0.08, 0.001, -0.0005}),
      MakeCamera(M::kOpenCvFisheye, 1280, 960,
                 {600, 601, 640.2, 480.7, 0.05, -0.01, 0.002, -0.0003}),
      MakeCamera(M::kFullOpenCv, 1280, 960,
                 {1000, 1001, 640, 480, 0.2, -0.1, 0.0008, -0.0006, 0.01, 0.25, -0.05, 0.01}),
      MakeCamera(M::kFov, 640, 480, {300, 301, 320.5, 239.5, 0.9}),
      MakeCamera(M::kSimpleRadialFisheye, 1280, 960, {600, 640, 480, 0.02}),
      MakeCamera(M::kRadialFisheye, 1280, 960, {600, 640, 480, 0.02, -0.005}),
      MakeCamera(
          M::kThinPrismFisheye, 1280, 960,
          {600, 601, 640, 480, 0.02, -0.005, 0.0005, -0.0003, 0.001, -0.0002, 0.0004, -0.0002}),
  };
}

TEST(CameraModel, NamesIdsAndParameterCountsMatchColmap) {
  // COLMAP's model ids (cameras.bin) and parameter counts (sensor/models.h).
  const std::vector<std::tuple<std::string, int, int>> expected = {{"SIMPLE_PINHOLE", 0, 3},
                                                                   {"PINHOLE", 1, 4},
                                                                   {"SIMPLE_RADIAL", 2, 4},
                                                                   {"RADIAL", 3, 5},
                                                                   {"OPENCV", 4, 8},
                                                                   {"OPENCV_FISHEYE", 5, 8},
                                                                   {"FULL_OPENCV", 6, 12},
                                                                   {"FOV", 7, 5},
                                                                   {"SIMPLE_RADIAL_FISHEYE", 8, 4},
                                                                   {"RADIAL_FISHEYE", 9, 5},
                                                                   {"THIN_PRISM_FISHEYE", 10, 12}};
  for (const auto& [name, id, count] : expected) {
    const std::optional<CameraModel> model = ParseCameraModel(name);
    ASSERT_TRUE(model.has_value()) << name;
    EXPECT_EQ(static_cast<int>(*model), id);
    EXPECT_EQ(CameraModelName(*model), name);
    EXPECT_EQ(CameraModelFromId(id), model);
    EXPECT_EQ(CameraModelParamCount(*model), count);
  }
  EXPECT_FALSE(ParseCameraModel("pinhole").has_value());
  EXPECT_FALSE(ParseCameraModel("EQUIRECTANGULAR").has_value());
  EXPECT_FALSE(CameraModelFromId(11).has_value());
  EXPECT_FALSE(CameraModelFromId(-1).has_value());
}

TEST(Camera, PinholeProjectionByHand) {
  const Camera camera = MakeCamera(CameraModel::kPinhole, 640, 480, {800, 900, 320, 240});
  // (1, 2, 4): u = 0.25, v = 0.5 -> (800 * 0.25 + 320, 900 * 0.5 + 240) = (520, 690).
  const auto pixel = camera.ImgFromCam({1, 2, 4});
  ASSERT_TRUE(pixel.has_value());
  EXPECT_DOUBLE_EQ(pixel->x(), 520);
  EXPECT_DOUBLE_EQ(pixel->y(), 690);
  // Back: the ray through (520, 690) is (0.25, 0.5, 1) normalized.
  const auto ray = camera.CamFromImg({520, 690});
  ASSERT_TRUE(ray.has_value());
  EXPECT_NEAR((*ray - Eigen::Vector3d(0.25, 0.5, 1).normalized()).norm(), 0, 1e-15);
  EXPECT_FALSE(camera.ImgFromCam({1, 2, 0}).has_value());
  EXPECT_FALSE(camera.ImgFromCam({1, 2, -1}).has_value());
  EXPECT_FALSE(camera.ImgFromCam({1, 2, std::nan("")}).has_value());
  EXPECT_DOUBLE_EQ(camera.MeanFocalLength(), 850);
  EXPECT_DOUBLE_EQ(camera.PrincipalPointX(), 320);
  EXPECT_DOUBLE_EQ(camera.PrincipalPointY(), 240);
  EXPECT_TRUE(camera.IsPinhole());
}

TEST(Camera, SimpleRadialProjectionByHand) {
  const Camera camera = MakeCamera(CameraModel::kSimpleRadial, 1000, 800, {1000, 500, 400, 0.1});
  // u = 0.3, v = -0.4, r^2 = 0.25, factor 1 + 0.1 * 0.25 = 1.025:
  // (1000 * 0.3075 + 500, 1000 * -0.41 + 400) = (807.5, -10).
  const auto pixel = camera.ImgFromCam({0.6, -0.8, 2});
  ASSERT_TRUE(pixel.has_value());
  EXPECT_NEAR(pixel->x(), 807.5, 1e-12);
  EXPECT_NEAR(pixel->y(), -10, 1e-12);
  const auto ray = camera.CamFromImg({807.5, -10});
  ASSERT_TRUE(ray.has_value());
  EXPECT_NEAR((*ray - Eigen::Vector3d(0.3, -0.4, 1).normalized()).norm(), 0, 1e-12);
}

TEST(Camera, OpenCvProjectionByHand) {
  const Camera camera =
      MakeCamera(CameraModel::kOpenCv, 1000, 1000, {1000, 1000, 0, 0, 0.1, 0.01, 0.001, 0.002});
  // u = 0.1, v = 0.2, r^2 = 0.05, radial = 0.1 * 0.05 + 0.01 * 0.0025 = 0.005025.
  // du = 0.1 * 0.005025 + 2 * 0.001 * 0.02 + 0.002 * (0.05 + 2 * 0.01) = 0.0006825
  // dv = 0.2 * 0.005025 + 2 * 0.002 * 0.02 + 0.001 * (0.05 + 2 * 0.04) = 0.001215
  const auto pixel = camera.ImgFromCam({0.1, 0.2, 1});
  ASSERT_TRUE(pixel.has_value());
  EXPECT_NEAR(pixel->x(), 100.6825, 1e-10);
  EXPECT_NEAR(pixel->y(), 201.215, 1e-10);
}

TEST(Camera, OpenCvFisheyeProjectionByHand) {
  const Camera camera =
      MakeCamera(CameraModel::kOpenCvFisheye, 1000, 1000, {400, 410, 500, 500, 0.1, 0.02, 0, 0});
  // A point 45 degrees off axis along x: theta = pi/4, theta_d = theta (1 + k1 t^2 + k2 t^4).
  const double t = M_PI / 4;
  const double theta_d = t * (1 + 0.1 * t * t + 0.02 * t * t * t * t);
  const auto pixel = camera.ImgFromCam({3, 0, 3});
  ASSERT_TRUE(pixel.has_value());
  EXPECT_NEAR(pixel->x(), 400 * theta_d + 500, 1e-10);
  EXPECT_NEAR(pixel->y(), 500, 1e-12);
  // Along y, 60 degrees: same formula with fy.
  const double t2 = M_PI / 3;
  const auto pixel2 = camera.ImgFromCam({0, std::tan(t2), 1});
  ASSERT_TRUE(pixel2.has_value());
  EXPECT_NEAR(pixel2->y(), 410 * t2 * (1 + 0.1 * t2 * t2 + 0.02 * std::pow(t2, 4)) + 500, 1e-10);
  EXPECT_TRUE(camera.IsFisheye());
}

TEST(Camera, FovProjectionByHand) {
  const double omega = 0.5;
  const Camera camera = MakeCamera(CameraModel::kFov, 1000, 1000, {300, 300, 500, 500, omega});
  // r = 0.5: r_d = atan(2 r tan(omega / 2)) / omega.
  const double rd = std::atan(2 * 0.5 * std::tan(omega / 2)) / omega;
  const auto pixel = camera.ImgFromCam({0.3, 0.4, 1});
  ASSERT_TRUE(pixel.has_value());
  EXPECT_NEAR(pixel->x(), 300 * 0.3 / 0.5 * rd + 500, 1e-10);
  EXPECT_NEAR(pixel->y(), 300 * 0.4 / 0.5 * rd + 500, 1e-10);
}

TEST(Camera, FullOpenCvRadialFisheyeAndThinPrismByHand) {
  // FULL_OPENCV: radial (1 + k1 r2 + k2 r4 + k3 r6) / (1 + k4 r2 + k5 r4 + k6 r6), tangential
  // as OPENCV. u = 0.2, v = -0.1: r2 = 0.05, uv = -0.02.
  const Camera full = MakeCamera(CameraModel::kFullOpenCv, 100, 100,
                                 {100, 200, 10, 20, 0.1, 0.2, 0.01, 0.02, 0.3, 0.4, 0.5, 0.6});
  {
    const double r2 = 0.05, u = 0.2, v = -0.1, uv = -0.02;
    const double radial = (1 + 0.1 * r2 + 0.2 * r2 * r2 + 0.3 * r2 * r2 * r2) /
                          (1 + 0.4 * r2 + 0.5 * r2 * r2 + 0.6 * r2 * r2 * r2);
    const double xd = u * radial + 2 * 0.01 * uv + 0.02 * (r2 + 2 * u * u);
    const double yd = v * radial + 2 * 0.02 * uv + 0.01 * (r2 + 2 * v * v);
    const auto pixel = full.ImgFromCam({0.4, -0.2, 2});
    ASSERT_TRUE(pixel.has_value());
    EXPECT_NEAR(pixel->x(), 100 * xd + 10, 1e-12);
    EXPECT_NEAR(pixel->y(), 200 * yd + 20, 1e-12);
  }
  // RADIAL_FISHEYE: theta = atan(r), theta_d = theta (1 + k1 theta^2 + k2 theta^4), along
  // the direction of (u, v). Point (3, 4, 5): r = 1, theta = pi / 4.
  const Camera radial_fisheye =
      MakeCamera(CameraModel::kRadialFisheye, 100, 100, {300, 50, 60, 0.05, -0.01});
  {
    const double t = M_PI / 4;
    const double td = t * (1 + 0.05 * t * t - 0.01 * t * t * t * t);
    const auto pixel = radial_fisheye.ImgFromCam({3, 4, 5});
    ASSERT_TRUE(pixel.has_value());
    EXPECT_NEAR(pixel->x(), 300 * td * 0.6 + 50, 1e-12);
    EXPECT_NEAR(pixel->y(), 300 * td * 0.8 + 60, 1e-12);
  }
  // THIN_PRISM_FISHEYE: on the angle-scaled (a, b) = theta * (u, v) / r, with
  // r2 = a^2 + b^2: radial k1 r2 + k2 r4 + k3 r6 + k4 r8, OPENCV's tangential terms, plus
  // sx1 r2 and sy1 r2.
  const Camera prism =
      MakeCamera(CameraModel::kThinPrismFisheye, 100, 100,
                 {300, 310, 50, 60, 0.05, -0.01, 0.001, 0.002, 0.003, -0.004, 0.0005, -0.0007});
  {
    const double t = M_PI / 4;
    const double a = t * 0.6, b = t * 0.8, r2 = t * t;
    const double radial =
        0.05 * r2 - 0.01 * r2 * r2 + 0.003 * std::pow(r2, 3) - 0.004 * std::pow(r2, 4);
    const double xd = a + a * radial + 2 * 0.001 * a * b + 0.002 * (r2 + 2 * a * a) + 0.0005 * r2;
    const double yd = b + b * radial + 2 * 0.002 * a * b + 0.001 * (r2 + 2 * b * b) - 0.0007 * r2;
    const auto pixel = prism.ImgFromCam({3, 4, 5});
    ASSERT_TRUE(pixel.has_value());
    EXPECT_NEAR(pixel->x(), 300 * xd + 50, 1e-12);
    EXPECT_NEAR(pixel->y(), 310 * yd + 60, 1e-12);
  }
}

// project(unproject(p)) = p over a dense grid covering the whole image, borders included.
TEST(Camera, UnprojectThenProjectIsIdentityOverTheImage) {
  for (const Camera& camera : RealisticCameras()) {
    SCOPED_TRACE(std::string(CameraModelName(camera.model)));
    constexpr int kSteps = 40;
    double worst = 0;
    for (int j = 0; j <= kSteps; ++j) {
      for (int i = 0; i <= kSteps; ++i) {
        const Eigen::Vector2d pixel(camera.width * i / double(kSteps),
                                    camera.height * j / double(kSteps));
        const auto ray = camera.CamFromImg(pixel);
        ASSERT_TRUE(ray.has_value()) << "pixel " << pixel.transpose();
        EXPECT_NEAR(ray->norm(), 1, 1e-12);
        EXPECT_GT(ray->z(), 0);
        // Any point along the ray projects to the same pixel.
        const auto back = camera.ImgFromCam(*ray * 3.7);
        ASSERT_TRUE(back.has_value());
        worst = std::max(worst, (*back - pixel).norm());
      }
    }
    EXPECT_LT(worst, 1e-6);
    RecordProperty(std::string(CameraModelName(camera.model)) + "_worst_px",
                   fmt::format("{:.3g}", worst));
  }
}

// unproject(project(X)) = X / |X| for random directions inside each image.
TEST(Camera, ProjectThenUnprojectRecoversTheRay) {
  std::mt19937_64 rng = testing::MakeRng();
  for (const Camera& camera : RealisticCameras()) {
    SCOPED_TRACE(std::string(CameraModelName(camera.model)));
    std::uniform_real_distribution<double> ux(0, camera.width), uy(0, camera.height);
    for (int n = 0; n < 500; ++n) {
      // A direction through a random pixel (found by unprojection), then a perturbed point.
      const auto ray = camera.CamFromImg({ux(rng), uy(rng)});
      ASSERT_TRUE(ray.has_value());
      const auto pixel = camera.ImgFromCam(*ray * 2.0);
      ASSERT_TRUE(pixel.has_value());
      const auto again = camera.CamFromImg(*pixel);
      ASSERT_TRUE(again.has_value());
      EXPECT_LT((*again - *ray).norm(), 1e-9);
    }
  }
}

TEST(Camera, FisheyeReachesWideAngles) {
  // OPENCV_FISHEYE with the image corner at about 76 degrees off axis: the corner ray is far
  // outside what a pinhole could show.
  const Camera camera = RealisticCameras()[5];
  ASSERT_EQ(camera.model, CameraModel::kOpenCvFisheye);
  const auto corner = camera.CamFromImg({0, 0});
  ASSERT_TRUE(corner.has_value());
  const double angle = std::acos(corner->z()) * 180 / M_PI;
  EXPECT_GT(angle, 70);
  EXPECT_LT(angle, 90);
}

TEST(Camera, UnprojectFailsBeyondTheUsableFieldOfView) {
  // SIMPLE_RADIAL with strong barrel distortion: r (1 - 0.5 r^2) peaks at r = sqrt(2/3) with
  // value 0.5443; no ray maps beyond it, so a pixel 0.6 f from the centre has no preimage.
  const Camera camera =
      MakeCamera(CameraModel::kSimpleRadial, 2000, 2000, {1000, 1000, 1000, -0.5});
  EXPECT_FALSE(camera.CamFromImg({1600, 1000}).has_value());
  EXPECT_TRUE(camera.CamFromImg({1500, 1000}).has_value());
  // A point on the folded branch (r = 1.2, distorted to 0.336) projects, but the pixel is
  // unprojected to the ray on the one-to-one branch (r ~ 0.36), not back to r = 1.2.
  const auto folded = camera.ImgFromCam({1.2, 0, 1});
  ASSERT_TRUE(folded.has_value());
  EXPECT_NEAR(folded->x(), 1000 + 1000 * 1.2 * (1 - 0.5 * 1.44), 1e-9);
  const auto ray = camera.CamFromImg(*folded);
  ASSERT_TRUE(ray.has_value());
  EXPECT_LT(ray->x() / ray->z(), 0.5);
  // Fisheye: theta_d beyond what any theta < 90 degrees reaches.
  const Camera fisheye =
      MakeCamera(CameraModel::kOpenCvFisheye, 2000, 2000, {300, 300, 1000, 1000, 0, 0, 0, 0});
  EXPECT_FALSE(fisheye.CamFromImg({1000 + 300 * 1.6, 1000}).has_value());
  EXPECT_TRUE(fisheye.CamFromImg({1000 + 300 * 1.5, 1000}).has_value());
  // FOV: angle reaches 90 degrees when r_d * omega = pi / 2.
  const Camera fov = MakeCamera(CameraModel::kFov, 2000, 2000, {300, 300, 1000, 1000, 0.9});
  EXPECT_FALSE(fov.CamFromImg({1000 + 300 * (M_PI / 2 / 0.9 + 0.01), 1000}).has_value());
  EXPECT_FALSE(camera.CamFromImg({std::nan(""), 0}).has_value());
}

TEST(Camera, ScaledFollowsThePixelCornerConvention) {
  for (const Camera& camera : RealisticCameras()) {
    SCOPED_TRACE(std::string(CameraModelName(camera.model)));
    const Camera half = camera.Scaled(camera.width / 2, camera.height / 2);
    EXPECT_EQ(half.width, camera.width / 2);
    EXPECT_EQ(half.height, camera.height / 2);
    // The image corner (width, height) and centre map to the halved positions.
    for (const Eigen::Vector2d& pixel :
         {Eigen::Vector2d(camera.width, camera.height),
          Eigen::Vector2d(camera.width / 2.0, camera.height / 2.0), Eigen::Vector2d(0, 0)}) {
      const auto ray = camera.CamFromImg(pixel);
      ASSERT_TRUE(ray.has_value());
      const auto scaled_pixel = half.ImgFromCam(*ray);
      ASSERT_TRUE(scaled_pixel.has_value());
      EXPECT_NEAR((*scaled_pixel - 0.5 * pixel).norm(), 0, 1e-6);
    }
    // Distortion coefficients are unchanged (index 4 on is distortion in every model).
    for (size_t i = 4; i < camera.params.size(); ++i) {
      EXPECT_EQ(half.params[i], camera.params[i]);
    }
  }
  // Hand example: PINHOLE 4032x3024 -> 504x378 divides everything by 8; SIMPLE_RADIAL keeps k.
  const Camera radial =
      MakeCamera(CameraModel::kSimpleRadial, 4032, 3024, {3260.526, 2016, 1512, 0.01975});
  const Camera small = radial.Scaled(504, 378);
  EXPECT_DOUBLE_EQ(small.params[0], 3260.526 / 8);
  EXPECT_DOUBLE_EQ(small.params[1], 252);
  EXPECT_DOUBLE_EQ(small.params[2], 189);
  EXPECT_DOUBLE_EQ(small.params[3], 0.01975);
  // Anisotropic: fx and cx follow the width, fy and cy the height.
  const Camera pinhole = MakeCamera(CameraModel::kPinhole, 100, 100, {80, 90, 50, 40});
  const Camera stretched = pinhole.Scaled(200, 50);
  EXPECT_EQ(stretched.params, (std::vector<double>{160, 45, 100, 20}));
  EXPECT_THROW(pinhole.Scaled(0, 10), Error);
}

void ExpectValidateError(const Camera& camera, const std::string& part) {
  try {
    camera.Validate("cameras.txt:3");
    ADD_FAILURE() << "no error for " << part;
  } catch (const Error& error) {
    const std::string message = error.what();
    EXPECT_EQ(message.rfind("cameras.txt:3: ", 0), 0u) << message;
    EXPECT_NE(message.find(part), std::string::npos) << message;
  }
}

TEST(Camera, ValidateRejectsBadCameras) {
  Camera camera;
  camera.model = CameraModel::kSimpleRadial;
  camera.width = 640;
  camera.height = 480;
  camera.params = {500, 320, 240, 0.01};
  EXPECT_NO_THROW(camera.Validate("ok"));

  Camera nan = camera;
  nan.params[3] = std::nan("");
  ExpectValidateError(nan, "NaN");
  Camera inf = camera;
  inf.params[1] = std::numeric_limits<double>::infinity();
  ExpectValidateError(inf, "NaN or infinite");
  Camera zero_focal = camera;
  zero_focal.params[0] = 0;
  ExpectValidateError(zero_focal, "focal length");
  Camera count = camera;
  count.params.pop_back();
  ExpectValidateError(count, "has 3 parameters, expected 4");
  Camera size = camera;
  size.height = 0;
  ExpectValidateError(size, "640x0");
  Camera bad_model = camera;
  bad_model.model = static_cast<CameraModel>(42);
  ExpectValidateError(bad_model, "unknown camera model id 42");
  Camera negative_fy = MakeCamera(CameraModel::kPinhole, 10, 10, {5, 5, 5, 5});
  negative_fy.params[1] = -5;
  ExpectValidateError(negative_fy, "focal length");
  // Wrong parameter count never reads out of bounds: projection throws instead.
  EXPECT_THROW(count.ImgFromCam({0, 0, 1}), Error);
  EXPECT_THROW(count.CamFromImg({0, 0}), Error);
}

TEST(Pose, FromQuaternionByHand) {
  // 90 degrees about z: q = (cos 45, 0, 0, sin 45); R maps x to y.
  const double h = std::sqrt(0.5);
  const Pose pose = Pose::FromQuaternion(h, 0, 0, h, {1, 2, 3});
  Eigen::Matrix3d expected;
  expected << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_LT((pose.rotation - expected).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_NO_THROW(pose.Validate("pose"));
  // x_cam = R x + t; centre = -R^T t.
  EXPECT_LT((pose.CamFromWorld(pose.Center())).norm(), 1e-15);
  EXPECT_LT((pose.Center() - Eigen::Vector3d(-2, 1, -3)).norm(), 1e-15);
  EXPECT_LT((pose.ViewDirection() - Eigen::Vector3d(0, 0, 1)).norm(), 1e-15);
  // Quaternion() round trip, sign normalized to w >= 0.
  const Eigen::Vector4d q = pose.Quaternion();
  EXPECT_LT((q - Eigen::Vector4d(h, 0, 0, h)).norm(), 1e-15);
  const Pose negated = Pose::FromQuaternion(-h, 0, 0, -h, {0, 0, 0});
  EXPECT_LT((negated.Quaternion() - Eigen::Vector4d(h, 0, 0, h)).norm(), 1e-15);
  // A slightly non-unit quaternion is normalized.
  const Pose scaled = Pose::FromQuaternion(2 * h, 0, 0, 2 * h, {0, 0, 0});
  EXPECT_LT((scaled.rotation - expected).cwiseAbs().maxCoeff(), 1e-15);
  // Zero quaternion: NaN rotation, rejected by Validate.
  EXPECT_THROW(Pose::FromQuaternion(0, 0, 0, 0, {0, 0, 0}).Validate("zero"), Error);
}

TEST(Pose, ValidateRejectsNonRotations) {
  Pose pose;
  EXPECT_NO_THROW(pose.Validate("identity"));
  Pose scaled = pose;
  scaled.rotation *= 1.01;
  EXPECT_THROW(scaled.Validate("scaled"), Error);
  Pose sheared = pose;
  sheared.rotation(0, 1) = 0.1;
  EXPECT_THROW(sheared.Validate("sheared"), Error);
  Pose reflection = pose;
  reflection.rotation(2, 2) = -1;
  try {
    reflection.Validate("images.txt:7");
    ADD_FAILURE() << "reflection accepted";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("images.txt:7: rotation is a reflection"),
              std::string::npos)
        << error.what();
  }
  Pose nan = pose;
  nan.translation.x() = std::nan("");
  EXPECT_THROW(nan.Validate("nan"), Error);
}

TEST(Pose, NearestRotationRepairsPrintedPrecision) {
  const Eigen::Matrix3d exact =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  // Rounded to 6 decimals, as some files print it: not a rotation to 1e-6, close to one.
  const Eigen::Matrix3d printed = (exact * 1e6).array().round() / 1e6;
  const Eigen::Matrix3d repaired = NearestRotation(printed, 1e-4, "bundle.out:12");
  Pose pose;
  pose.rotation = repaired;
  EXPECT_NO_THROW(pose.Validate("repaired"));
  EXPECT_LT((repaired - exact).cwiseAbs().maxCoeff(), 2e-6);
  EXPECT_THROW(NearestRotation(exact * 1.1, 1e-4, "scaled"), Error);
  EXPECT_THROW(NearestRotation(-exact, 1e-4, "reflection"), Error);
}

}  // namespace
}  // namespace rephoto::camera

namespace rephoto::camera {
namespace {

// The usable field against closed forms: for radial distortion d(r) = r (1 + k1 r^2 + k2 r^4)
// the Jacobian determinant is (1 + k1 r^2 + k2 r^4)(1 + 3 k1 r^2 + 5 k2 r^4), whose second
// factor vanishes first (k1 < 0) at r^2 = (-3 k1 - sqrt(9 k1^2 - 20 k2)) / (10 k2), or
// r^2 = -1 / (3 k1) when k2 = 0.
TEST(UsableField, FoldRadiusMatchesClosedForm) {
  struct Case {
    CameraModel model;
    std::vector<double> params;
    double expected;
  };
  const double k1 = -0.3, k2 = 0.01;
  const double opencv =
      std::sqrt((-3 * k1 - std::sqrt(9 * k1 * k1 - 20 * k2)) / (10 * k2));  // 1.0908
  for (const Case& c :
       {Case{CameraModel::kRadial, {500, 320, 240, -0.2, 0.0}, 1.0 / std::sqrt(0.6)},
        Case{CameraModel::kOpenCv, {500, 500, 320, 240, k1, k2, 0, 0}, opencv},
        Case{CameraModel::kSimpleRadial, {500, 320, 240, -0.05}, 1.0 / std::sqrt(0.15)}}) {
    Camera camera{c.model, 640, 480, c.params};
    const UsableField field(camera);
    SCOPED_TRACE(CameraModelName(c.model));
    EXPECT_LE(field.radius(), c.expected);
    EXPECT_GE(field.radius(), c.expected * 0.994);
    // Just inside and just outside, along a diagonal.
    const double inside = 0.99 * c.expected / std::sqrt(2.0);
    const double outside = 1.01 * c.expected / std::sqrt(2.0);
    EXPECT_TRUE(field.Contains({inside, inside, 1.0}));
    EXPECT_FALSE(field.Contains({outside, outside, 1.0}));
    EXPECT_FALSE(field.Contains({0.0, 0.0, -1.0}));  // behind the camera
  }
  // No fold: pinhole, pincushion (k1 > 0).
  for (const Camera& camera : {Camera{CameraModel::kPinhole, 640, 480, {500, 500, 320, 240}},
                               Camera{CameraModel::kRadial, 640, 480, {500, 320, 240, 0.1, 0.0}}}) {
    const UsableField field(camera);
    EXPECT_EQ(field.radius(), std::numeric_limits<double>::infinity());
    EXPECT_TRUE(field.Contains({100.0, 100.0, 1.0}));
  }
}

// What the field is for: with strong barrel distortion a point far outside the lens's view
// projects inside the image; the field rejects it.
TEST(UsableField, RejectsPointsTheDistortionFoldsIntoTheImage) {
  Camera camera{CameraModel::kRadial, 640, 480, {300, 320, 240, -0.2, 0.0}};
  // r = 2.5: d = 2.5 (1 - 0.2 * 6.25) = -0.625 -> 300 * -0.625 + 320 = 132.5, inside.
  const Eigen::Vector3d folded(2.5, 0.0, 1.0);
  const auto pixel = camera.ImgFromCam(folded);
  ASSERT_TRUE(pixel.has_value());
  EXPECT_NEAR(pixel->x(), 132.5, 1e-9);
  EXPECT_FALSE(UsableField(camera).Contains(folded));
}

}  // namespace
}  // namespace rephoto::camera

namespace rephoto::camera {
namespace {

// A camera larger than --max-pixels is refused by Validate, which every reader and the renderer
// call, naming the context: not an out-of-memory failure later.
TEST(Camera, SizeAboveMaxPixelsIsAnError) {
  const Camera huge{CameraModel::kPinhole, 1000000000, 1000000000, {1e9, 1e9, 5e8, 5e8}};
  try {
    huge.Validate("cameras.txt:3");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "cameras.txt:3: image size 1000000000x1000000000 is more than --max-pixels"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace rephoto::camera
