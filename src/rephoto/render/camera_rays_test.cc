#include "rephoto/render/camera_rays.h"

#include <cmath>
#include <cstring>
#include <random>
#include <utility>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
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
}

// Rays (the renderer's batch form) gives Ray's values bit for bit, for the pinhole formula and
// the table, including positions where a wide-angle model has no ray.
TEST(CameraRaysTest, BatchEqualsSingleRays) {
  camera::Camera pinhole;
  pinhole.model = camera::CameraModel::kPinhole;
  pinhole.width = 64;
  pinhole.height = 48;
  pinhole.params = {51.3, 52.1, 31.7, 24.2};
  camera::Camera distorted = pinhole;
  distorted.model = camera::CameraModel::kOpenCv;
  distorted.params = {30.0, 31.0, 31.7, 24.2, -0.5, 0.0, 0.0, 0.0};  // no rays at the rim
  camera::Camera mild = distorted;  // a ray at every corner of the table, edges included
  mild.params = {51.3, 52.1, 31.7, 24.2, -0.05, 0.01, 0.001, -0.002};
  auto rng = testing::MakeRng();
  std::uniform_real_distribution<float> ux(0, 64), uy(0, 48);
  for (const core::Isa isa : core::SupportedIsas()) {
    SCOPED_TRACE(core::IsaName(isa));
    const core::ScopedIsa scoped(isa);
    // The camera, and whether every position has a ray.
    for (const auto& [camera, everywhere] : std::vector<std::pair<camera::Camera, bool>>{
             {pinhole, true}, {distorted, false}, {mild, true}}) {
      const CameraRays rays(camera);
      EXPECT_EQ(rays.is_pinhole(), camera.model == camera::CameraModel::kPinhole);
      // Not a multiple of 8 (the table's vector width): the last positions take the scalar path.
      constexpr int kCount = 4096 + 5;
      std::vector<float> px(kCount), py(kCount), xn(kCount), yn(kCount);
      std::vector<int> ok(kCount);
      for (int i = 0; i < kCount; ++i) {
        px[i] = ux(rng);
        py[i] = uy(rng);
      }
      // The image's edges and corners (the clamped corners of the table), pixel corners and
      // positions a hair inside the edges.
      const float w = 64, h = 48, below_w = std::nextafter(w, 0.0f),
                  below_h = std::nextafter(h, 0.0f);
      const std::vector<std::pair<float, float>> edges = {
          {0, 0},       {w, 0},       {0, h},   {w, h},   {below_w, below_h},
          {w, 20.5f},   {31.5f, h},   {0, 17},  {12, 0},  {13, 14},
          {below_w, 0}, {0, below_h}, {32, 24}, {63, 47}, {1, 1}};
      for (size_t k = 0; k < edges.size(); ++k) {
        px[100 + k] = edges[k].first;
        py[100 + k] = edges[k].second;
        px[kCount - 1 - k % 5] = edges[k].first;
        py[kCount - 1 - k % 5] = edges[k].second;
      }
      rays.Rays(kCount, px.data(), py.data(), xn.data(), yn.data(), ok.data());
      int valid = 0;
      for (int i = 0; i < kCount; ++i) {
        float x, y;
        const bool has = rays.Ray(px[i], py[i], &x, &y);
        ASSERT_EQ(ok[i], has ? 1 : 0) << i;
        if (!has) continue;
        ++valid;
        EXPECT_EQ(std::memcmp(&x, &xn[i], sizeof x), 0) << i;
        EXPECT_EQ(std::memcmp(&y, &yn[i], sizeof y), 0) << i;
        if (rays.is_pinhole()) {
          float x1, y1;
          rays.PinholeRay(px[i], py[i], &x1, &y1);
          EXPECT_EQ(x1, x);
          EXPECT_EQ(y1, y);
        }
      }
      if (everywhere) {
        EXPECT_EQ(valid, kCount);
      } else {
        EXPECT_GT(valid, kCount / 5);
        EXPECT_LT(valid, kCount);  // about a quarter have a ray
      }
    }
  }
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
