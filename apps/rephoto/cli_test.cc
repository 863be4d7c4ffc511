// The rephoto program as a user runs it (issue 14): usage mistakes exit 2 with one line, a run
// folder has one writer and `kill -9` releases it at once, a hung pipeline times out.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>

#include "rephoto/core/file.h"
#include "rephoto/core/isa.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/synth/demo_files.h"
#include "rephoto/testing/testing.h"

namespace rephoto {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using Outcome = testing::ShellOutcome;

// Runs `rephoto ARGS` through the shell, stdout and stderr captured.
Outcome RunCli(const std::string& args) {
  return testing::RunShell(std::string(REPHOTO_CLI) + " -q " + args);
}

size_t Lines(const std::string& text) {
  size_t lines = 0;
  for (char c : text) lines += c == '\n';
  return lines;
}

const fs::path kSceaux = "openmvs_sceaux";

std::string SceauxArgs() {
  const fs::path data = testing::SharedDataDir() / kSceaux;
  return fmt::format("--scene '{}' --image-root '{}'", (data / "colmap_text_derived").string(),
                     (data / "images").string());
}

std::string Mesh() { return (testing::SharedDataDir() / kSceaux / "scene_mesh.ply").string(); }

// The last line of a program's stderr (warnings about the data may come before it).
std::string LastLine(const std::string& text) {
  const size_t end = text.size() > 0 && text.back() == '\n' ? text.size() - 1 : text.size();
  const size_t begin = text.rfind('\n', end == 0 ? 0 : end - 1);
  return text.substr(begin == std::string::npos ? 0 : begin + 1);
}

TEST(Cli, UsageMistakesAnywhereExitTwoWithOneLine) {
  REPHOTO_REQUIRE_DATA(kSceaux);
  const fs::path dir = testing::MakeTempDir();
  for (const std::string& args :
       {"split " + SceauxArgs().substr(8) + " --scheme bogus:3 --out '" + (dir / "s").string() +
            "'",
        "evaluate " + SceauxArgs() + " --scheme kfold:x --model '" + Mesh() + "' --out '" +
            (dir / "e").string() + "'",
        "evaluate " + SceauxArgs() + " --command-timeout -1 --model '" + Mesh() + "' --out '" +
            (dir / "t").string() + "'",
        "evaluate " + SceauxArgs() + " --scheme bogus --model '" + Mesh() + "' --out '" +
            (dir / "e").string() + "'",
        // Found against the data: Sceaux has 11 photos.
        "split " + SceauxArgs().substr(8) + " --scheme kfold:12 --out '" + (dir / "s").string() +
            "'",
        "evaluate " + SceauxArgs() + " --reconstruct true --out '" + (dir / "e").string() + "'",
        "evaluate " + SceauxArgs() + " --executor bogus --model '" + Mesh() + "' --out '" +
            (dir / "e").string() + "'",
        std::string("evaluate --bogus-flag")}) {
    SCOPED_TRACE(args);
    const Outcome outcome = RunCli(args);
    EXPECT_EQ(outcome.exit_code, 2) << outcome.err;
    // One line saying what is wrong (evaluate adds where to find the options).
    const std::string message = outcome.err.find("Run 'rephoto") != std::string::npos
                                    ? outcome.err.substr(0, outcome.err.find("Run 'rephoto"))
                                    : outcome.err;
    EXPECT_EQ(Lines(message), 1u) << outcome.err;
  }
  EXPECT_FALSE(fs::exists(dir / "e"));
  // A scheme that does not fit the photos found (Sceaux: 10 of its 11 photos exist) is a usage
  // error in evaluate too; its message is the last line (after the warning naming the missing
  // photo).
  const Outcome kfold = RunCli("evaluate " + SceauxArgs() + " --scheme kfold:12 --model '" +
                               Mesh() + "' --out '" + (dir / "k").string() + "'");
  EXPECT_EQ(kfold.exit_code, 2) << kfold.err;
  EXPECT_THAT(kfold.err, HasSubstr("rephoto: error: split kfold:12:0: needs 2 <= K <= number of "
                                   "images (10)\n"));
}

// rephoto render decides nothing itself (representation/make_renderer.h): a representation
// without the model it needs fails with the library's one line (exit 1), a bad --background is
// a usage error (exit 2) whatever is rendered, and nothing is written.
TEST(Cli, RenderWithoutItsModelSaysWhichModelIsMissing) {
  REPHOTO_REQUIRE_DATA(kSceaux);
  const fs::path dir = testing::MakeTempDir();
  const std::string out = " --out '" + (dir / "r").string() + "'";
  const Outcome vdt = RunCli("render " + SceauxArgs() + " --representation vdt" + out);
  EXPECT_EQ(vdt.exit_code, 1) << vdt.err;
  EXPECT_EQ(LastLine(vdt.err),
            "rephoto: error: --representation vdt needs a model (the geometry proxy)\n");
  const Outcome mesh = RunCli("render " + SceauxArgs() + out);
  EXPECT_EQ(mesh.exit_code, 1) << mesh.err;
  EXPECT_EQ(LastLine(mesh.err),
            "rephoto: error: --representation auto needs a model (a mesh or point cloud)\n");
  const Outcome background =
      RunCli("render '" + Mesh() + "' " + SceauxArgs() + " --background pink" + out);
  EXPECT_EQ(background.exit_code, 2) << background.err;
  EXPECT_THAT(background.err, HasSubstr("--background pink"));
  EXPECT_FALSE(fs::exists(dir / "r"));
}

// REPHOTO_ISA (core/isa.h): --version names the path; an unknown path, or one the CPU lacks, is
// a usage error naming the variable.
TEST(Cli, IsaPathIsShownAndCanBeForced) {
  // (Without a REPHOTO_ISA of the caller's environment, which would decide the path.)
  const Outcome version =
      testing::RunShell("env -u REPHOTO_ISA " + std::string(REPHOTO_CLI) + " --version");
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_THAT(version.out, HasSubstr("isa: " + std::string(core::IsaName(core::DetectedIsa()))));
  const Outcome forced =
      testing::RunShell("REPHOTO_ISA=baseline " + std::string(REPHOTO_CLI) + " --version");
  EXPECT_THAT(forced.out, HasSubstr("isa: baseline"));
  std::vector<std::string> bad = {"avx1024"};
  if (!core::CpuSupports(core::Isa::kAvx512)) bad.push_back("avx512");
  for (const std::string& isa : bad) {
    const Outcome run = testing::RunShell("REPHOTO_ISA=" + isa + " " + std::string(REPHOTO_CLI) +
                                          " split /nonexistent --scheme kfold:2 --out " +
                                          testing::MakeTempDir().string() + "/s");
    EXPECT_EQ(run.exit_code, 2) << run.err;
    EXPECT_EQ(Lines(run.err), 1u) << run.err;
    EXPECT_THAT(run.err, HasSubstr("REPHOTO_ISA=" + isa));
  }
}

// A mistake in a sweep's TOML file is a usage error too, found before anything is written, and
// the message names the file.
TEST(Cli, SweepConfigMistakesExitTwoWithOneLineNamingTheFile) {
  REPHOTO_REQUIRE_DATA(kSceaux);
  const fs::path dir = testing::MakeTempDir();
  const fs::path data = testing::SharedDataDir() / kSceaux;
  const std::string valid = fmt::format(
      "scene = \"{}\"\nimage_root = \"{}\"\nmodel = \"{}\"\nscheme = \"kfold:2\"\n"
      "metrics = [\"1-ncc\", \"cb+cr\"]\n[sweep]\ntexture_noise = [0, 0.1]\nout = \"out\"\n",
      (data / "colmap_text_derived").string(), (data / "images").string(), Mesh());
  struct Case {
    std::string name, from, to, message;
  };
  for (const Case& c : {Case{"metric.toml", "\"cb+cr\"", "\"bogus\"", "unknown metric 'bogus'"},
                        Case{"scheme.toml", "kfold:2", "kfold:x", "K must be an integer"},
                        Case{"key.toml", "texture_noise =", "texture_noize =",
                             "[sweep] texture_noize: unknown key"}}) {
    SCOPED_TRACE(c.name);
    const fs::path config = testing::WriteFile(dir / c.name, testing::Replace(valid, c.from, c.to));
    const Outcome outcome = RunCli("sweep '" + config.string() + "'");
    EXPECT_EQ(outcome.exit_code, 2) << outcome.err;
    EXPECT_EQ(Lines(outcome.err), 1u) << outcome.err;
    EXPECT_THAT(outcome.err, HasSubstr("rephoto: error: " + config.string() + ": "));
    EXPECT_THAT(outcome.err, HasSubstr(c.message));
    EXPECT_FALSE(fs::exists(dir / "out"));
  }
}

// Ctrl-C: the documented exit code 130 and how to resume, as the last line.
TEST(Cli, InterruptExitsWith130AndSaysHowToResume) {
  REPHOTO_REQUIRE_DATA(kSceaux);
  const fs::path dir = testing::MakeTempDir();
  const fs::path run = dir / "run";
  const std::string command = std::string(REPHOTO_CLI) + " -q evaluate " + SceauxArgs() +
                              " --scheme kfold:2 --model mesh.ply --reconstruct 'sleep 30' "
                              "--out '" +
                              run.string() + "' 2>'" + (dir / "stderr").string() + "'";
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::execl("/bin/sh", "sh", "-c", ("exec " + command).c_str(), nullptr);
    ::_exit(127);
  }
  // Wait until fold_00's command runs (its log exists), then interrupt.
  for (int i = 0; i < 600 && !fs::exists(run / "logs"); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_TRUE(fs::exists(run / "logs"));
  const auto start = std::chrono::steady_clock::now();
  ::kill(child, SIGINT);
  int status = 0;
  ::waitpid(child, &status, 0);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 20);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_EQ(LastLine(ReadFileToString(dir / "stderr")),
            fmt::format("rephoto: {}: interrupted; finished folds and views are kept: rerun the "
                        "same command to resume\n",
                        run.string()));
}

TEST(Cli, OneWriterPerRunFolderAndKillNineReleasesIt) {
  REPHOTO_REQUIRE_DATA(kSceaux);
  const fs::path run = testing::MakeTempDir() / "run";
  const std::string args = "evaluate " + SceauxArgs() +
                           " --scheme kfold:2 --model mesh.ply --reconstruct 'sleep 30' --out '" +
                           run.string() + "'";
  // The first writer: started in the background, it holds the folder while its command runs.
  const pid_t first = ::fork();
  ASSERT_GE(first, 0);
  if (first == 0) {
    const std::string command = std::string(REPHOTO_CLI) + " -q " + args;
    ::execl("/bin/sh", "sh", "-c", ("exec " + command + " >/dev/null 2>&1").c_str(), nullptr);
    ::_exit(127);
  }
  // Wait until it owns the folder (its log of fold_00's command exists).
  for (int i = 0; i < 600 && !fs::exists(run / "logs"); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_TRUE(fs::exists(run / "logs"));
  const Outcome second = RunCli(args);
  EXPECT_EQ(second.exit_code, 1);
  EXPECT_EQ(LastLine(second.err),
            fmt::format("rephoto: error: {}: another rephoto evaluate (pid {}) is "
                        "writing this run folder; wait for it or use another --out\n",
                        run.string(), first));
  ::kill(first, SIGKILL);
  int status = 0;
  ::waitpid(first, &status, 0);
  // Released at once: the next run takes the folder; its hung commands time out.
  const auto start = std::chrono::steady_clock::now();
  const Outcome third = RunCli(args + " --command-timeout 0.2");
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 30);
  EXPECT_EQ(third.exit_code, 3) << third.err;  // finished, both folds failed (timed out)
  EXPECT_THAT(ReadFileToString(run / "per_fold.csv"), HasSubstr("timed out after 0.2 s"));
}

// issue 14, item 8: what a new user read wrong.
TEST(Cli, HelpAndMessagesSayWhatTheyMean) {
  const Outcome help = RunCli("evaluate --help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_THAT(help.out, HasSubstr("--colorize,--no-colorize "));
  EXPECT_EQ(help.out.find("{false}"), std::string::npos);
  EXPECT_THAT(help.out, HasSubstr("interleaved:K"));
  EXPECT_THAT(help.out, HasSubstr("20x vdt's time"));
  EXPECT_THAT(help.out, HasSubstr("--command-timeout"));
  EXPECT_THAT(RunCli("degrade --help").out, HasSubstr("Fraction of the faces removed"));
  const Outcome metric = RunCli("evaluate --scene s --model m --out o --metrics 1-nc");
  EXPECT_EQ(metric.exit_code, 2);
  EXPECT_THAT(metric.err, HasSubstr("rephoto: --metrics: unknown metric '1-nc'"));
  EXPECT_EQ(metric.err.find("--metrics: --metrics"), std::string::npos);
  REPHOTO_REQUIRE_DATA(kSceaux);
  const Outcome info =
      RunCli("scene info '" +
             (testing::SharedDataDir() / kSceaux / "colmap_text_derived").string() + "' --json");
  EXPECT_EQ(info.exit_code, 0);
  ASSERT_FALSE(info.out.empty());
  EXPECT_EQ(info.out.back(), '\n');
}

// issue 16: a Gaussian splatting model through evaluate (report) and project, as a user runs them.
TEST(Cli, GaussianModelsGoThroughEvaluateReportAndProject) {
  REPHOTO_REQUIRE_DATA(kSceaux);
  const fs::path dir = testing::MakeTempDir();
  const mesh::Mesh mesh = mesh::ReadPly(testing::SharedDataDir() / kSceaux / "scene_mesh.ply");
  splat::GaussianModel gaussians;
  for (size_t v = 0; v < mesh.vertex_count(); v += 7) {
    gaussians.positions.push_back(mesh.positions[v]);
    gaussians.scales.push_back(Eigen::Vector3f::Constant(0.05f));
    gaussians.rotations.push_back(Eigen::Vector4f(1, 0, 0, 0));
    gaussians.opacities.push_back(0.8f);
    for (int c = 0; c < 3; ++c) gaussians.sh.push_back(0.2f * static_cast<float>(c));
  }
  splat::WriteInriaPly(dir / "point_cloud.ply", gaussians);
  const std::string model = (dir / "point_cloud.ply").string();
  const Outcome evaluate = RunCli("evaluate " + SceauxArgs() + " --model '" + model +
                                  "' --eval-short-side 120 --metrics 1-ncc,cb+cr --out '" +
                                  (dir / "run").string() + "'");
  EXPECT_EQ(evaluate.exit_code, 3) << evaluate.err;  // Sceaux lacks one photo: incomplete
  EXPECT_THAT(ReadFileToString(dir / "run/report.html"), HasSubstr("1-ncc"));
  EXPECT_THAT(ReadFileToString(dir / "run/projected/1-ncc.ply"),
              HasSubstr("property float error\nend_header"));
  const Outcome project =
      RunCli("project '" + model + "' " + SceauxArgs() + " --errors '" + (dir / "run").string() +
             "' --scale-cameras --out '" + (dir / "projected.ply").string() + "'");
  EXPECT_EQ(project.exit_code, 0) << project.err;
  EXPECT_EQ(ReadFileToString(dir / "projected.ply"),
            ReadFileToString(dir / "run/projected/1-ncc.ply"));
}

// issue 21: the small demo scene (8 photos around the object) and its ground-truth mesh.
fs::path DemoScene() {
  static const fs::path root = [] {
    const fs::path r = testing::MakeTempDir() / "demo_scene";
    synth::DemoSceneOptions options;
    options.image_width = 160;
    options.image_height = 120;
    options.camera_count = 8;
    options.ground_cells = 40;
    options.object_bands = 24;
    synth::WriteDemoSceneFiles(options, r, [](size_t i) {
      return synth::PhotoSettings{1, 0.01, i};
    });
    return r;
  }();
  return root;
}

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// issue 30: `evaluate --compat 3dgs` is accepted (it was "arguments were not expected") and
// prints the numbers as graphdeco's metrics.py does, after rephoto's own table; a bad preset is
// one line.
TEST(Cli, EvaluateCompatPrintsThePublishedNumbers) {
  const fs::path dir = testing::MakeTempDir();
  const std::string scene = "--scene '" + (DemoScene() / "sparse").string() + "' --model '" +
                            (DemoScene() / "truth.ply").string() + "'";
  const Outcome ok =
      RunCli("evaluate " + scene + " --compat 3dgs --metrics 1-ncc --no-report --out '" +
             (dir / "run").string() + "'");
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_THAT(ok.out, HasSubstr("1-ncc"));
  EXPECT_THAT(ok.out, HasSubstr("\nMethod: rephoto\n  SSIM : "));
  EXPECT_THAT(ok.out, HasSubstr("\n  PSNR : "));
  EXPECT_EQ(Count(ok.out, "Scene: "), 1u);
  EXPECT_TRUE(fs::is_regular_file(dir / "run/results.json"));
  EXPECT_THAT(ReadFileToString(dir / "run/per_image.csv"), HasSubstr(",3dgs_psnr,3dgs_ssim\n"));
  const Outcome bad =
      RunCli("evaluate " + scene + " --compat mip --out '" + (dir / "bad").string() + "'");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.err, HasSubstr("--compat: 'mip' is not 3dgs, nerfstudio or none"));
}

// issue 21: rephoto geometry's outputs, and one-line errors for a missing reference or a bad
// tolerance list.
TEST(Cli, GeometryWritesItsOutputsAndRefusesBadInputInOneLine) {
  const fs::path dir = testing::MakeTempDir();
  const std::string truth = (DemoScene() / "truth.ply").string();
  const Outcome ok =
      RunCli("geometry '" + truth + "' --reference '" + truth +
             "' --tolerances 0.01,0.02 --samples 5000 --out '" + (dir / "geo").string() + "'");
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  for (const char* file :
       {"geometry.json", "geometry.csv", "model_distance.ply", "reference_distance.ply"}) {
    EXPECT_TRUE(fs::is_regular_file(dir / "geo" / file)) << file;
  }
  // The model is the reference: complete at every tolerance.
  const std::string csv = ReadFileToString(dir / "geo/geometry.csv");
  EXPECT_THAT(csv, HasSubstr("tolerance,completeness,precision,recall,f_score,accuracy"));
  EXPECT_THAT(csv, HasSubstr("\n0.01,1,1,1,1,"));
  EXPECT_THAT(csv, HasSubstr("\n0.02,1,1,1,1,"));

  const Outcome missing =
      RunCli("geometry '" + truth + "' --reference '" + (dir / "nothing.ply").string() +
             "' --out '" + (dir / "m").string() + "'");
  EXPECT_EQ(missing.exit_code, 1) << missing.err;
  EXPECT_EQ(Lines(missing.err), 1u) << missing.err;
  EXPECT_THAT(missing.err, HasSubstr("nothing.ply"));
  for (const std::string& tolerances : {"0.01,x", "0.01,-1", "0"}) {
    SCOPED_TRACE(tolerances);
    const Outcome bad =
        RunCli("geometry '" + truth + "' --reference '" + truth + "' --tolerances " + tolerances +
               " --out '" + (dir / "b").string() + "'");
    EXPECT_EQ(bad.exit_code, 2) << bad.err;
    const std::string message = bad.err.find("Run 'rephoto") != std::string::npos
                                    ? bad.err.substr(0, bad.err.find("Run 'rephoto"))
                                    : bad.err;
    EXPECT_EQ(Lines(message), 1u) << bad.err;
    EXPECT_THAT(bad.err, HasSubstr("tolerance"));
  }
  EXPECT_FALSE(fs::exists(dir / "b"));
}

// issue 21: rephoto suggest writes the suggested cameras, their rephotos and report.html.
TEST(Cli, SuggestWritesCamerasRephotosAndAReport) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path out = dir / "next";
  const Outcome ok = RunCli("suggest --scene '" + (DemoScene() / "sparse").string() +
                            "' --model '" + (DemoScene() / "truth.ply").string() +
                            "' --count 2 --candidates 100 --out '" + out.string() + "'");
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_THAT(ok.out, HasSubstr("suggest_01"));
  for (const char* file :
       {"suggestions.json", "transforms.json", "sparse/cameras.txt", "sparse/images.txt",
        "renders/suggest_00.png", "renders/suggest_01.png", "report.html"}) {
    EXPECT_TRUE(fs::is_regular_file(out / file)) << file;
  }
  const std::string html = ReadFileToString(out / "report.html");
  EXPECT_EQ(Count(html, "<tr class=\"suggestion\""), 2u);
  EXPECT_EQ(Count(html, "<img src=\"data:image/"), 2u);  // each suggestion's rephoto
  EXPECT_THAT(html, HasSubstr("data-name=\"suggest_00.png\""));

  const Outcome bad = RunCli("suggest --scene '" + (DemoScene() / "sparse").string() +
                             "' --model '" + (DemoScene() / "truth.ply").string() +
                             "' --count 0 --out '" + (dir / "b").string() + "'");
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
  EXPECT_EQ(Lines(bad.err), 1u) << bad.err;
}

// The files of `folder` whose names end in `suffix`.
size_t FilesEndingIn(const fs::path& folder, const std::string& suffix) {
  size_t n = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    n += entry.path().filename().string().ends_with(suffix);
  }
  return n;
}

// issue 30: the test views of a split rendered without depth maps (what a benchmark's tar
// takes) and compared on their own against the scene's photo folder.
TEST(Cli, TestViewsOfASplitRenderedWithoutDepthAndComparedAlone) {
  const fs::path dir = testing::MakeTempDir();
  const std::string sparse = (DemoScene() / "sparse").string();
  const std::string photos = (DemoScene() / "images").string();
  const fs::path split = dir / "split";
  ASSERT_EQ(
      RunCli("split '" + sparse + "' --scheme every:4 --out '" + split.string() + "'").exit_code,
      0);
  const fs::path test_list = split / "fold_00/test.txt";
  ASSERT_EQ(ReadFileToString(test_list), "view_000.png\nview_004.png\n");

  // render --no-depth: only the PNGs, and an earlier run's depth maps are gone.
  const fs::path renders = dir / "renders";
  const std::string render = "render '" + (DemoScene() / "truth.ply").string() + "' --scene '" +
                             sparse + "' --images '" + test_list.string() + "' --spp 1 --out '" +
                             renders.string() + "'";
  ASSERT_EQ(RunCli(render).exit_code, 0);
  EXPECT_EQ(FilesEndingIn(renders, ".depth.exr"), 2u);
  const Outcome no_depth = RunCli(render + " --no-depth");
  ASSERT_EQ(no_depth.exit_code, 0) << no_depth.err;
  EXPECT_EQ(FilesEndingIn(renders, ".png"), 2u);
  EXPECT_EQ(FilesEndingIn(renders, ".depth.exr"), 0u);
  EXPECT_EQ(std::distance(fs::directory_iterator(renders), fs::directory_iterator()), 2);

  const std::string compare = "compare --photos '" + photos + "' --renders '" + renders.string() +
                              "' --metrics cb+cr --no-error-images ";
  // Without a selection the 6 training photos have no rendering: incomplete.
  const Outcome all = RunCli(compare + "--out '" + (dir / "all").string() + "'");
  EXPECT_EQ(all.exit_code, 3) << all.err;
  EXPECT_EQ(Lines(ReadFileToString(dir / "all/per_image.csv")), 9u);
  // --split DIR (its only fold) and --images FILE: exactly the two test views, complete.
  for (const std::string& selection :
       {"--split '" + split.string() + "'", "--split '" + (split / "fold_00").string() + "'",
        "--images '" + test_list.string() + "'"}) {
    SCOPED_TRACE(selection);
    const fs::path out = dir / "selected";
    const Outcome outcome = RunCli(compare + selection + " --out '" + out.string() + "'");
    EXPECT_EQ(outcome.exit_code, 0) << outcome.err;
    const std::string csv = ReadFileToString(out / "per_image.csv");
    EXPECT_EQ(Lines(csv), 3u) << csv;
    EXPECT_THAT(csv, HasSubstr("\nview_000,ok,"));
    EXPECT_THAT(csv, HasSubstr("\nview_004,ok,"));
  }
  // --min-alpha is recorded; out of range or with --compat it is a usage mistake.
  const Outcome strict = RunCli(compare + "--split '" + split.string() +
                                "' --min-alpha 0.5 --out '" + (dir / "strict").string() + "'");
  EXPECT_EQ(strict.exit_code, 0) << strict.err;
  EXPECT_THAT(ReadFileToString(dir / "strict/summary.json"), HasSubstr("\"min_alpha\": 0.5"));

  // Mistakes: one line naming the file and line, the folder, or the options.
  WriteTextFileAtomically(dir / "bad.txt", "view_000.png\n../images/view_001.png\n");
  const Outcome hostile = RunCli(compare + "--images '" + (dir / "bad.txt").string() + "' --out '" +
                                 (dir / "bad").string() + "'");
  EXPECT_EQ(hostile.exit_code, 1) << hostile.err;
  EXPECT_EQ(Lines(hostile.err), 1u) << hostile.err;
  EXPECT_THAT(hostile.err,
              HasSubstr("bad.txt:2: image name '../images/view_001.png' contains '..'"));
  const fs::path folds = dir / "folds";
  ASSERT_EQ(
      RunCli("split '" + sparse + "' --scheme kfold:2 --out '" + folds.string() + "'").exit_code,
      0);
  const Outcome several =
      RunCli(compare + "--split '" + folds.string() + "' --out '" + (dir / "bad").string() + "'");
  EXPECT_EQ(several.exit_code, 1) << several.err;
  EXPECT_EQ(Lines(several.err), 1u) << several.err;
  EXPECT_THAT(several.err, HasSubstr("the split has 2 folds (fold_00 ... fold_01); name the fold's "
                                     "folder, e.g. " +
                                     (folds / "fold_00").string()));
  for (const std::string& mistake :
       {"--split '" + split.string() + "' --images '" + test_list.string() + "'",
        std::string("--min-alpha 1.5"), std::string("--min-alpha 0.5 --compat 3dgs")}) {
    SCOPED_TRACE(mistake);
    const Outcome outcome = RunCli(compare + mistake + " --out '" + (dir / "bad").string() + "'");
    EXPECT_EQ(outcome.exit_code, 2) << outcome.err;
  }
  EXPECT_FALSE(fs::exists(dir / "bad"));
  EXPECT_THAT(RunCli("compare --help").out, HasSubstr("--min-alpha"));
}

// issue 21: report --reference refuses a missing reference and a single run in one line.
TEST(Cli, ReportReferenceMistakesExitTwoWithOneLine) {
  const fs::path dir = testing::MakeTempDir();
  fs::create_directories(dir / "a");
  fs::create_directories(dir / "b");
  const std::string runs = "'" + (dir / "a").string() + "' '" + (dir / "b").string() + "'";
  const Outcome missing = RunCli("report " + runs + " --reference '" + (dir / "gt.ply").string() +
                                 "' --out '" + (dir / "r.html").string() + "'");
  EXPECT_EQ(missing.exit_code, 2) << missing.err;
  EXPECT_EQ(Lines(missing.err), 1u) << missing.err;
  EXPECT_THAT(missing.err, HasSubstr("gt.ply: no such file"));
  const Outcome single =
      RunCli("report '" + (dir / "a").string() + "' --reference '" +
             (DemoScene() / "truth.ply").string() + "' --out '" + (dir / "r.html").string() + "'");
  EXPECT_EQ(single.exit_code, 2) << single.err;
  EXPECT_THAT(single.err, HasSubstr("two or more runs"));
  EXPECT_FALSE(fs::exists(dir / "r.html"));
}

}  // namespace
}  // namespace rephoto
