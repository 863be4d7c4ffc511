// Issue 6, the ordering criterion of the paper's Section 3 on the demo scene: for each synthetic
// defect (Section 4.1: texture noise, geometry noise, simplification), more of the defect gives
// strictly more 1-NCC error, over six increasing strengths and several noise seeds. Photos are
// the ground truth rendered finely with exposure differences and sensor noise, as in the demo.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "rephoto/degrade/degrade.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/metrics/validity.h"
#include "rephoto/render/render.h"
#include "rephoto/synth/demo_scene.h"

namespace rephoto::demo {
namespace {

struct Photos {
  scene::Scene scene;
  std::vector<Image> images;
};

Image Rgb(const Image& rgba) {
  Image rgb(rgba.width(), rgba.height(), 3);
  for (size_t p = 0; p < rgb.pixel_count(); ++p) {
    for (int c = 0; c < 3; ++c) rgb.data()[3 * p + c] = rgba.data()[4 * p + c];
  }
  return rgb;
}

// Mean over the views of each view's masked mean 1-NCC (the demo's per-fold aggregate).
double MeanOneMinusNcc(const mesh::Mesh& model, const Photos& photos) {
  const render::RenderModel renderable(model);
  double sum = 0;
  for (size_t i = 0; i < photos.scene.views.size(); ++i) {
    const auto& view = photos.scene.views[i];
    const render::Rephoto r =
        render::RenderRephoto(renderable, photos.scene.CameraOf(view), view.cam_from_world);
    const Mask valid = metrics::CombineMasks(metrics::PhotoValidity(photos.images[i], {}),
                                             metrics::RephotoValidity(r.color));
    const auto result = metrics::ComputeMetric(metrics::Metric::kOneMinusNcc, photos.images[i],
                                               Rgb(r.color), valid);
    EXPECT_GT(result.evaluated, 0u);
    sum += result.mean;
  }
  return sum / static_cast<double>(photos.scene.views.size());
}

class DefectOrdering : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    options_.image_width = 256;
    options_.image_height = 192;
    options_.camera_count = 3;
    options_.ground_cells = 160;
    options_.object_bands = 80;
    truth_ = new mesh::Mesh(synth::MakeDemoMesh(options_));
    photos_ = new Photos{synth::MakeDemoScene(options_, "unused"), {}};
    const render::RenderModel model(*truth_);
    render::RenderOptions fine;
    fine.samples_per_pixel = 16;
    for (size_t i = 0; i < photos_->scene.views.size(); ++i) {
      const auto& view = photos_->scene.views[i];
      const auto clean =
          render::RenderRephoto(model, photos_->scene.CameraOf(view), view.cam_from_world, fine);
      const double gain = i % 2 == 0 ? 1.05 : 0.95;
      photos_->images.push_back(synth::SimulatePhoto(clean.color, gain, 0.01, 100 + i));
    }
  }
  static void TearDownTestSuite() {
    delete truth_;
    delete photos_;
  }

  // Asserts that the error strictly increases along `strengths` for every seed and returns
  // the errors of the first seed (printed for the issue note).
  void ExpectStrictlyIncreasing(const std::string& defect, const std::vector<float>& strengths,
                                void (*set)(degrade::DegradeOptions&, float)) {
    const double truth_error = MeanOneMinusNcc(*truth_, *photos_);
    for (uint64_t seed : {1, 2, 3}) {
      double previous = truth_error;
      std::string line = defect + " seed " + std::to_string(seed) + ": ground truth " +
                         std::to_string(truth_error);
      for (float strength : strengths) {
        degrade::DegradeOptions d;
        d.seed = seed;
        set(d, strength);
        const double error = MeanOneMinusNcc(degrade::Degrade(*truth_, d), *photos_);
        line += ", " + std::to_string(strength) + " -> " + std::to_string(error);
        EXPECT_GT(error, previous) << defect << " strength " << strength << " seed " << seed;
        previous = error;
      }
      std::printf("%s\n", line.c_str());
    }
  }

  static synth::DemoSceneOptions options_;
  static mesh::Mesh* truth_;
  static Photos* photos_;
};

synth::DemoSceneOptions DefectOrdering::options_;
mesh::Mesh* DefectOrdering::truth_ = nullptr;
Photos* DefectOrdering::photos_ = nullptr;

TEST_F(DefectOrdering, MoreTextureNoiseGivesMoreError) {
  ExpectStrictlyIncreasing("texture noise", {0.025f, 0.05f, 0.1f, 0.2f, 0.3f, 0.4f},
                           [](degrade::DegradeOptions& d, float s) { d.texture_noise = s; });
}

TEST_F(DefectOrdering, MoreGeometryNoiseGivesMoreError) {
  ExpectStrictlyIncreasing("geometry noise", {0.00025f, 0.0005f, 0.001f, 0.002f, 0.004f, 0.008f},
                           [](degrade::DegradeOptions& d, float s) { d.geometry_noise = s; });
}

TEST_F(DefectOrdering, MoreSimplificationGivesMoreError) {
  // Simplification is deterministic (no seed), so the three seeds repeat the same numbers.
  // The demo mesh carries its texture in its vertex colours, so beyond about 80 % removed the
  // texture is gone and 1-NCC saturates near 0.87 (unrelated content gives about 1); there the
  // order is noise (0.9 -> 0.872, 0.95 -> 0.870 at this size). The strengths stay below that.
  ExpectStrictlyIncreasing("simplification", {0.1f, 0.2f, 0.3f, 0.45f, 0.6f, 0.75f},
                           [](degrade::DegradeOptions& d, float s) { d.simplify = s; });
}

}  // namespace
}  // namespace rephoto::demo
