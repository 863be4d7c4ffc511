#include "rephoto/synth/demo_scene.h"

#include <gtest/gtest.h>

#include <cmath>

namespace rephoto::synth {
namespace {

DemoSceneOptions SmallOptions() {
  DemoSceneOptions options;
  options.ground_cells = 40;
  options.object_bands = 30;
  options.image_width = 320;
  options.image_height = 240;
  options.camera_count = 8;
  return options;
}

TEST(DemoScene, MeshHasTheStatedTopologyAndOutwardNormals) {
  const DemoSceneOptions options = SmallOptions();
  const mesh::Mesh m = MakeDemoMesh(options);
  m.Validate("demo mesh");
  const size_t ground_v = 41 * 41, object_v = 29 * 60 + 2;
  EXPECT_EQ(m.positions.size(), ground_v + object_v);
  EXPECT_EQ(m.faces.size(), 2u * 40 * 40 + 2u * 60 + 2u * 60 * 28);
  ASSERT_EQ(m.colors.size(), m.positions.size());
  ASSERT_EQ(m.normals.size(), m.positions.size());
  for (size_t v = 0; v < ground_v; ++v) EXPECT_GT(m.normals[v].z(), 0.99f);
  size_t outward = 0;
  for (size_t v = ground_v; v < m.positions.size(); ++v) {
    if (m.normals[v].dot(m.positions[v] - Eigen::Vector3f(0, 0, 0.5f)) > 0) ++outward;
  }
  EXPECT_EQ(outward, object_v);
  for (const auto& c : m.colors) {
    EXPECT_GE(c.minCoeff(), 0.f);
    EXPECT_LE(c.maxCoeff(), 1.f);
  }
}

TEST(DemoScene, AlbedoHasStructureAtPatchScale) {
  // Neighbouring samples 3 mm apart (about a photo pixel) must not all be equal: the patch
  // metrics need texture everywhere.
  double variation = 0;
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3f p(-1.f + 0.013f * i, 0.7f, 0.f);
    variation += (DemoAlbedo(p, 1) - DemoAlbedo(p + Eigen::Vector3f(0.003f, 0, 0), 1)).norm();
  }
  EXPECT_GT(variation / 100, 0.003);
  EXPECT_EQ(DemoAlbedo({0.1f, 0.2f, 0.3f}, 5), DemoAlbedo({0.1f, 0.2f, 0.3f}, 5));
}

TEST(DemoScene, EveryCameraLooksAtTheObject) {
  const DemoSceneOptions options = SmallOptions();
  const scene::Scene scene = MakeDemoScene(options, "photos");
  ASSERT_EQ(scene.views.size(), 8u);
  const camera::Camera& cam = scene.cameras.at(1);
  cam.Validate("demo camera");
  for (const auto& view : scene.views) {
    view.cam_from_world.Validate(view.name);
    const Eigen::Vector3d centre = view.cam_from_world.Center();
    EXPECT_NEAR(std::hypot(centre.x(), centre.y()), 3.2, 1e-9);
    const auto pixel = cam.ImgFromCam(view.cam_from_world.CamFromWorld({0, 0, 0.45}));
    ASSERT_TRUE(pixel.has_value());
    // The target is near the image centre (jitter of at most 5 cm at 3.3 m).
    EXPECT_NEAR(pixel->x(), 160, 12);
    EXPECT_NEAR(pixel->y(), 120, 12);
    EXPECT_EQ(view.image_path, std::filesystem::path("photos") / view.name);
  }
}

TEST(DemoScene, SimulatedPhotoAppliesGainNoiseAndQuantization) {
  Image clean(200, 100, 4, 0.f);
  for (int y = 0; y < 100; ++y) {
    for (int x = 0; x < 200; ++x) {
      for (int c = 0; c < 3; ++c) clean.at(x, y, c) = 0.2f + 0.5f * x / 200.f;
      clean.at(x, y, 3) = 1.f;
    }
  }
  const Image exact = SimulatePhoto(clean, 1.1, 0.0, 1);
  ASSERT_EQ(exact.channels(), 3);
  EXPECT_FLOAT_EQ(exact.at(10, 5, 1), std::round((0.2f + 0.5f * 10 / 200.f) * 1.1 * 255) / 255);
  const Image noisy = SimulatePhoto(clean, 1.0, 0.02, 1);
  double sum = 0, sum2 = 0;
  const size_t n = noisy.size();
  for (int y = 0; y < 100; ++y) {
    for (int x = 0; x < 200; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double d = noisy.at(x, y, c) - clean.at(x, y, c);
        sum += d;
        sum2 += d * d;
      }
    }
  }
  const double mean = sum / n, sigma = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 0, 0.002);
  // sigma^2 = noise^2 + quantization^2 (1/255^2/12).
  EXPECT_NEAR(sigma, std::sqrt(0.02 * 0.02 + 1.0 / (255.0 * 255.0 * 12)), 0.001);
  const Image again = SimulatePhoto(clean, 1.0, 0.02, 1);
  EXPECT_EQ(std::vector<float>(again.data(), again.data() + again.size()),
            std::vector<float>(noisy.data(), noisy.data() + noisy.size()));
}

}  // namespace
}  // namespace rephoto::synth
