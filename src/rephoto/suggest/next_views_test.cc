#include "rephoto/suggest/next_views.h"

#include <cmath>
#include <numbers>

#include "rephoto/core/error.h"
#include "rephoto/geometry/shapes.h"
#include "rephoto/synth/demo_scene.h"
#include "rephoto/testing/testing.h"

namespace rephoto::suggest {
namespace {

camera::Camera TestCamera() {
  camera::Camera camera;
  camera.model = camera::CameraModel::kPinhole;
  camera.width = 640;
  camera.height = 480;
  camera.params = {500, 500, 320, 240};
  return camera;
}

// A camera at `center` looking at the origin, image y along -z (z is up).
camera::Pose LookAtOrigin(const Eigen::Vector3d& center) {
  const Eigen::Vector3d z = -center.normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  camera::Pose pose;
  pose.rotation.row(0) = x.transpose();
  pose.rotation.row(1) = z.cross(x).transpose();
  pose.rotation.row(2) = z.transpose();
  pose.translation = -pose.rotation * center;
  return pose;
}

Eigen::Vector3d OnSphere(double radius, double azimuth_degrees, double elevation_degrees) {
  const double a = azimuth_degrees * std::numbers::pi / 180;
  const double e = elevation_degrees * std::numbers::pi / 180;
  return radius *
         Eigen::Vector3d(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e));
}

// The unit sphere seen from (4, 0, 0): the horizon is the circle x = 1/4 (the tangent cone),
// so vertices clearly in front of it are seen and those behind it are not.
TEST(SuggestTest, VisibleVerticesOfASphere) {
  const render::RenderModel model(geometry::MakeIcosphere(1.0, 4));
  const std::vector<Eigen::Vector3f> normals = mesh::ComputeVertexNormals(model.mesh());
  const std::vector<uint8_t> visible =
      VisibleVertices(model, normals, TestCamera(), LookAtOrigin({4, 0, 0}));
  for (size_t i = 0; i < visible.size(); ++i) {
    const float x = model.mesh().positions[i].x();
    if (x > 0.35f) {
      EXPECT_EQ(visible[i], 1) << i;
    }
    if (x < 0.2f) {
      EXPECT_EQ(visible[i], 0) << i;
    }
  }
}

// Eight photos see the sphere from one side only (azimuths -60..60 degrees around +x,
// elevations -15 and +15); about a quarter of the surface, at the back, is unobserved. The
// first suggestion must look at the back, each must add unobserved surface, and together they
// must see most of what no photo saw.
TEST(SuggestTest, SuggestionsLookAtTheUnseenSide) {
  const render::RenderModel model(geometry::MakeIcosphere(1.0, 4));
  scene::Scene scene;
  scene.cameras[1] = TestCamera();
  for (int k = 0; k < 8; ++k) {
    scene::View view;
    view.name = "photo_" + std::to_string(k) + ".png";
    view.camera_id = 1;
    view.cam_from_world = LookAtOrigin(OnSphere(4, -60 + 120.0 * (k / 2) / 3, k % 2 ? 15 : -15));
    scene.views.push_back(view);
  }
  SuggestOptions options;
  options.count = 3;
  const SuggestResult result = SuggestViews(model, scene, TestCamera(), {}, options);
  ASSERT_EQ(result.suggestions.size(), 3u);
  EXPECT_GT(result.unobserved_area, 0.2 * result.total_area);
  const double covered = result.unobserved_area_covered / result.unobserved_area;
  EXPECT_GT(covered, 0.95) << covered;
  EXPECT_NEAR(result.distance, 4.0, 1e-9);
  for (const Suggestion& s : result.suggestions) {
    EXPECT_NEAR(s.cam_from_world.Center().norm(), 4.0, 1e-6);
    // Each looks at the model's centre.
    EXPECT_GT(s.cam_from_world.ViewDirection().dot(-s.cam_from_world.Center().normalized()), 0.999);
    EXPECT_GT(s.unobserved_area, 0);
  }
  EXPECT_LT(result.suggestions[0].cam_from_world.Center().x(), -2.0);
  RecordProperty("unobserved_covered", std::to_string(covered));
  std::printf("unobserved area %.3f of %.3f; the 3 suggestions see %.1f %% of it\n",
              result.unobserved_area, result.total_area, 100 * covered);

  // With the whole sphere observed, projected errors decide: the high-error cap (x < -0.5)
  // attracts the first suggestion.
  std::vector<float> errors(model.mesh().vertex_count());
  for (size_t i = 0; i < errors.size(); ++i) {
    errors[i] = model.mesh().positions[i].x() < -0.5f ? 1.0f : 0.1f;
  }
  scene::Scene all_round = scene;
  for (int k = 0; k < 8; ++k) {
    scene::View view = scene.views[static_cast<size_t>(k)];
    view.name = "back_" + std::to_string(k) + ".png";
    view.cam_from_world =
        LookAtOrigin(OnSphere(4, 180 - 60 + 120.0 * (k / 2) / 3, k % 2 ? 15 : -15));
    all_round.views.push_back(view);
  }
  for (int k = 0; k < 2; ++k) {
    scene::View view = scene.views[0];
    view.name = "pole_" + std::to_string(k) + ".png";
    view.cam_from_world = LookAtOrigin(OnSphere(4, 90, k ? 80 : -80));
    all_round.views.push_back(view);
  }
  for (int k = 0; k < 4; ++k) {
    scene::View view = scene.views[0];
    view.name = "side_" + std::to_string(k) + ".png";
    view.cam_from_world = LookAtOrigin(OnSphere(4, k < 2 ? 90 : -90, k % 2 ? 30 : -30));
    all_round.views.push_back(view);
  }
  const SuggestResult by_error = SuggestViews(model, all_round, TestCamera(), errors, options);
  EXPECT_LT(by_error.suggestions[0].cam_from_world.Center().x(), -2.0);
  // The mean error a suggestion looks at: none without errors; a constant field's value; with
  // the high-error cap in view, above the low value and below the high one.
  for (const Suggestion& s : result.suggestions) EXPECT_TRUE(std::isnan(s.mean_error));
  const SuggestResult constant =
      SuggestViews(model, all_round, TestCamera(),
                   std::vector<float>(model.mesh().vertex_count(), 0.25f), options);
  for (const Suggestion& s : constant.suggestions) EXPECT_NEAR(s.mean_error, 0.25, 1e-12);
  EXPECT_GT(by_error.suggestions[0].mean_error, 0.1);
  EXPECT_LT(by_error.suggestions[0].mean_error, 1.0);
  EXPECT_THROW(SuggestViews(model, scene, TestCamera(), {1.0f}, options), Error);
}

// The demo scene (synth/demo_scene.h: an object on a ground plane, cameras on a ring), coarse,
// photographed from one half of the ring only: the suggestions must see most of the surface
// those photos miss (the object's far side and the ground behind it).
TEST(SuggestTest, DemoSceneFromOneSide) {
  synth::DemoSceneOptions demo;
  demo.image_width = 320;
  demo.image_height = 240;
  demo.camera_count = 16;
  demo.ground_cells = 60;
  demo.object_bands = 60;
  const render::RenderModel model(synth::MakeDemoMesh(demo));
  scene::Scene scene = synth::MakeDemoScene(demo, "images");
  const std::array<Eigen::Vector3f, 2> box = mesh::BoundingBox(model.mesh());
  const Eigen::Vector3d target = 0.5 * (box[0].cast<double>() + box[1].cast<double>());
  std::vector<scene::View> one_side;
  for (const scene::View& view : scene.views) {
    if (view.cam_from_world.Center().x() > target.x()) one_side.push_back(view);
  }
  ASSERT_GE(one_side.size(), 4u);
  ASSERT_LT(one_side.size(), scene.views.size());
  scene.views = one_side;
  SuggestOptions options;
  options.count = 3;
  const SuggestResult result =
      SuggestViews(model, scene, scene.cameras.begin()->second, {}, options);
  const double covered = result.unobserved_area_covered / result.unobserved_area;
  std::printf(
      "demo scene, %zu photos from one side: %.1f %% of the surface unseen; the 3 "
      "suggestions see %.1f %% of it\n",
      one_side.size(), 100 * result.unobserved_area / result.total_area, 100 * covered);
  EXPECT_GT(result.unobserved_area, 0.05 * result.total_area);
  EXPECT_GT(covered, 0.7);
  EXPECT_LT(result.suggestions[0].cam_from_world.Center().x(), target.x());
  // The photos look down from one side: no suggestion from under the horizon of the model's
  // centre (the world's z is up; the photos' mean -y axis alone would tilt toward -x).
  for (const Suggestion& s : result.suggestions) {
    EXPECT_GE(s.cam_from_world.Center().z(), target.z() - 1e-6);
  }
}

}  // namespace
}  // namespace rephoto::suggest
