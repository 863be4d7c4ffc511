// Fig. 8 in one command (paper Section 4.3): a sweep of geometric noise on the demo scene with
// its ground-truth mesh as the geometric reference. Each setting's rendered model is evaluated
// against the reference; sweep.csv and the report carry the geometric accuracy beside 1-NCC,
// the report's scatterplot has one point per run, and the correlations are checked against a
// hand computation from sweep.csv. With monotone defects the rank correlation is exactly 1.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>

#include "rephoto/core/file.h"
#include "rephoto/geometry/geometry.h"
#include "rephoto/geometry/run_geometry.h"
#include "rephoto/io/csv.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/report/report.h"
#include "rephoto/sweep/sweep.h"
#include "rephoto/synth/demo_files.h"
#include "rephoto/testing/testing.h"

namespace rephoto::sweep {
namespace {

namespace fs = std::filesystem;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

int Column(const std::vector<std::string>& header, const std::string& name) {
  for (size_t i = 0; i < header.size(); ++i) {
    if (header[i] == name) return static_cast<int>(i);
  }
  ADD_FAILURE() << "no column " << name;
  return 0;
}

// Pearson's r by the textbook formula, independent of geometry/correlation.cc.
double HandPearson(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += y[i];
    sxx += x[i] * x[i];
    syy += y[i] * y[i];
    sxy += x[i] * y[i];
  }
  return (n * sxy - sx * sy) / std::sqrt((n * sxx - sx * sx) * (n * syy - sy * sy));
}

// The value of attribute `name` on the element that has `anchor`.
std::string Attribute(const std::string& html, const std::string& anchor, const std::string& name) {
  const size_t at = html.find(anchor);
  if (at == std::string::npos) return "";
  const size_t start = html.rfind('<', at);
  const size_t end = html.find('>', at);
  const std::string element = html.substr(start, end - start);
  const std::regex re(name + "=\"([^\"]*)\"");
  std::smatch m;
  return std::regex_search(element, m, re) ? m[1].str() : "";
}

TEST(Fig8, GeometryNoiseSweepCorrelatesOneNccWithGeometricAccuracy) {
  const fs::path root = testing::MakeTempDir() / "scene";
  synth::DemoSceneOptions scene;
  scene.image_width = 160;
  scene.image_height = 120;
  scene.camera_count = 8;
  scene.ground_cells = 40;
  scene.object_bands = 24;
  synth::WriteDemoSceneFiles(scene, root, [](size_t i) {
    return synth::PhotoSettings{1, 0.01, i};
  });
  const mesh::Mesh truth = mesh::ReadPly(root / "truth.ply");
  const auto box = mesh::BoundingBox(truth);
  const double extent = (box[1] - box[0]).cast<double>().norm();
  // geometry_noise moves vertices by up to that fraction of the extent: tolerances between.
  const double t1 = 0.002 * extent, t2 = 0.006 * extent;

  const fs::path dir = testing::MakeTempDir();
  fs::create_directories(dir);
  std::ofstream(dir / "fig8.toml") << fmt::format(R"(
scene = "{0}/sparse"
image_root = "{0}/images"
model = "{0}/truth.ply"
scheme = "kfold:2"
metrics = ["1-ncc"]
projection_metric = "none"

[sweep]
geometry_noise = [0, 0.002, 0.005, 0.01, 0.02]
out = "fig8"
reference = "{0}/truth.ply"
tolerances = [{1}, {2}]
geometry_samples = 20000
)",
                                                  root.string(), t1, t2);
  const SweepOptions options = LoadSweepConfig(dir / "fig8.toml");
  EXPECT_EQ(options.reference, root / "truth.ply");
  EXPECT_EQ(options.geometry.samples, 20000u);
  ASSERT_EQ(options.geometry.tolerances.size(), 2u);
  const SweepResult result = RunSweep(options);
  ASSERT_EQ(result.settings.size(), 5u);
  for (const auto& s : result.settings) ASSERT_TRUE(s.ok) << s.message;

  // sweep.csv: the geometric columns beside the rephoto ones.
  const auto table = io::ParseCsv(ReadText(options.out / "sweep.csv"), "sweep.csv");
  ASSERT_EQ(table.size(), 6u);
  const int acc = Column(table[0], "geo_accuracy");
  const int ncc = Column(table[0], "1-ncc_median");
  const int comp1 = Column(table[0], fmt::format("geo_completeness@{:g}", t1));
  const int f1 = Column(table[0], fmt::format("geo_f_score@{:g}", t1));
  std::vector<double> accuracy, one_minus_ncc;
  for (size_t r = 1; r < table.size(); ++r) {
    accuracy.push_back(std::stod(table[r][acc]));
    one_minus_ncc.push_back(std::stod(table[r][ncc]));
  }
  // The undistorted model is the reference: accuracy 0 (up to float rounding), complete.
  EXPECT_LT(accuracy[0], 1e-6 * extent);
  EXPECT_DOUBLE_EQ(std::stod(table[1][comp1]), 1.0);
  EXPECT_DOUBLE_EQ(std::stod(table[1][f1]), 1.0);
  // Monotone defects: accuracy and 1-NCC both increase strictly; accuracy stays within the
  // maximum displacement (noise x extent).
  const double noise[] = {0, 0.002, 0.005, 0.01, 0.02};
  for (size_t i = 1; i < accuracy.size(); ++i) {
    EXPECT_GT(accuracy[i], accuracy[i - 1]) << i;
    EXPECT_GT(one_minus_ncc[i], one_minus_ncc[i - 1]) << i;
    EXPECT_LE(accuracy[i], noise[i] * extent * 1.001) << i;
    EXPECT_LT(std::stod(table[i + 1][comp1]), std::stod(table[i][comp1]) + 1e-12) << i;
  }

  // The sweep's numbers are the direct evaluation of the rendered model (fold 0's model.ply).
  const fs::path run = options.out / "settings" / "geometry_noise-0.01";
  const geometry::GeometryResult direct = geometry::EvaluateGeometry(
      mesh::ReadPly(run / "folds" / "fold_00" / "model.ply"), truth, options.geometry);
  EXPECT_NEAR(accuracy[3], direct.accuracy, 1e-9 * extent);

  // Cached in the run folder: a second evaluation reads it back, same numbers.
  const geometry::RunGeometry again =
      geometry::EvaluateRunGeometry(run, options.reference, options.geometry);
  EXPECT_TRUE(again.cached);
  EXPECT_TRUE(fs::is_regular_file(again.cache_file));
  EXPECT_EQ(again.cache_file.parent_path(), run / "geometry");
  ASSERT_EQ(again.models.size(), 2u);  // one model per fold
  EXPECT_EQ(again.models[0].path, run / "folds" / "fold_00" / "model.ply");
  // A fixed model degraded the same way in both folds: fold_01 rendered fold_00's model
  // (same colorize_key, reused in memory), linked into fold_01 as its model.ply, not truth.ply.
  EXPECT_EQ(again.models[1].path, run / "folds" / "fold_01" / "model.ply");
  EXPECT_EQ(ReadFileToString(again.models[1].path), ReadFileToString(again.models[0].path));
  EXPECT_DOUBLE_EQ(again.accuracy, accuracy[3]);
  // Other options: another cache file, computed afresh.
  geometry::GeometryOptions other = options.geometry;
  other.samples = 10000;
  const geometry::RunGeometry fresh = geometry::EvaluateRunGeometry(run, options.reference, other);
  EXPECT_FALSE(fresh.cached);
  EXPECT_NE(fresh.cache_file, again.cache_file);

  // The report: one scatter point per run, correlations as computed by hand.
  const std::string html = ReadText(options.out / "report.html");
  ASSERT_NE(html.find("<section id=\"geometry\">"), std::string::npos);
  size_t points = 0;
  for (size_t at = html.find("class=\"point-group\""); at != std::string::npos;
       at = html.find("class=\"point-group\"", at + 1)) {
    ++points;
  }
  EXPECT_EQ(points, 5u);
  const std::string row = "data-measure=\"accuracy\"";
  EXPECT_EQ(Attribute(html, row, "data-runs"), "5");
  EXPECT_DOUBLE_EQ(std::stod(Attribute(html, row, "data-spearman")), 1.0);
  const double pearson = std::stod(Attribute(html, row, "data-pearson"));
  EXPECT_NEAR(pearson, HandPearson(accuracy, one_minus_ncc), 1e-9);
  EXPECT_GT(pearson, 0.8);
  for (size_t i = 0; i < accuracy.size(); ++i) {
    std::printf("geometry_noise %g: accuracy %.6g (%.3g %% of the extent), 1-NCC median %.6g\n",
                noise[i], accuracy[i], 100 * accuracy[i] / extent, one_minus_ncc[i]);
  }
  std::printf("Pearson %.4f, Spearman %s over 5 runs\n", pearson,
              Attribute(html, row, "data-spearman").c_str());
  EXPECT_NE(html.find("data-col=\"geo_accuracy\""), std::string::npos);

  // The comparison report of the same runs (rephoto report --reference --csv): the ranking CSV
  // has the geometric columns, read from the cache.
  std::vector<report::CollectionEntry> entries;
  for (const auto& s : result.settings)
    entries.push_back({.label = s.setting.name, .run_dir = s.run_dir});
  report::CollectionOptions report_options;
  report_options.geometry_reference = options.reference;
  report_options.geometry_options = options.geometry;
  report_options.ranking_csv = dir / "ranking.csv";
  report::WriteCollectionReport(entries, dir / "report.html", report_options);
  const auto ranking = io::ParseCsv(ReadText(dir / "ranking.csv"), "ranking.csv");
  ASSERT_EQ(ranking.size(), 6u);
  const int label = Column(ranking[0], "label");
  const int ranking_acc = Column(ranking[0], "geo_accuracy");
  Column(ranking[0], fmt::format("geo_precision@{:g}", t2));
  for (size_t r = 1; r < ranking.size(); ++r) {
    const std::string name = ranking[r][label];
    for (size_t i = 0; i < result.settings.size(); ++i) {
      if (result.settings[i].setting.name == name) {
        EXPECT_DOUBLE_EQ(std::stod(ranking[r][ranking_acc]), accuracy[i]) << name;
      }
    }
  }
}

}  // namespace
}  // namespace rephoto::sweep
