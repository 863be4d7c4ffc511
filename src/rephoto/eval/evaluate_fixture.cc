#include "rephoto/eval/evaluate_fixture.h"

#include "rephoto/testing/testing.h"

namespace rephoto::eval {

const synth::DemoSceneFiles& EvaluateTestScene() {
  static const synth::DemoSceneFiles files = [] {
    synth::DemoSceneOptions options;
    options.image_width = 160;
    options.image_height = 120;
    options.camera_count = kTestViews;
    options.ground_cells = 40;
    options.object_bands = 24;
    return synth::WriteDemoSceneFiles(
        options, testing::MakeTempDir() / "scene with space", [](size_t i) {
          return synth::PhotoSettings{1.0 + 0.02 * static_cast<double>(i % 3), 0.01, 100 + i};
        });
  }();
  return files;
}

EvaluateOptions EvaluateTestOptions(const std::filesystem::path& out) {
  EvaluateOptions o;
  o.scene = EvaluateTestScene().sparse;
  o.image_root = EvaluateTestScene().images;
  o.out = out;
  o.metrics = {metrics::Metric::kOneMinusNcc, metrics::Metric::kCbCr};
  o.report = false;
  o.projection_metric = "none";
  return o;
}

}  // namespace rephoto::eval
