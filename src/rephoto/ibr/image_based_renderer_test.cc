#include "rephoto/ibr/image_based_renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "rephoto/core/error.h"
#include "rephoto/ibr/demo_photos_test_util.h"
#include "rephoto/ibr/depth_map_io.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/render/render_model.h"
#include "rephoto/testing/testing.h"

namespace rephoto::ibr {
namespace {

// The demo scene at a small resolution: 12 cameras 30 degrees apart, a coarse mesh (ground cells
// of 8 cm, 40 object bands) whose vertex colours hold far less detail than the photos.
class ImageBasedRendererTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    synth::DemoSceneOptions options;
    options.image_width = 200;
    options.image_height = 150;
    options.camera_count = 12;
    options.ground_cells = 50;
    options.object_bands = 40;
    demo_ =
        new testing::DemoPhotos(testing::MakeDemoPhotos(options, rephoto::testing::MakeTempDir()));
  }
  static void TearDownTestSuite() {
    delete demo_;
    demo_ = nullptr;
  }

  static std::vector<TrainingView> AllBut(size_t held_out) {
    std::vector<TrainingView> training;
    for (size_t i = 0; i < demo_->scene.views.size(); ++i) {
      if (i != held_out) training.push_back(demo_->Training(i));
    }
    return training;
  }

  struct Score {
    double one_minus_ncc = 0;
    double completeness = 0;  // rendered pixels / pixels where the true surface is
  };
  // 1-NCC (9x9) of a rendering against view i's photo over the pixels the rendering covers.
  static Score Evaluate(const render::Rephoto& r, size_t i) {
    const Image& photo = demo_->photos[i];
    Image rgb(photo.width(), photo.height(), 3);
    Mask valid(photo.width(), photo.height(), 1);
    const Image truth = demo_->TrueDepth(i);
    size_t covered = 0, surface = 0;
    for (int y = 0; y < photo.height(); ++y) {
      for (int x = 0; x < photo.width(); ++x) {
        for (int c = 0; c < 3; ++c) rgb.at(x, y, c) = r.color.at(x, y, c);
        valid.at(x, y) = r.color.at(x, y, 3) > 0.5f;
        if (std::isfinite(truth.at(x, y))) {
          ++surface;
          covered += valid.at(x, y) != 0;
        }
      }
    }
    const metrics::MetricResult ncc =
        metrics::ComputeMetric(metrics::Metric::kOneMinusNcc, photo, rgb, valid);
    return {ncc.mean, static_cast<double>(covered) / surface};
  }

  static Score VertexColourScore(size_t i) {
    const render::RenderModel model(demo_->mesh);
    const scene::View& view = demo_->scene.views[i];
    return Evaluate(render::RenderRephoto(model, demo_->scene.CameraOf(view), view.cam_from_world),
                    i);
  }

  static testing::DemoPhotos* demo_;
};

testing::DemoPhotos* ImageBasedRendererTest::demo_ = nullptr;

TEST_F(ImageBasedRendererTest, VdtReproducesHeldOutViewsBetterThanVertexColours) {
  for (size_t held_out : {0u, 5u}) {
    const ImageBasedRenderer vdt = ImageBasedRenderer::Vdt(demo_->mesh, AllBut(held_out), {});
    const scene::View& view = demo_->scene.views[held_out];
    const Score score =
        Evaluate(vdt.Render(demo_->scene.CameraOf(view), view.cam_from_world), held_out);
    const Score vertex = VertexColourScore(held_out);
    std::cout << view.name << ": VDT 1-NCC " << score.one_minus_ncc << " (completeness "
              << score.completeness << "), vertex colours 1-NCC " << vertex.one_minus_ncc
              << " (completeness " << vertex.completeness << ")\n";
    EXPECT_LT(score.one_minus_ncc, 0.5 * vertex.one_minus_ncc);
    EXPECT_LT(score.one_minus_ncc, 0.1);
    EXPECT_GT(score.completeness, 0.97);
  }
}

TEST_F(ImageBasedRendererTest, TestPhotoInTheTrainingSetIsReproducedAlmostExactly) {
  // Epipole consistency: a training camera at the novel camera dominates the fusion, so a
  // renderer that saw the test photo scores (almost) perfectly: evaluation must hold it out.
  std::vector<TrainingView> training = AllBut(0);
  training.push_back(demo_->Training(0));
  const ImageBasedRenderer cheating = ImageBasedRenderer::Vdt(demo_->mesh, training, {});
  const ImageBasedRenderer honest = ImageBasedRenderer::Vdt(demo_->mesh, AllBut(0), {});
  const scene::View& view = demo_->scene.views[0];
  const camera::Camera camera = demo_->scene.CameraOf(view);
  const render::Rephoto r = cheating.Render(camera, view.cam_from_world);
  const Score seen = Evaluate(r, 0);
  const Score held_out = Evaluate(honest.Render(camera, view.cam_from_world), 0);
  std::cout << "test photo in training: 1-NCC " << seen.one_minus_ncc << ", held out "
            << held_out.one_minus_ncc << "\n";
  EXPECT_LT(seen.one_minus_ncc, 0.01);
  EXPECT_LT(seen.one_minus_ncc, 0.2 * held_out.one_minus_ncc);
  // Pixel values: the photo itself wherever the surface is visible (bilinear at the pixel
  // centre = the pixel), except where the occlusion test falls back to other views.
  size_t exact = 0, rendered = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      if (r.color.at(x, y, 3) == 0) continue;
      ++rendered;
      bool same = true;
      for (int c = 0; c < 3; ++c) {
        same &= std::abs(r.color.at(x, y, c) - demo_->photos[0].at(x, y, c)) < 1e-3f;
      }
      exact += same;
    }
  }
  EXPECT_GT(static_cast<double>(exact) / rendered, 0.98);
}

TEST_F(ImageBasedRendererTest, PixelsNoTrainingViewSeesAreInvalid) {
  // One training view on the opposite side of the ring: the novel view's pixels whose surface
  // point that view cannot see (the object's near side, ground hidden behind it, beyond its
  // image) must be invalid, and the sky too. Visibility is recomputed here independently:
  // the surface point projects inside the training photo and the training view's true depth
  // there matches (1 % tolerance; ambiguous pixels within 1-3 % are not counted).
  const size_t novel = 0, seen_from = 4;  // 120 degrees apart
  const ImageBasedRenderer vdt =
      ImageBasedRenderer::Vdt(demo_->mesh, {demo_->Training(seen_from)}, {});
  const scene::View& view = demo_->scene.views[novel];
  const camera::Camera camera = demo_->scene.CameraOf(view);
  const render::Rephoto r = vdt.Render(camera, view.cam_from_world);
  const Image truth = demo_->TrueDepth(novel);
  const Image other_depth = demo_->TrueDepth(seen_from);
  const scene::View& other = demo_->scene.views[seen_from];
  const camera::Camera other_camera = demo_->scene.CameraOf(other);
  const render::CameraRays rays(camera);
  size_t agree = 0, counted = 0, visible = 0, hidden = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const bool rendered = r.color.at(x, y, 3) > 0;
      const float z = truth.at(x, y);
      if (!std::isfinite(z)) {
        EXPECT_FALSE(rendered) << "sky pixel " << x << "," << y;
        continue;
      }
      float xn, yn;
      ASSERT_TRUE(rays.Ray(x + 0.5f, y + 0.5f, &xn, &yn));
      const Eigen::Vector3d X =
          view.cam_from_world.rotation.transpose() *
          (Eigen::Vector3d(xn * z, yn * z, z) - view.cam_from_world.translation);
      const Eigen::Vector3d p = other.cam_from_world.CamFromWorld(X);
      const auto pixel = other_camera.ImgFromCam(p);
      bool sees = false, ambiguous = false;
      if (pixel && pixel->x() >= 1 && pixel->y() >= 1 && pixel->x() <= other_camera.width - 1 &&
          pixel->y() <= other_camera.height - 1) {
        const float d = other_depth.at(static_cast<int>(pixel->x()), static_cast<int>(pixel->y()));
        const double error = std::abs(d - p.z()) / p.z();
        sees = error < 0.01;
        ambiguous = !sees && error < 0.03;
      }
      if (ambiguous) continue;
      ++counted;
      agree += sees == rendered;
      visible += sees;
      hidden += !sees;
    }
  }
  std::cout << "visibility: " << visible << " visible, " << hidden << " hidden, agreement "
            << static_cast<double>(agree) / counted << "\n";
  EXPECT_GT(visible, 1000u);
  EXPECT_GT(hidden, 1000u);
  EXPECT_GT(static_cast<double>(agree) / counted, 0.98);
}

TEST_F(ImageBasedRendererTest, IbrFromTrueDepthMapsReproducesHeldOutView) {
  // Ground-truth depth maps written in COLMAP's .bin format at half resolution.
  const std::filesystem::path folder = rephoto::testing::MakeTempDir();
  std::vector<TrainingView> training = AllBut(0);
  for (size_t i = 0; i < training.size(); ++i) {
    const size_t view = i + 1;
    const scene::View& v = demo_->scene.views[view];
    const camera::Camera half = demo_->scene.CameraOf(v).Scaled(100, 75);
    render::RenderOptions o;
    o.samples_per_pixel = 1;
    o.pattern = render::SamplePattern::kRegular;
    training[i].depth_map = folder / (v.name + ".geometric.bin");
    WriteColmapDepthMap(training[i].depth_map,
                        render::RenderRephoto(*demo_->geometry, half, v.cam_from_world, o).depth);
  }
  const ImageBasedRenderer ibr = ImageBasedRenderer::Ibr(training, {});
  EXPECT_EQ(ibr.depth_map(0).width(), 100);
  const scene::View& view = demo_->scene.views[0];
  const render::Rephoto r = ibr.Render(demo_->scene.CameraOf(view), view.cam_from_world);
  // The forward-warped proxies give the true depth (perspective-correct interpolation).
  const Image truth = demo_->TrueDepth(0);
  std::vector<float> errors;
  for (size_t i = 0; i < truth.pixel_count(); ++i) {
    if (std::isfinite(truth.data()[i]) && std::isfinite(r.depth.data()[i])) {
      errors.push_back(std::abs(r.depth.data()[i] - truth.data()[i]) / truth.data()[i]);
    }
  }
  ASSERT_GT(errors.size(), truth.pixel_count() / 2);
  std::sort(errors.begin(), errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.002);
  EXPECT_LT(errors[errors.size() * 95 / 100], 0.02);
  const Score score = Evaluate(r, 0);
  const Score vertex = VertexColourScore(0);
  std::cout << "IBR (true depth maps) 1-NCC " << score.one_minus_ncc << " (completeness "
            << score.completeness << "), vertex colours " << vertex.one_minus_ncc << "\n";
  EXPECT_LT(score.one_minus_ncc, 0.7 * vertex.one_minus_ncc);
  EXPECT_GT(score.completeness, 0.95);
  // The same depth maps given in memory (TrainingView::depth) instead of as files: the same
  // rendering, bit for bit (the file round trip is exact for float32).
  std::vector<TrainingView> in_memory = training;
  for (TrainingView& t : in_memory) {
    t.depth = std::make_shared<const Image>(ReadDepthMap(t.depth_map));
    t.depth_map.clear();
  }
  const ImageBasedRenderer ibr2 = ImageBasedRenderer::Ibr(in_memory, {});
  EXPECT_EQ(ibr2.depth_map(0).width(), 100);
  const render::Rephoto r2 = ibr2.Render(demo_->scene.CameraOf(view), view.cam_from_world);
  ASSERT_EQ(r2.color.pixel_count(), r.color.pixel_count());
  size_t differing = 0;
  for (size_t i = 0; i < r.color.pixel_count() * 4; ++i) {
    const float a = r.color.data()[i], b = r2.color.data()[i];
    differing += !(a == b || (std::isnan(a) && std::isnan(b)));
  }
  EXPECT_EQ(differing, 0u);
  // A multi-channel in-memory depth map is refused with the view's name.
  in_memory[1].depth = std::make_shared<const Image>(Image(10, 10, 3, 1.f));
  EXPECT_THROW(ImageBasedRenderer::Ibr(in_memory, {}), Error);
}

TEST_F(ImageBasedRendererTest, IbrFromPlaneSweepDepthRendersHeldOutViewReasonably) {
  ImageBasedOptions options;
  options.plane_sweep.num_planes = 64;
  for (const scene::Point3D& p : demo_->scene.points) options.scene_points.push_back(p.position);
  const ImageBasedRenderer ibr = ImageBasedRenderer::Ibr(AllBut(0), options);
  const scene::View& view = demo_->scene.views[0];
  const Score score = Evaluate(ibr.Render(demo_->scene.CameraOf(view), view.cam_from_world), 0);
  const Score vertex = VertexColourScore(0);
  std::cout << "IBR (plane sweep) 1-NCC " << score.one_minus_ncc << " (completeness "
            << score.completeness << "), vertex colours " << vertex.one_minus_ncc << "\n";
  EXPECT_LT(score.one_minus_ncc, 0.36);
  EXPECT_GT(score.completeness, 0.6);
}

// A camera 4 units from the origin at `degrees` from +z around the y axis, looking at the origin
// (the fusion tests' plane z = 0 is seen at 90 - degrees above it).
camera::Pose PoseAround(double degrees) {
  const double a = degrees * M_PI / 180;
  // Image y along +y (up = -y): the cameras turn about the image's vertical axis.
  return camera::LookAt({4 * std::sin(a), 0, 4 * std::cos(a)}, Eigen::Vector3d::Zero(),
                        -Eigen::Vector3d::UnitY());
}

// The plane z = 0 over [-half, half]^2, facing +z.
mesh::Mesh Plane(float half) {
  mesh::Mesh plane;
  plane.positions = {{-half, -half, 0}, {half, -half, 0}, {half, half, 0}, {-half, half, 0}};
  plane.faces = {{0, 1, 2}, {0, 2, 3}};
  return plane;
}

// Two constant-colour training photos of a plane, 10 and 25 degrees to either side of the novel
// camera: the weighted median returns the colour of the view with the smaller angle (Buehler's
// weights: 1 - p/p_th over p + epsilon), the other one when the novel camera moves towards it,
// and exactly a view's own colour at its own camera (epipole consistency).
TEST(ImageBasedRendererFusion, NearerViewWinsAndEpipoleIsConsistent) {
  const mesh::Mesh plane = Plane(5);
  const camera::Camera camera{camera::CameraModel::kPinhole, 64, 48, {60, 60, 32, 24}};
  const auto dir = rephoto::testing::MakeTempDir();
  io::WritePng(dir / "a.png", Image(64, 48, 3, 0.2f));
  io::WritePng(dir / "b.png", Image(64, 48, 3, 0.8f));
  const std::vector<TrainingView> training = {{"a", camera, PoseAround(-10), dir / "a.png", {}},
                                              {"b", camera, PoseAround(25), dir / "b.png", {}}};
  ImageBasedOptions options;
  options.k_best = 2;
  const ImageBasedRenderer vdt = ImageBasedRenderer::Vdt(plane, training, options);
  auto centre_value = [&](double degrees) {
    const camera::Pose pose = PoseAround(degrees);
    const render::Rephoto r = vdt.Render(camera, pose);
    EXPECT_EQ(r.color.at(32, 24, 3), 1.f);
    // Depth of the plane z = 0 through the centre of pixel (32, 24): (32.5 - 32) / 60 etc.
    const Eigen::Vector3d direction =
        pose.rotation.transpose() * Eigen::Vector3d(0.5 / 60, 0.5 / 60, 1);
    EXPECT_NEAR(r.depth.at(32, 24), -pose.Center().z() / direction.z(), 1e-4);
    return r.color.at(32, 24, 0);
  };
  EXPECT_NEAR(centre_value(0), 0.2f, 1e-6);   // 10 vs 25 degrees: a
  EXPECT_NEAR(centre_value(15), 0.8f, 1e-6);  // 25 vs 10 degrees: b
  EXPECT_NEAR(centre_value(-10), 0.2f, 1e-6);
  EXPECT_NEAR(centre_value(25), 0.8f, 1e-6);
}

// The resolution penalty (header, step 3) on the same plane, with the closed form written out
// here: the novel camera 60 degrees from the plane's normal, photo a at 80 degrees (20 from the
// novel camera, but grazing: 10 degrees above the plane) and photo b at 20 degrees (40 from the
// novel camera, steep). With k_best = 1 the pixel takes the colour of the smaller penalty. A
// pinhole pixel covers z^3 / (fx fy |X - C| |cos t|) of the plane, so a's penalty grows by
// r * log2(A_a / A_novel) and b's not at all (it samples the plane finer than the novel view):
// below the r where the two penalties meet the pixel is a's, above it b's.
TEST(ImageBasedRendererFusion, ResolutionPenaltyPrefersTheViewThatSeesTheSurfaceSteeply) {
  const mesh::Mesh plane = Plane(50);
  const camera::Camera camera{camera::CameraModel::kPinhole, 64, 48, {60, 60, 32, 24}};
  const camera::Pose novel = PoseAround(60), pose_a = PoseAround(80), pose_b = PoseAround(20);
  // The plane point of the novel camera's pixel (32, 24) and the closed-form penalties.
  const Eigen::Vector3d ray = novel.rotation.transpose() * Eigen::Vector3d(0.5 / 60, 0.5 / 60, 1);
  const Eigen::Vector3d X = novel.Center() - novel.Center().z() / ray.z() * ray;
  auto area = [&](const camera::Pose& pose) {
    const Eigen::Vector3d to = pose.Center() - X;
    const double z = (pose.rotation * X + pose.translation).z();
    return z * z * z / (60.0 * 60.0 * to.norm() * std::abs(to.z() / to.norm()));
  };
  auto angle = [&](const camera::Pose& pose) {
    return std::acos((pose.Center() - X).normalized().dot((novel.Center() - X).normalized()));
  };
  const double log_ratio = std::log2(area(pose_a) / area(novel));
  ASSERT_GT(log_ratio, 1.4);                   // cos 60 / cos 80 = 2.9: 1.53 doublings
  ASSERT_LT(area(pose_b), area(novel));        // b: no resolution term
  const double flip = (angle(pose_b) - angle(pose_a)) / log_ratio;  // about 0.23
  EXPECT_NEAR(flip, (40 - 20) * M_PI / 180 / std::log2(std::cos(M_PI / 3) / std::cos(4 * M_PI / 9)),
              0.01);

  const auto dir = rephoto::testing::MakeTempDir();
  io::WritePng(dir / "a.png", Image(64, 48, 3, 0.2f));
  io::WritePng(dir / "b.png", Image(64, 48, 3, 0.8f));
  const std::vector<TrainingView> training = {{"a", camera, pose_a, dir / "a.png", {}},
                                              {"b", camera, pose_b, dir / "b.png", {}}};
  auto centre_value = [&](double resolution_penalty) {
    ImageBasedOptions options;
    options.k_best = 1;
    options.resolution_penalty = resolution_penalty;
    const render::Rephoto r = ImageBasedRenderer::Vdt(plane, training, options).Render(camera, novel);
    EXPECT_EQ(r.color.at(32, 24, 3), 1.f);
    return r.color.at(32, 24, 0);
  };
  EXPECT_NEAR(centre_value(0), 0.2f, 1e-6);  // off: the smaller angle wins
  EXPECT_NEAR(centre_value(0.97 * flip), 0.2f, 1e-6);
  EXPECT_NEAR(centre_value(1.03 * flip), 0.8f, 1e-6);
  EXPECT_NEAR(centre_value(1.0), 0.8f, 1e-6);

  ImageBasedOptions bad;
  bad.resolution_penalty = -0.1;
  EXPECT_THROW(ImageBasedRenderer::Vdt(plane, training, bad), Error);
}

TEST_F(ImageBasedRendererTest, BadInputThrowsNamingTheFile) {
  std::vector<TrainingView> training = {demo_->Training(1)};
  training[0].photo = "/nonexistent/photo.png";
  try {
    ImageBasedRenderer::Vdt(demo_->mesh, training, {});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/photo.png"), std::string::npos) << e.what();
  }
  training = {demo_->Training(1), demo_->Training(2)};
  training[1].depth_map = "/nonexistent/depth.bin";
  try {
    ImageBasedRenderer::Ibr(training, {});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/depth.bin"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ImageBasedRenderer::Vdt(demo_->mesh, {}, {}), Error);
  ImageBasedOptions bad;
  bad.k_best = 0;
  EXPECT_THROW(ImageBasedRenderer::Vdt(demo_->mesh, {demo_->Training(1)}, bad), Error);
}

}  // namespace
}  // namespace rephoto::ibr
