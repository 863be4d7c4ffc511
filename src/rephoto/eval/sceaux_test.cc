// Real data: the OpenMVS Sceaux Castle sample (../shared/data/openmvs_sceaux, see its
// SOURCE.txt): 11 cameras (COLMAP text derived from scene.mvs), 10 photos on disk (00010.jpg
// is missing), the uncoloured MVS mesh scene_mesh.ply (7378 vertices). Leave-one-out: each
// fold colours the mesh from its 9 training photos (--colorize) and rephotographs it at the
// held-out camera. To keep the test short, the mesh is coloured from the training photos at
// half size (--train-short-side 1064; each photo is decoded and downscaled once for all folds)
// and rephotos are rendered and compared at a quarter (--eval-short-side 532: 708x532).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

#include "rephoto/core/file.h"
#include "rephoto/eval/evaluate.h"
#include "rephoto/io/csv.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/testing/testing.h"

namespace rephoto::eval {
namespace {

namespace fs = std::filesystem;

TEST(SceauxTest, LeaveOneOutColorizedMeshIsSane) {
  REPHOTO_REQUIRE_DATA("openmvs_sceaux");
  const fs::path data = testing::SharedDataDir() / "openmvs_sceaux";
  const fs::path out = testing::MakeTempDir();
  EvaluateOptions o;
  o.scene = data / "colmap_text_derived";
  o.format = "colmap";
  o.image_root = data / "images";
  o.model = data / "scene_mesh.ply";
  o.colorize = true;
  o.scheme = "loo";
  o.eval_short_side = 532;
  o.train_short_side = 1064;
  o.metrics = {metrics::Metric::kOneMinusNcc, metrics::Metric::kCbCr};
  o.out = out / "run";
  const auto start = std::chrono::steady_clock::now();
  const EvaluateResult result = RunEvaluate(o);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // 00010.jpg has a camera but no photo: reported, not fatal.
  EXPECT_EQ(result.exit_code, ExitCode::kIncomplete);
  ASSERT_EQ(result.missing_photos, std::vector<std::string>{"00010.jpg"});
  ASSERT_EQ(result.folds.size(), 10u);
  EXPECT_EQ(result.evaluated_images, 10u);
  EXPECT_EQ(result.counters.models_colorized, 10u);

  const auto rows = io::ParseCsv(ReadFileToString(o.out / "per_image.csv"), "per_image.csv");
  ASSERT_EQ(rows.size(), 11u);
  const auto& header = rows[0];
  const auto column = [&](const std::string& name) {
    return static_cast<size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  std::printf(
      "Sceaux leave-one-out, mesh coloured per fold from 9 training photos (1416x1064), "
      "compared at 708x532:\n%-8s %-10s %8s %12s %8s\n",
      "fold", "image", "1-NCC", "completeness", "Cb+Cr");
  for (size_t r = 1; r < rows.size(); ++r) {
    const auto& row = rows[r];
    EXPECT_EQ(row[column("status")], "ok");
    const double ncc = std::stod(row[column("1-ncc")]);
    const double completeness = std::stod(row[column("completeness")]);
    std::printf("%-8s %-10s %8.4f %12.4f %8.4f\n", row[0].c_str(), row[column("name")].c_str(), ncc,
                completeness, std::stod(row[column("cb+cr")]));
    EXPECT_GT(completeness, 0.0);
    EXPECT_LT(completeness, 1.0);  // the mesh does not cover sky and surroundings
    EXPECT_LT(ncc, 0.75);
  }
  const MetricAggregate& ncc = result.metrics[0];
  std::printf(
      "1-NCC over images: median %.4f (min %.4f, max %.4f); completeness median %.4f; "
      "%.1f s (colorize %.1f s, render %.1f s, compare %.1f s, project %.1f s, "
      "report %.1f s)\n",
      ncc.over_images.median, ncc.over_images.min, ncc.over_images.max,
      result.completeness_over_images.median, seconds, result.timings.colorize,
      result.timings.render, result.timings.compare, result.timings.project, result.timings.report);
  EXPECT_TRUE(fs::exists(o.out / "projected/1-ncc.ply"));
  EXPECT_TRUE(fs::exists(o.out / "report.html"));

  // Control: the same mesh with its vertex colours shuffled (seeded) has no relation to the
  // photos; its 1-NCC is near 1, far above the real colours'.
  mesh::Mesh shuffled = mesh::ReadPly(o.out / "folds/fold_00/model.ply");
  std::mt19937_64 rng(7);
  std::shuffle(shuffled.colors.begin(), shuffled.colors.end(), rng);
  mesh::WritePly(out / "shuffled.ply", shuffled);
  EvaluateOptions control = o;
  control.model = out / "shuffled.ply";
  control.colorize = false;
  control.scheme = "none";
  control.report = false;
  control.projection_metric = "none";
  control.error_images = false;
  control.out = out / "control";
  const EvaluateResult shuffled_result = RunEvaluate(control);
  std::printf("shuffled colours: 1-NCC median %.4f\n",
              shuffled_result.metrics[0].over_images.median);
  EXPECT_GT(shuffled_result.metrics[0].over_images.median, 0.8);
  EXPECT_LT(ncc.over_images.max, shuffled_result.metrics[0].over_images.min);
  EXPECT_LT(ncc.over_images.median, 0.6 * shuffled_result.metrics[0].over_images.median);
}

}  // namespace
}  // namespace rephoto::eval
