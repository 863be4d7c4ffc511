// The geometric evaluation of a run folder (run_geometry.h) on hand-made run folders whose
// models are spheres around a unit reference sphere: per-fold models averaged (closed forms),
// cache reuse and invalidation, run.json fallback, and hostile or malformed records.
#include "rephoto/geometry/run_geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/geometry/shapes.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/testing/testing.h"

namespace rephoto::geometry {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

void WriteJson(const fs::path& path, const Json& json) {
  fs::create_directories(path.parent_path());
  std::ofstream(path) << json.dump(2);
}

GeometryOptions Options() {
  GeometryOptions o;
  o.tolerances = {0.03, 0.07};
  o.accuracy_fraction = 0.9;
  o.samples = 20000;
  return o;
}

struct Fixture {
  fs::path dir = testing::MakeTempDir();
  fs::path run = dir / "run";
  fs::path reference = dir / "gt.ply";
  Fixture() {
    mesh::WritePly(reference, MakeIcosphere(1.0, 5));
    mesh::WritePly(dir / "r102.ply", MakeIcosphere(1.02, 5));
    // fold_00: a fixed model (absolute path); fold_01: its derived model.ply (r = 1.05);
    // fold_02 failed (ignored).
    WriteJson(run / "folds/fold_00/fold.json",
              {{"fold", "fold_00"}, {"status", "ok"}, {"model", (dir / "r102.ply").string()}});
    WriteJson(run / "folds/fold_01/fold.json", {{"fold", "fold_01"},
                                                {"status", "ok"},
                                                {"model", (dir / "r102.ply").string()},
                                                {"colorize_key", "k1"},
                                                {"colorized_model", "model.ply"}});
    mesh::WritePly(run / "folds/fold_01/model.ply", MakeIcosphere(1.05, 5));
    WriteJson(run / "folds/fold_02/fold.json",
              {{"fold", "fold_02"}, {"status", "failed"}, {"model", "nowhere.ply"}});
  }
};

TEST(RunGeometry, PerFoldModelsAveragedAndCached) {
  Fixture f;
  const std::vector<RunModel> models = FindRunModels(f.run);
  ASSERT_EQ(models.size(), 2u);
  EXPECT_EQ(models[0].path, f.dir / "r102.ply");
  EXPECT_EQ(models[1].path, f.run / "folds/fold_01/model.ply");

  const RunGeometry g = EvaluateRunGeometry(f.run, f.reference, Options());
  ASSERT_TRUE(g.available) << g.message;
  EXPECT_FALSE(g.cached);
  // Concentric spheres: every model point lies (R - 1) from the reference, up to the
  // tessellation (sagitta ~1e-4 at this subdivision): accuracy (0.02 + 0.05) / 2.
  const double tess = TessellationError(MakeIcosphere(1.05, 5), 1.05, Eigen::Vector3d::Zero());
  EXPECT_NEAR(g.accuracy, 0.035, 2 * tess + 1e-6);
  // At 0.03 the 1.02 sphere is complete and precise, the 1.05 sphere not at all: 0.5; at 0.07
  // both are: 1.
  ASSERT_EQ(g.tolerances.size(), 2u);
  EXPECT_NEAR(g.tolerances[0].completeness, 0.5, 1e-12);
  EXPECT_NEAR(g.tolerances[0].precision, 0.5, 1e-12);
  EXPECT_NEAR(g.tolerances[0].f_score, 0.5, 1e-12);
  EXPECT_NEAR(g.tolerances[1].f_score, 1.0, 1e-12);
  EXPECT_EQ(g.cache_file.parent_path(), f.run / "geometry");
  ASSERT_TRUE(fs::is_regular_file(g.cache_file));
  const Json cache = Json::parse(std::ifstream(g.cache_file));
  EXPECT_EQ(cache["schema"], "rephoto.run_geometry/1");
  EXPECT_EQ(cache["folds"].size(), 2u);

  const RunGeometry again = EvaluateRunGeometry(f.run, f.reference, Options());
  EXPECT_TRUE(again.cached);
  EXPECT_EQ(again.accuracy, g.accuracy);
  EXPECT_EQ(again.tolerances[0].completeness, g.tolerances[0].completeness);

  // A changed model is evaluated afresh: (0.02 + 0.04) / 2.
  mesh::WritePly(f.run / "folds/fold_01/model.ply", MakeIcosphere(1.04, 5));
  const RunGeometry changed = EvaluateRunGeometry(f.run, f.reference, Options());
  EXPECT_FALSE(changed.cached);
  EXPECT_NE(changed.cache_file, g.cache_file);
  EXPECT_NEAR(changed.accuracy, 0.03, 2 * tess + 1e-6);

  const std::vector<std::string> columns = RunGeometryColumns(Options());
  ASSERT_EQ(columns.size(), 9u);
  EXPECT_EQ(columns[0], "geo_accuracy");
  EXPECT_EQ(columns[1], "geo_completeness@0.03");
  EXPECT_EQ(columns[8], "geo_f_score@0.07");
  const std::vector<double> values = RunGeometryValues(changed, Options());
  EXPECT_EQ(values[0], changed.accuracy);
  EXPECT_EQ(values[8], changed.tolerances[1].f_score);
}

TEST(RunGeometry, RunJsonFallbackAndUnavailableRuns) {
  Fixture f;
  // No fold records: run.json inputs.model (relative to the run folder).
  const fs::path single = f.dir / "single";
  mesh::WritePly(single / "m.ply", MakeIcosphere(1.02, 5));
  WriteJson(single / "run.json", {{"inputs", {{"model", {{"path", "m.ply"}}}}}});
  const RunGeometry g = EvaluateRunGeometry(single, f.reference, Options());
  ASSERT_TRUE(g.available) << g.message;
  EXPECT_NEAR(g.accuracy, 0.02, 1e-3);
  EXPECT_NEAR(g.tolerances[0].completeness, 1.0, 1e-12);

  // A compare run (no model): unavailable, with the reason, and NaN values.
  const fs::path compare = f.dir / "compare";
  fs::create_directories(compare);
  const RunGeometry none = EvaluateRunGeometry(compare, f.reference, Options());
  EXPECT_FALSE(none.available);
  EXPECT_NE(none.message.find("no model"), std::string::npos) << none.message;
  EXPECT_TRUE(std::isnan(RunGeometryValues(none, Options())[0]));

  // A hostile derived-model name never leaves the fold's folder.
  WriteJson(f.run / "folds/fold_01/fold.json",
            {{"status", "ok"}, {"colorized_model", "../../../r102.ply"}});
  const RunGeometry hostile = EvaluateRunGeometry(f.run, f.reference, Options());
  EXPECT_FALSE(hostile.available);
  EXPECT_NE(hostile.message.find("not a file name"), std::string::npos) << hostile.message;

  // A derived model missing without another fold to share it.
  WriteJson(f.run / "folds/fold_01/fold.json",
            {{"status", "ok"}, {"colorize_key", "zz"}, {"colorized_model", "gone.ply"}});
  const RunGeometry missing = EvaluateRunGeometry(f.run, f.reference, Options());
  EXPECT_FALSE(missing.available);
  EXPECT_NE(missing.message.find("fold_01/fold.json"), std::string::npos) << missing.message;

  // Malformed JSON names the file.
  std::ofstream(f.run / "folds/fold_01/fold.json") << "{not json";
  const RunGeometry bad = EvaluateRunGeometry(f.run, f.reference, Options());
  EXPECT_FALSE(bad.available);
  EXPECT_NE(bad.message.find("fold.json: not valid JSON"), std::string::npos) << bad.message;

  // A missing reference is an error naming it.
  EXPECT_THROW(EvaluateRunGeometry(single, f.dir / "nothing.ply", Options()), Error);
}

}  // namespace
}  // namespace rephoto::geometry
