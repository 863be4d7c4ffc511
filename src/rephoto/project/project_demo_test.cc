// End-to-end check on the procedural demo scene: a model whose texture is degraded on one half
// of the object only must get higher projected errors on that half.
#include <gmock/gmock.h>

#include <cmath>
#include <limits>

#include "rephoto/degrade/degrade.h"
#include "rephoto/io/image_io.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/project/project.h"
#include "rephoto/render/render.h"
#include "rephoto/synth/demo_scene.h"
#include "rephoto/testing/testing.h"

namespace rephoto::project {
namespace {

namespace fs = std::filesystem;

// RGB copy of an RGBA rendering and its coverage mask (alpha > 0).
void SplitRgba(const Image& rgba, Image* rgb, Mask* covered) {
  *rgb = Image(rgba.width(), rgba.height(), 3);
  *covered = Mask(rgba.width(), rgba.height(), 1);
  for (int y = 0; y < rgba.height(); ++y) {
    for (int x = 0; x < rgba.width(); ++x) {
      for (int c = 0; c < 3; ++c) rgb->at(x, y, c) = rgba.at(x, y, c);
      covered->at(x, y) = rgba.at(x, y, 3) > 0 ? 1 : 0;
    }
  }
}

TEST(ProjectDemo, TextureNoiseOnOneHalfIsLocalized) {
  synth::DemoSceneOptions scene_options;
  scene_options.image_width = 320;
  scene_options.image_height = 240;
  scene_options.camera_count = 8;
  scene_options.ground_cells = 100;
  scene_options.object_bands = 80;
  const mesh::Mesh truth = synth::MakeDemoMesh(scene_options);
  const scene::Scene scene = synth::MakeDemoScene(scene_options, "images");
  const size_t ground_vertices = 101 * 101;
  ASSERT_GT(truth.vertex_count(), ground_vertices);

  // Fine-grained texture noise (features of ~1 cm, below the 9x9 window at this resolution),
  // kept only on the object's half x > 0.
  degrade::DegradeOptions noise;
  noise.texture_noise = 0.3f;
  noise.noise_frequency = 400;
  noise.seed = 7;
  mesh::Mesh degraded = degrade::Degrade(truth, noise);
  for (size_t i = 0; i < truth.vertex_count(); ++i) {
    if (i < ground_vertices || truth.positions[i].x() <= 0) degraded.colors[i] = truth.colors[i];
  }

  // "Photos" = the ground truth rendered; rephotos = the degraded model; 1-NCC error images in
  // the layout of a `rephoto compare` run.
  const fs::path run = testing::MakeTempDir();
  const render::RenderModel truth_model(truth);
  const render::RenderModel degraded_model(degraded);
  render::RenderOptions render_options;
  render_options.samples_per_pixel = 1;
  render::Rephoto photo, rephoto;
  Image photo_rgb, rephoto_rgb;
  Mask photo_covered, rephoto_covered;
  for (const scene::View& view : scene.views) {
    const camera::Camera& camera = scene.CameraOf(view);
    render::RenderRephoto(truth_model, *truth_model.RaysFor(camera), view.cam_from_world,
                          render_options, &photo);
    render::RenderRephoto(degraded_model, *degraded_model.RaysFor(camera), view.cam_from_world,
                          render_options, &rephoto);
    SplitRgba(photo.color, &photo_rgb, &photo_covered);
    SplitRgba(rephoto.color, &rephoto_rgb, &rephoto_covered);
    Mask valid(photo_covered.width(), photo_covered.height(), 1);
    for (size_t k = 0; k < valid.size(); ++k) {
      valid.data()[k] = photo_covered.data()[k] && rephoto_covered.data()[k];
    }
    const metrics::MetricResult error =
        metrics::ComputeMetric(metrics::Metric::kOneMinusNcc, photo_rgb, rephoto_rgb, valid);
    io::WriteExr(run / "errors" / (fs::path(view.name).stem().string() + ".1-ncc.exr"),
                 error.error);
  }

  size_t without = 99;
  const std::vector<ProjectView> views = FindErrorImages(scene, run, "1-ncc", &without);
  ASSERT_EQ(views.size(), scene.views.size());
  EXPECT_EQ(without, 0u);
  const ProjectResult result = ProjectErrors(truth, views, {});

  // Mean projected error over the seen object vertices of each half (away from the seam, where
  // windows straddle both halves).
  double sum[2] = {0, 0};
  size_t count[2] = {0, 0}, object[2] = {0, 0};
  for (size_t i = ground_vertices; i < truth.vertex_count(); ++i) {
    const float x = truth.positions[i].x();
    if (std::abs(x) < 0.1f) continue;
    const int half = x > 0 ? 1 : 0;
    ++object[half];
    if (result.view_count[i] == 0) continue;
    sum[half] += result.vertex_error[i];
    ++count[half];
  }
  ASSERT_GT(count[0], object[0] / 2);  // most of each half is seen by some camera
  ASSERT_GT(count[1], object[1] / 2);
  const double clean = sum[0] / count[0], noisy = sum[1] / count[1];
  RecordProperty("clean_half_mean_1ncc", std::to_string(clean));
  RecordProperty("noisy_half_mean_1ncc", std::to_string(noisy));
  // The clean half renders identically to the photo: 1-NCC is exactly 0 on windows that see
  // only clean surface.
  EXPECT_LT(clean, 0.01);
  EXPECT_GT(noisy, 0.1);
  // The colour range spans the two: the noisy half is mostly in the upper part of the map.
  EXPECT_LT(result.low, 0.01f);
  EXPECT_GT(result.high, 0.1f);
}

// The depth test against the rendered depth agrees with exact visibility by ray casting where
// visibility is unambiguous at pixel resolution. Reference per (vertex, view), for vertices
// projecting inside the image, from Embree rays from the camera centre C towards the vertex V
// and towards 8 points Q_k around it (V moved by 1.5 pixel footprints z / f in the camera's
// image plane, at V's depth, in 8 directions), so that the pixel containing V's projection
// (its centre is at most 0.71 px away) is covered by the same answer. With t = first hit as a
// fraction of the distance to the target:
//   clearly visible: t(V) >= 0.999 (nothing in front of V, as render/colorize.h decides), V
//                    faces the camera (normal . direction to camera > 0.3), V is not on the
//                    ground's open border, and every t(Q_k) in [0.97, 1.03] (a surface near
//                    V's depth all around: no occluder edge and no silhouette of V's own
//                    surface within 1.5 px; the 3 % leave room for the surface's slope);
//   clearly hidden:  t(V) < 0.95 and every t(Q_k) < 0.95 (an occluder at least 5 % of the
//                    depth in front, far beyond the tolerance, covering the pixel
//                    neighbourhood).
// The other pairs (silhouettes, grazing views, contact regions) are ambiguous at pixel
// resolution: whether the pixel there shows V depends on sub-pixel positions.
// Constant error images make view_count the number of views that see a vertex; projecting one
// view at a time gives the per-pair answer.
TEST(ProjectDemo, DepthTestAgreesWithRayCastVisibility) {
  synth::DemoSceneOptions scene_options;
  scene_options.image_width = 320;
  scene_options.image_height = 240;
  scene_options.camera_count = 8;
  scene_options.ground_cells = 100;
  scene_options.object_bands = 80;
  const mesh::Mesh truth = synth::MakeDemoMesh(scene_options);
  ASSERT_EQ(truth.normals.size(), truth.vertex_count());
  const scene::Scene scene = synth::MakeDemoScene(scene_options, "images");
  const size_t ground_vertices = 101 * 101;  // the ground grid comes first
  const fs::path run = testing::MakeTempDir();
  const render::RenderModel model(truth);
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  // First hit towards `to` as a fraction of the distance (infinity when nothing is hit).
  auto hit_fraction = [&](const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
    RTCRayHit hit;
    hit.ray.org_x = static_cast<float>(from.x());
    hit.ray.org_y = static_cast<float>(from.y());
    hit.ray.org_z = static_cast<float>(from.z());
    hit.ray.dir_x = static_cast<float>(to.x() - from.x());
    hit.ray.dir_y = static_cast<float>(to.y() - from.y());
    hit.ray.dir_z = static_cast<float>(to.z() - from.z());
    hit.ray.tnear = 0.0f;
    hit.ray.tfar = std::numeric_limits<float>::infinity();
    hit.ray.mask = 0xFFFFFFFFu;
    hit.ray.time = 0.0f;
    hit.ray.flags = 0;
    hit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(model.scene(), &context, &hit);
    return hit.hit.geomID == RTC_INVALID_GEOMETRY_ID ? std::numeric_limits<float>::infinity()
                                                     : hit.ray.tfar;
  };
  size_t visible = 0, visible_agree = 0, hidden = 0, hidden_agree = 0, ambiguous = 0;
  for (const scene::View& view : scene.views) {
    const camera::Camera& camera = scene.CameraOf(view);
    const fs::path path = run / (view.name + ".exr");
    io::WriteExr(path, Image(camera.width, camera.height, 1, 1.0f));
    const ProjectResult result =
        ProjectErrors(model, {{camera, view.cam_from_world, path, view.name}}, {});
    const Eigen::Vector3d centre = view.cam_from_world.Center();
    for (size_t i = 0; i < truth.vertex_count(); ++i) {
      const Eigen::Vector3d p = truth.positions[i].cast<double>();
      const auto pixel = camera.ImgFromCam(view.cam_from_world.CamFromWorld(p));
      if (!pixel || !(pixel->x() >= 0 && pixel->x() < camera.width && pixel->y() >= 0 &&
                      pixel->y() < camera.height)) {
        EXPECT_EQ(result.view_count[i], 0u);
        continue;
      }
      const bool seen = result.view_count[i] > 0;
      const Eigen::Vector3d cam = view.cam_from_world.CamFromWorld(p);
      const double footprint = cam.z() / camera.MeanFocalLength();
      auto beside = [&](double dx, double dy) -> Eigen::Vector3d {
        return view.cam_from_world.rotation.transpose() *
               (cam + Eigen::Vector3d(dx, dy, 0) * footprint - view.cam_from_world.translation);
      };
      int around_hidden = 0, around_surface = 0;  // of the 8 points 1.5 px around V
      for (int k = 0; k < 8; ++k) {
        const double angle = k * M_PI / 4;
        const float t = hit_fraction(centre, beside(1.5 * std::cos(angle), 1.5 * std::sin(angle)));
        around_hidden += t < 0.95f;
        around_surface += t >= 0.97f && t <= 1.03f;
      }
      const bool boundary =
          i < ground_vertices && (i % 101 == 0 || i % 101 == 100 || i / 101 == 0 || i / 101 == 100);
      const double facing =
          truth.normals[i].cast<double>().normalized().dot((centre - p).normalized());
      const float t = hit_fraction(centre, p);
      if (t < 0.95f && around_hidden == 8) {
        ++hidden;
        hidden_agree += !seen;
      } else if (t >= 0.999f && facing > 0.3 && around_surface == 8 && !boundary) {
        ++visible;
        visible_agree += seen;
      } else {
        ++ambiguous;
      }
    }
  }
  RecordProperty("clearly_visible_pairs", std::to_string(visible));
  RecordProperty("clearly_visible_seen", std::to_string(visible_agree));
  RecordProperty("clearly_hidden_pairs", std::to_string(hidden));
  RecordProperty("clearly_hidden_not_seen", std::to_string(hidden_agree));
  RecordProperty("ambiguous_pairs", std::to_string(ambiguous));
  ASSERT_GT(visible, 10000u);
  ASSERT_GT(hidden, 10000u);
  EXPECT_GT(static_cast<double>(visible_agree) / visible, 0.998);
  EXPECT_GT(static_cast<double>(hidden_agree) / hidden, 0.999);
}

}  // namespace
}  // namespace rephoto::project
