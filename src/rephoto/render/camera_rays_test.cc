#include "rephoto/render/camera_rays.h"

#include <random>

#include "rephoto/core/error.h"
#include "rephoto/testing/testing.h"

namespace rephoto::render {
namespace {

// The interpolated table agrees with exact unprojection to well below a thousandth of a pixel.
TEST(CameraRaysTest, TableMatchesExactUnprojection) {
  camera::Camera camera;
  camera.model = camera::CameraModel::kOpenCv;
  camera.width = 320;
  camera.height = 240;
  camera.params = {300.0, 305.0, 161.0, 119.0, -0.3, 0.1, 0.001, -0.002};
  const CameraRays rays(camera);
  auto rng = testing::MakeRng();
  std::uniform_real_distribution<double> ux(0, 320), uy(0, 240);
  double worst = 0;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector2d pixel(ux(rng), uy(rng));
    float xn, yn;
    ASSERT_TRUE(rays.Ray(static_cast<float>(pixel.x()), static_cast<float>(pixel.y()), &xn, &yn));
    // Error measured in pixels: project the interpolated ray back.
    const auto back = camera.ImgFromCam(Eigen::Vector3d(xn, yn, 1));
    ASSERT_TRUE(back.has_value());
    worst = std::max(worst, (*back - pixel).norm());
  }
  std::printf("worst reprojection error of interpolated rays: %.2e px\n", worst);
  EXPECT_LT(worst, 1e-3);  // float storage limits it to ~1e-5 px at this focal length
  EXPECT_TRUE(rays.Matches(camera));
  camera.params[4] = -0.31;
  EXPECT_FALSE(rays.Matches(camera));
}

TEST(CameraRaysTest, PinholeIsExactAndBadCamerasAreErrors) {
  camera::Camera camera;
  camera.model = camera::CameraModel::kSimplePinhole;
  camera.width = 100;
  camera.height = 50;
  camera.params = {80.0, 50.0, 25.0};
  const CameraRays rays(camera);
  float xn, yn;
  ASSERT_TRUE(rays.Ray(90.0f, 5.0f, &xn, &yn));
  EXPECT_FLOAT_EQ(xn, 0.5f);
  EXPECT_FLOAT_EQ(yn, -0.25f);
  camera.params[0] = 0;
  EXPECT_THROW(CameraRays{camera}, Error);
}

}  // namespace
}  // namespace rephoto::render
