// Models rephoto derives per fold from the fold's training photos (--colorize, --texture): each
// fold's copy uses only that fold's training photos, is rendered as stored, and is reused.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "rephoto/core/file.h"
#include "rephoto/eval/evaluate.h"
#include "rephoto/eval/evaluate_fixture.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/synth/demo_files.h"
#include "rephoto/testing/testing.h"

namespace rephoto::eval {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const synth::DemoSceneFiles& Files() { return EvaluateTestScene(); }

EvaluateOptions BaseOptions(const fs::path& out) { return EvaluateTestOptions(out); }

nlohmann::json ReadJson(const fs::path& path) {
  return nlohmann::json::parse(ReadFileToString(path));
}

TEST(DerivedModelTest, ColorizeUsesEachFoldsTrainingPhotos) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().plain;
  o.colorize = true;
  o.scheme = "kfold:3";
  o.error_images = false;
  const EvaluateResult coloured = RunEvaluate(o);
  EXPECT_EQ(coloured.exit_code, ExitCode::kOk);
  EXPECT_EQ(coloured.counters.models_colorized, 3u);
  const mesh::Mesh model = mesh::ReadPly(run / "folds/fold_01/model.ply");
  EXPECT_EQ(model.colors.size(), model.positions.size());
  const nlohmann::json fold = ReadJson(run / "folds/fold_01/fold.json");
  EXPECT_EQ(fold["train"]["count"], 4);
  // Without colours every face is flat grey: 1-NCC near 1 wherever the photo has texture.
  EvaluateOptions g = BaseOptions(testing::MakeTempDir() / "grey");
  g.model = Files().plain;
  g.scheme = "kfold:3";
  g.error_images = false;
  const EvaluateResult grey = RunEvaluate(g);
  EXPECT_GT(grey.metrics[0].over_images.median, 0.8);
  EXPECT_LT(coloured.metrics[0].over_images.median, 0.6 * grey.metrics[0].over_images.median);
  // Resume reuses the coloured models; the recorded costs stay.
  const std::string per_fold = ReadFileToString(run / "per_fold.csv");
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(ReadFileToString(run / "per_fold.csv"), per_fold);
  EXPECT_EQ(again.counters.models_colorized, 0u);
  EXPECT_EQ(again.counters.views_rendered, 0u);
}

// A fixed model with defects is degraded once and shared by the folds (the same seed): every
// fold still has the model.ply its fold.json names, with the same bytes, and a rerun keeps it.
TEST(DerivedModelTest, DegradedFixedModelIsEveryFoldsModelPly) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().truth;
  o.scheme = "kfold:3";
  o.error_images = false;
  o.report = false;
  o.degrade.geometry_noise = 0.01f;
  ASSERT_EQ(RunEvaluate(o).exit_code, ExitCode::kOk);
  const std::string first = ReadFileToString(run / "folds/fold_00/model.ply");
  EXPECT_GT(first.size(), 1000u);
  EXPECT_NE(first, ReadFileToString(Files().truth));  // degraded
  for (const char* fold : {"fold_00", "fold_01", "fold_02"}) {
    const fs::path dir = run / "folds" / fold;
    const nlohmann::json j = ReadJson(dir / "fold.json");
    ASSERT_TRUE(j["colorized_model"].is_string()) << fold;
    EXPECT_EQ(ReadFileToString(dir / j["colorized_model"].get<std::string>()), first) << fold;
    EXPECT_EQ(ReadFileToString(dir / "model.key"), j["colorize_key"].get<std::string>()) << fold;
  }
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(again.counters.views_rendered, 0u);
  EXPECT_EQ(ReadFileToString(run / "folds/fold_02/model.ply"), first);
}

// Issue 22: --texture textures each fold's mesh from that fold's training photos only; the
// rendered model is the textured OBJ as stored, and a rerun reuses it.
TEST(DerivedModelTest, TextureUsesEachFoldsTrainingPhotos) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().plain;
  o.texture = true;
  o.scheme = "kfold:3";
  o.error_images = false;
  const EvaluateResult textured = RunEvaluate(o);
  EXPECT_EQ(textured.exit_code, ExitCode::kOk);
  EXPECT_EQ(textured.counters.models_colorized, 3u);
  const nlohmann::json fold = ReadJson(run / "folds/fold_01/fold.json");
  EXPECT_EQ(fold["colorized_model"], "textured/model.obj");
  EXPECT_EQ(fold["train"]["count"], 4);
  const nlohmann::json report = ReadJson(run / "folds/fold_01/textured/texture.json");
  EXPECT_EQ(report["views_given"], 4);
  EXPECT_GT(report["textured_faces"].get<size_t>(), 0u);
  const mesh::Mesh model = mesh::ReadMesh(run / "folds/fold_01/textured/model.obj");
  EXPECT_FALSE(model.materials.empty());
  // Flat grey without texture: 1-NCC near 1; the textured mesh is far below it.
  EvaluateOptions g = BaseOptions(testing::MakeTempDir() / "grey");
  g.model = Files().plain;
  g.scheme = "kfold:3";
  g.error_images = false;
  const EvaluateResult grey = RunEvaluate(g);
  EXPECT_LT(textured.metrics[0].over_images.median, 0.6 * grey.metrics[0].over_images.median);
  const std::string per_image = ReadFileToString(run / "per_image.csv");
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(ReadFileToString(run / "per_image.csv"), per_image);
  EXPECT_EQ(again.counters.models_colorized, 0u);
  EXPECT_EQ(again.counters.views_rendered, 0u);
  o.colorize = true;
  EXPECT_THAT(testing::ErrorOf([&] { RunEvaluate(o); }), HasSubstr("either --colorize"));
}

}  // namespace
}  // namespace rephoto::eval
