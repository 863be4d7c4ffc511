// End-to-end tests of `rephoto sweep` on a small synthetic scene (synth/demo_scene.h): eight
// 160x120 photos of the demo object and its ground-truth mesh.
#include "rephoto/sweep/sweep.h"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/io/csv.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/render/render.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/synth/demo_files.h"
#include "rephoto/testing/testing.h"

namespace rephoto::sweep {
namespace {

namespace fs = std::filesystem;

struct SceneFiles {
  fs::path root;
};

const SceneFiles& Files() {
  static const SceneFiles files = [] {
    SceneFiles f;
    f.root = testing::MakeTempDir() / "scene";
    synth::DemoSceneOptions options;
    options.image_width = 160;
    options.image_height = 120;
    options.camera_count = 8;
    options.ground_cells = 40;
    options.object_bands = 24;
    synth::WriteDemoSceneFiles(options, f.root, [](size_t i) {
      return synth::PhotoSettings{1, 0.01, i};
    });
    return f;
  }();
  return files;
}

TEST(Sweep, TextureNoiseOrdersTheErrorInEverySeriesAndResumes) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path config = testing::WriteFile(dir / "exp.toml", fmt::format(R"(
scene = "{0}/sparse"
image_root = "{0}/images"
model = "{0}/truth.ply"
scheme = "kfold:2"
metrics = ["1-ncc", "cb+cr"]

[sweep]
texture_noise = [0, 0.1, 0.3]
seed = [1, 2]
x = "texture_noise"
out = "noise"
)",
                                                                           Files().root.string()));
  const SweepOptions options = LoadSweepConfig(config);
  ASSERT_EQ(options.axes.size(), 2u);
  EXPECT_EQ(options.axes[0].parameter, "seed");  // x axis last
  EXPECT_EQ(options.axes[1].parameter, "texture_noise");
  EXPECT_EQ(options.out, dir / "noise");

  const SweepResult result = RunSweep(options);
  ASSERT_EQ(result.settings.size(), 6u);
  EXPECT_EQ(result.exit_code, ExitCode::kOk);
  for (const auto& s : result.settings) {
    ASSERT_TRUE(s.ok) << s.message;
    EXPECT_EQ(s.result.folds.size(), 2u);
  }
  // Settings run seed by seed, texture noise fastest: in each series the median 1-NCC across
  // folds strictly increases with the noise (the ordering criterion).
  ASSERT_EQ(result.table.columns[1], "1-ncc");
  for (size_t series = 0; series < 2; ++series) {
    double previous = -1;
    for (size_t x = 0; x < 3; ++x) {
      const auto& rows = result.table.settings[series * 3 + x];
      EXPECT_EQ(rows.setting.Value("seed"), series + 1.0);
      EXPECT_EQ(rows.across_folds[1].count, 2u);
      EXPECT_GT(rows.across_folds[1].median, previous) << rows.setting.name;
      previous = rows.across_folds[1].median;
    }
  }
  // The noise-free settings of both seeds are the same model: the same error.
  EXPECT_EQ(result.table.settings[0].across_folds[1].median,
            result.table.settings[3].across_folds[1].median);

  const auto table = io::ReadCsvFile(options.out / "sweep.csv");
  ASSERT_EQ(table.size(), 7u);
  EXPECT_EQ(table[0][0], "setting");
  EXPECT_EQ(table[0][1], "seed");
  EXPECT_EQ(table[0][2], "texture_noise");
  EXPECT_EQ(table[2][0], "seed-1_texture_noise-0.1");
  EXPECT_EQ(io::ReadCsvFile(options.out / "sweep_per_fold.csv").size(), 1u + 6u * 2u);
  EXPECT_TRUE(fs::exists(options.out / "report.html"));
  EXPECT_TRUE(fs::exists(options.out / "settings" / "seed-2_texture_noise-0.3" / "report.html"));
  std::ifstream json_file(options.out / "sweep.json");
  const auto json = nlohmann::json::parse(json_file);
  EXPECT_EQ(json["schema"], "rephoto.sweep/1");
  EXPECT_EQ(json["settings"].size(), 6u);
  EXPECT_EQ(json["seconds"]["external"], 0.0);  // no pipeline: rephoto is all the work
  EXPECT_GT(json["seconds"]["rephoto"].get<double>(), 0.0);

  // Rerunning the same sweep reuses every view of every setting.
  const SweepResult again = RunSweep(options);
  size_t reused = 0, rendered = 0;
  for (const auto& s : again.settings) {
    reused += s.result.counters.views_reused;
    rendered += s.result.counters.views_rendered;
  }
  EXPECT_EQ(rendered, 0u);
  EXPECT_EQ(reused, 6u * 8u);
  EXPECT_EQ(io::ReadCsvFile(options.out / "sweep.csv"), table);
}

TEST(Sweep, HalvingTrainingSetsFromTheSmallestFold) {
  const fs::path dir = testing::MakeTempDir();
  // JSON config; colouring from each fold's training photos, |T| halved from the fold's 4.
  const fs::path config = testing::WriteFile(dir / "exp.json", fmt::format(R"({{
  "scene": "{0}/sparse", "image-root": "{0}/images", "model": "{0}/plain.ply",
  "colorize": true, "scheme": "kfold:2", "metrics": "1-ncc", "projection-metric": "none",
  "sweep": {{"train_count": "halve", "min_train_count": 1}}
}})",
                                                                           Files().root.string()));
  SweepOptions options = LoadSweepConfig(config);
  options.report = false;
  EXPECT_EQ(options.out, dir / "exp.sweep");
  const SweepResult result = RunSweep(options);
  ASSERT_EQ(result.axes.size(), 1u);
  EXPECT_EQ(result.axes[0].values, (std::vector<double>{4, 2, 1}));
  ASSERT_EQ(result.settings.size(), 3u);
  for (const auto& s : result.settings) {
    ASSERT_TRUE(s.ok) << s.message;
    EXPECT_EQ(s.result.counters.models_colorized, 2u) << s.setting.name;
  }
  // Every fold of "train_count-1" was coloured from one photo.
  std::ifstream fold_json(options.out / "settings" / "train_count-1" / "folds" / "fold_00" /
                          "fold.json");
  EXPECT_EQ(nlohmann::json::parse(fold_json)["train"]["count"], 1);
  EXPECT_FALSE(fs::exists(options.out / "report.html"));
}

TEST(Sweep, BadConfigsAreErrorsNamingTheFileAndKey) {
  const fs::path dir = testing::MakeTempDir();
  auto message = [&](const std::string& text) {
    const fs::path config = testing::WriteFile(dir / "bad.toml", text);
    try {
      RunSweep(LoadSweepConfig(config));
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string base =
      fmt::format("scene = \"{0}/sparse\"\nmodel = \"{0}/truth.ply\"\n", Files().root.string());
  EXPECT_NE(message(base).find("no [sweep] table"), std::string::npos);
  EXPECT_NE(message(base + "[sweep]\nblur = [1]\n").find("bad.toml: [sweep] blur: unknown key"),
            std::string::npos);
  EXPECT_NE(message(base + "[sweep]\ntrain_count = \"third\"\n").find("\"halve\""),
            std::string::npos);
  EXPECT_NE(message(base + "[sweep]\nsimplify = [1.5]\n").find("below 1"), std::string::npos);
  EXPECT_NE(message(base + "[sweep]\nseed = [1]\nx = \"simplify\"\n")
                .find("x axis 'simplify' is not a swept parameter"),
            std::string::npos);
  EXPECT_NE(message(base + "bogus = 1\n[sweep]\nseed = [1]\n").find("unknown key 'bogus'"),
            std::string::npos);
}

}  // namespace
}  // namespace rephoto::sweep
