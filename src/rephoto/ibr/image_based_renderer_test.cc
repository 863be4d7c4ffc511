#include "rephoto/ibr/image_based_renderer.h"

#include <gtest/gtest.h>

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
  const Score score = Evaluate(ibr.Render(demo_->scene.CameraOf(view), view.cam_from_world), 0);
  const Score vertex = VertexColourScore(0);
  std::cout << "IBR (true depth maps) 1-NCC " << score.one_minus_ncc << " (completeness "
            << score.completeness << "), vertex colours " << vertex.one_minus_ncc << "\n";
  EXPECT_LT(score.one_minus_ncc, 0.7 * vertex.one_minus_ncc);
  EXPECT_GT(score.completeness, 0.95);
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
