#include "rephoto/eval/settings.h"

#include <gtest/gtest.h>

#include "rephoto/core/file.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/testing/testing.h"

namespace rephoto::eval {
namespace {

namespace fs = std::filesystem;

// The same experiment as flags (strings and bools, as the CLI passes them).
EvaluateOptions FromFlags() {
  EvaluateOptions o;
  ApplySetting(&o, "scene", std::string("/data/scene"), "--scene");
  ApplySetting(&o, "out", std::string("/runs/a"), "--out");
  ApplySetting(&o, "scheme", std::string("loo"), "--scheme");
  ApplySetting(&o, "reconstruct", std::string("recon {train} {out}"), "--reconstruct");
  ApplySetting(&o, "model", std::string("mesh/model.ply"), "--model");
  ApplySetting(&o, "colorize", true, "--colorize");
  ApplySetting(&o, "train-count", std::string("12"), "--train-count");
  ApplySetting(&o, "eval-short-side", std::string("480"), "--eval-short-side");
  ApplySetting(&o, "metrics", std::string("1-ncc,census"), "--metrics");
  ApplySetting(&o, "window", std::string("7"), "--window");
  ApplySetting(&o, "ssim-mode", std::string("skimage"), "--ssim-mode");
  ApplySetting(&o, "dark", std::string("0.02"), "--dark");
  ApplySetting(&o, "error-images", false, "--no-error-images");
  ApplySetting(&o, "spp", std::string("2"), "--spp");
  ApplySetting(&o, "backfaces", false, "--no-backfaces");
  ApplySetting(&o, "jobs", std::string("2"), "--jobs");
  return o;
}

void ExpectSameSettings(const EvaluateOptions& a, const EvaluateOptions& b) {
  EXPECT_EQ(SettingsJson(a).dump(), SettingsJson(b).dump());
}

TEST(SettingsTest, TomlAndJsonGiveTheSameSettingsAsFlags) {
  const fs::path dir = testing::MakeTempDir();
  // Absolute paths so that the config file's folder does not matter.
  WriteTextFileAtomically(dir / "exp.toml", R"(# an experiment
scene = "/data/scene"
out = "/runs/a"
scheme = "loo"
reconstruct = "recon {train} {out}"
model = "mesh/model.ply"
colorize = true
train_count = 12
eval-short-side = 480
metrics = ["1-ncc", "census"]
window = 7
ssim_mode = "skimage"
dark = 0.02
error_images = false
spp = 2
backfaces = false
jobs = 2
)");
  WriteTextFileAtomically(dir / "exp.json", R"({
  "scene": "/data/scene", "out": "/runs/a", "scheme": "loo",
  "reconstruct": "recon {train} {out}", "model": "mesh/model.ply", "colorize": true,
  "train-count": 12, "eval_short_side": 480, "metrics": "1-ncc,census", "window": 7,
  "ssim-mode": "skimage", "dark": 0.02, "error-images": false, "spp": 2,
  "backfaces": false, "jobs": 2
})");
  const EvaluateOptions flags = FromFlags();
  EvaluateOptions toml, json;
  LoadConfigFile(dir / "exp.toml", &toml);
  LoadConfigFile(dir / "exp.json", &json);
  ExpectSameSettings(flags, toml);
  ExpectSameSettings(flags, json);
  // fuzz_config: a number beyond double escaped as nlohmann's out_of_range ("internal error").
  EvaluateOptions huge;
  try {
    LoadConfigText(R"({"jobs": 6e999442})", "/x/exp.json", &huge);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("/x/exp.json: invalid JSON: ", 0), 0u) << e.what();
  }
  // The text entry point (fuzzers, tests) reads the same.
  EvaluateOptions text;
  LoadConfigText(ReadFileToString(dir / "exp.json"), dir / "exp.json", &text);
  ExpectSameSettings(flags, text);
  EXPECT_EQ(toml.train_count, 12);
  EXPECT_EQ(toml.metric_options.window, 7);
  EXPECT_FALSE(toml.metric_options.ssim_gaussian);
  EXPECT_EQ(toml.metric_options.ssim_window, 7);
  EXPECT_FLOAT_EQ(toml.exposure.dark_threshold, 0.02f);
  EXPECT_EQ(toml.metrics.size(), 2u);
  EXPECT_EQ(toml.model, fs::path("mesh/model.ply"));  // inside {out}: kept as written
  EXPECT_EQ(toml.config_file, dir / "exp.toml");
}

TEST(SettingsTest, FlagsOverrideTheFileAndPathsAreRelativeToIt) {
  const fs::path dir = testing::MakeTempDir();
  WriteTextFileAtomically(dir / "exp.toml",
                          "scene = \"data/scene\"\nmodel = \"m.ply\"\nspp = 8\nout = \"run\"\n");
  EvaluateOptions o;
  LoadConfigFile(dir / "exp.toml", &o);
  EXPECT_EQ(o.scene, fs::absolute(dir) / "data/scene");
  EXPECT_EQ(o.model, fs::absolute(dir) / "m.ply");  // a model file: relative to the config
  EXPECT_EQ(o.out, fs::absolute(dir) / "run");
  EXPECT_EQ(o.samples_per_pixel, 8);
  ApplySetting(&o, "spp", std::string("3"), "--spp");
  EXPECT_EQ(o.samples_per_pixel, 3);
}

TEST(SettingsTest, UnknownKeyNamesTheKeyAndTheFile) {
  const fs::path dir = testing::MakeTempDir();
  WriteTextFileAtomically(dir / "bad.toml", "scene = \"s\"\nsamples = 4\n");
  EvaluateOptions o;
  try {
    LoadConfigFile(dir / "bad.toml", &o);
    FAIL() << "no error";
  } catch (const UsageError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind((dir / "bad.toml").string() + ": unknown key 'samples'", 0), 0u)
        << message;
  }
  WriteTextFileAtomically(dir / "bad.json", R"({"scene": "s", "colourize": true})");
  EXPECT_THROW(
      {
        try {
          LoadConfigFile(dir / "bad.json", &o);
        } catch (const UsageError& e) {
          EXPECT_NE(std::string(e.what()).find("unknown key 'colourize'"), std::string::npos);
          throw;
        }
      },
      UsageError);
}

TEST(SettingsTest, BadValuesAreClearErrors) {
  const fs::path dir = testing::MakeTempDir();
  WriteTextFileAtomically(dir / "a.toml", "spp = \"many\"\n");
  EvaluateOptions o;
  EXPECT_THROW(LoadConfigFile(dir / "a.toml", &o), UsageError);
  WriteTextFileAtomically(dir / "b.toml", "spp = \n");
  try {
    LoadConfigFile(dir / "b.toml", &o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind((dir / "b.toml").string() + ":1:", 0), 0u) << e.what();
  }
  WriteTextFileAtomically(dir / "c.yaml", "spp: 3\n");
  EXPECT_THROW(LoadConfigFile(dir / "c.yaml", &o), Error);
  EXPECT_THROW(ApplySetting(&o, "window", std::string("8"), "--window"), UsageError);
  EXPECT_THROW(ApplySetting(&o, "metrics", std::string("1-ncc,nope"), "--metrics"), UsageError);
  EXPECT_THROW(ApplySetting(&o, "jobs", std::string("0"), "--jobs"), UsageError);
}

TEST(SettingsTest, EveryTableEntryIsAppliedAndRecorded) {
  const nlohmann::ordered_json recorded = SettingsJson(EvaluateOptions{});
  for (const SettingInfo& info : Settings()) {
    EXPECT_TRUE(recorded.contains(info.name)) << info.name;
  }
  EXPECT_EQ(recorded.size(), Settings().size());
}

}  // namespace
}  // namespace rephoto::eval
