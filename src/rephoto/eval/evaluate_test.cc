// End-to-end tests of `rephoto evaluate` on a small synthetic scene (synth/demo_scene.h): six
// 160x120 photos of the demo object, a ground-truth mesh of about 5000 triangles.
#include "rephoto/eval/evaluate.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "rephoto/compare/compare.h"
#include "rephoto/compare/resample.h"
#include "rephoto/core/file.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/eval/evaluate_fixture.h"
#include "rephoto/eval/result_text.h"
#include "rephoto/eval/settings.h"
#include "rephoto/io/csv.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/metrics/compat.h"
#include "rephoto/render/render.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"
#include "rephoto/synth/demo_files.h"
#include "rephoto/testing/testing.h"

namespace rephoto::eval {
namespace {

namespace fs = std::filesystem;
using metrics::Metric;
using ::testing::HasSubstr;

constexpr int kViews = kTestViews;

// The scene on disk: images/view_XXX.png, sparse/ (COLMAP text), truth.ply (vertex colours),
// plain.ply (no colours), and by_hand/ = the ground truth rendered at every view with the
// settings evaluate uses (4 spp, seed 0), as `rephoto render` would write them.
struct SceneFiles {
  fs::path root, sparse, images, truth, plain, by_hand;
  scene::Scene scene;
};

const SceneFiles& Files() {
  static const SceneFiles files = [] {
    SceneFiles f;
    const synth::DemoSceneFiles& demo = EvaluateTestScene();
    f.root = demo.root;
    f.by_hand = f.root / "by_hand";
    f.sparse = demo.sparse;
    f.images = demo.images;
    f.truth = demo.truth;
    f.plain = demo.plain;
    f.scene = demo.scene;
    // By hand = as `rephoto render truth.ply` renders it: from the file (8-bit colours).
    render::RenderModel from_file(mesh::ReadPly(f.truth));
    render::RenderOptions by_hand_options;  // evaluate's defaults: 4 spp, seed 0
    for (const scene::View& view : f.scene.views) {
      const render::Rephoto rephoto = render::RenderRephoto(from_file, f.scene.CameraOf(view),
                                                            view.cam_from_world, by_hand_options);
      io::WritePng(f.by_hand / fs::path(view.name).replace_extension(".png"), rephoto.color);
    }
    return f;
  }();
  return files;
}

EvaluateOptions BaseOptions(const fs::path& out) {
  Files();  // the by-hand renderings too
  return EvaluateTestOptions(out);
}

std::vector<std::vector<std::string>> ReadCsv(const fs::path& path) {
  return io::ParseCsv(ReadFileToString(path), path.string());
}

nlohmann::json ReadJson(const fs::path& path) {
  return nlohmann::json::parse(ReadFileToString(path));
}

// per_image.csv rows by image name: {completeness, 1-ncc, cb+cr} as text.
std::map<std::string, std::vector<std::string>> Measurements(const fs::path& per_image) {
  const auto rows = ReadCsv(per_image);
  std::map<std::string, std::vector<std::string>> by_name;
  const auto& header = rows.at(0);
  const auto column = [&](const std::string& name) {
    return static_cast<size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  for (size_t r = 1; r < rows.size(); ++r) {
    by_name[rows[r][column("name")]] = {rows[r][column("status")], rows[r][column("completeness")],
                                        rows[r][column("1-ncc")], rows[r][column("cb+cr")]};
  }
  return by_name;
}

TEST(EvaluateTest, ModelModeGivesTheNumbersOfSplitRenderCompareByHand) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().truth;
  o.scheme = "kfold:3";
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.exit_code, ExitCode::kOk);
  ASSERT_EQ(result.folds.size(), 3u);
  EXPECT_EQ(result.images, static_cast<size_t>(kViews));
  EXPECT_EQ(result.evaluated_images, static_cast<size_t>(kViews));
  EXPECT_EQ(result.counters.views_rendered, static_cast<size_t>(kViews));

  // By hand: `rephoto compare` of the photos with the same renderings.
  compare::CompareOptions c;
  c.photos = Files().images;
  c.renders = Files().by_hand;
  c.out = testing::MakeTempDir() / "compare";
  c.metrics = o.metrics;
  const compare::CompareResult by_hand = compare::RunCompare(c);
  ASSERT_EQ(by_hand.images.size(), static_cast<size_t>(kViews));
  const auto evaluated = Measurements(run / "per_image.csv");
  const auto expected = Measurements(c.out / "per_image.csv");
  ASSERT_EQ(evaluated.size(), expected.size());
  for (const auto& [name, values] : expected) {
    ASSERT_TRUE(evaluated.count(name)) << name;
    EXPECT_EQ(evaluated.at(name), values) << name;  // same text = same double
  }
  // The rendering written is byte-identical to the one rendered by hand.
  EXPECT_EQ(ReadFileToString(run / "folds/fold_00/renders" /
                             (ReadCsv(run / "per_image.csv")[1][1] + ".png")),
            ReadFileToString(Files().by_hand / (ReadCsv(run / "per_image.csv")[1][1] + ".png")));
  // Over images: the same summary as compare's.
  ASSERT_EQ(result.metrics.size(), 2u);
  EXPECT_DOUBLE_EQ(result.metrics[0].over_images.median, by_hand.metrics[0].over_images.median);
  EXPECT_DOUBLE_EQ(result.metrics[0].pooled, by_hand.metrics[0].pooled);
  EXPECT_DOUBLE_EQ(result.completeness_over_images.mean, by_hand.completeness.mean);
  // Across folds: the folds' means of their images' means.
  const auto per_fold = ReadCsv(run / "per_fold.csv");
  ASSERT_EQ(per_fold.size(), 4u);
  EXPECT_EQ(per_fold[0][0], "fold");
  std::vector<double> fold_means;
  for (const FoldResult& fold : result.folds) {
    EXPECT_TRUE(fold.ok);
    EXPECT_EQ(fold.test_images, 2u);
    fold_means.push_back(fold.metric_means[0]);
  }
  std::sort(fold_means.begin(), fold_means.end());
  EXPECT_DOUBLE_EQ(result.metrics[0].across_folds.median, fold_means[1]);
  EXPECT_DOUBLE_EQ(result.metrics[0].across_folds.min, fold_means[0]);

  // The layout of the run directory.
  const nlohmann::json summary = ReadJson(run / "summary.json");
  EXPECT_EQ(summary["schema"], "rephoto.evaluate/1");
  EXPECT_EQ(summary["folds"], 3);
  EXPECT_EQ(summary["failed_folds"].size(), 0u);
  EXPECT_EQ(summary["metrics"]["1-ncc"]["across_folds"]["count"], 3);
  EXPECT_EQ(summary["metrics"]["1-ncc"]["over_images"]["count"], kViews);
  EXPECT_TRUE(summary["completeness"]["pooled"].is_number());
  for (const char* file :
       {"run.json", "manifest.json", "split/split.json", "split/fold_00/train/sparse/cameras.txt",
        "split/fold_02/test.txt", "folds/fold_00/fold.json"}) {
    EXPECT_TRUE(fs::exists(run / file)) << file;
  }
  const nlohmann::json run_json = ReadJson(run / "run.json");
  EXPECT_EQ(run_json["schema"], "rephoto.evaluate/1");
  EXPECT_EQ(run_json["status"], "ok");
  EXPECT_EQ(run_json["split"]["folds"].size(), 3u);
  EXPECT_GT(run_json["timings"]["rephoto"]["render"].get<double>(), 0.0);
  EXPECT_EQ(run_json["timings"]["external"], 0.0);
  EXPECT_EQ(run_json["inputs"]["photos"].size(), static_cast<size_t>(kViews));
  const nlohmann::json manifest = ReadJson(run / "manifest.json");
  EXPECT_EQ(manifest["tasks"].size(), static_cast<size_t>(kViews));  // no command tasks
  const std::string stem = ReadCsv(run / "per_image.csv")[1][1];
  EXPECT_TRUE(fs::exists(run / "folds/fold_00/views" / (stem + ".json")));
  // Written by default: the rendering and the headline metric's error images; no depth map
  // (nothing reads it: no projection here) and no other metric's images.
  EXPECT_TRUE(fs::exists(run / "folds/fold_00/renders" / (stem + ".png")));
  EXPECT_FALSE(fs::exists(run / "folds/fold_00/renders" / (stem + ".depth.exr")));
  EXPECT_TRUE(fs::exists(run / "folds/fold_00/errors" / (stem + ".1-ncc.exr")));
  EXPECT_TRUE(fs::exists(run / "folds/fold_00/errors" / (stem + ".1-ncc.png")));
  EXPECT_FALSE(fs::exists(run / "folds/fold_00/errors" / (stem + ".cb+cr.png")));
  EXPECT_FALSE(fs::exists(run / "folds/fold_00/errors" / (stem + ".cb+cr.exr")));
}

TEST(EvaluateTest, ModelAloneDefaultsToOneFoldWithoutCrossValidation) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().truth;
  o.error_images = false;
  const EvaluateResult result = RunEvaluate(o);
  ASSERT_EQ(result.folds.size(), 1u);
  EXPECT_EQ(result.folds[0].test_images, static_cast<size_t>(kViews));
  const nlohmann::json summary = ReadJson(run / "summary.json");
  EXPECT_EQ(summary["scheme"], "none");
  EXPECT_EQ(summary["cross_validated"], false);
  EXPECT_FALSE(fs::exists(run / "folds/fold_00/errors"));
  // The ground truth: everything covered, errors only from noise and anti-aliasing.
  EXPECT_GT(result.completeness_over_images.min, 0.95);
  EXPECT_LT(result.metrics[0].over_images.max, 0.2);
}

TEST(EvaluateTest, ResumeSkipsFinishedWorkAndRecomputesExactlyWhatChanged) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().truth;
  o.scheme = "kfold:2";
  const EvaluateResult first = RunEvaluate(o);
  EXPECT_EQ(first.counters.views_rendered, static_cast<size_t>(kViews));
  const std::string per_image = ReadFileToString(run / "per_image.csv");
  const std::string per_fold = ReadFileToString(run / "per_fold.csv");
  const std::string summary = ReadFileToString(run / "summary.json");

  // The same command again: nothing rendered or compared, identical aggregates.
  const EvaluateResult second = RunEvaluate(o);
  EXPECT_EQ(second.counters.views_rendered, 0u);
  EXPECT_EQ(second.counters.views_compared, 0u);
  EXPECT_EQ(second.counters.views_reused, static_cast<size_t>(kViews));
  EXPECT_EQ(ReadFileToString(run / "per_image.csv"), per_image);
  EXPECT_EQ(ReadFileToString(run / "summary.json"), summary);
  // per_fold.csv holds the recorded seconds, which do not change either.
  EXPECT_EQ(ReadFileToString(run / "per_fold.csv"), per_fold);

  // One view record deleted: only that view is recomputed, with the same result.
  const auto rows = ReadCsv(run / "per_image.csv");
  const std::string fold = rows[1][0], stem = rows[1][1];
  fs::remove(run / "folds" / fold / "views" / (stem + ".json"));
  const EvaluateResult third = RunEvaluate(o);
  EXPECT_EQ(third.counters.views_rendered, 1u);
  EXPECT_EQ(third.counters.views_compared, 1u);
  EXPECT_EQ(third.counters.views_reused, static_cast<size_t>(kViews - 1));
  EXPECT_EQ(ReadFileToString(run / "per_image.csv"), per_image);

  // A compare setting changed: every view is compared again, the renderings are reused.
  o.metric_options.window = 7;
  const EvaluateResult fourth = RunEvaluate(o);
  EXPECT_EQ(fourth.counters.views_compared, static_cast<size_t>(kViews));
  EXPECT_EQ(fourth.counters.views_rendered, 0u);
  EXPECT_NE(ReadFileToString(run / "per_image.csv"), per_image);

  // Back to the first settings: recomputed again, the same numbers as at first.
  o.metric_options.window = 9;
  RunEvaluate(o);
  EXPECT_EQ(ReadFileToString(run / "per_image.csv"), per_image);

  // A render setting changed: rendered and compared again.
  o.samples_per_pixel = 2;
  const EvaluateResult fifth = RunEvaluate(o);
  EXPECT_EQ(fifth.counters.views_rendered, static_cast<size_t>(kViews));
  EXPECT_NE(ReadFileToString(run / "per_image.csv"), per_image);
}

TEST(EvaluateTest, AnotherSplitReplacesTheOldFoldsOutputs) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().truth;
  o.scheme = "kfold:3";
  RunEvaluate(o);
  ASSERT_TRUE(fs::exists(run / "folds/fold_02"));
  o.scheme = "kfold:2";
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_FALSE(fs::exists(run / "folds/fold_02"));
  EXPECT_FALSE(fs::exists(run / "split/fold_02"));
  // Every record, rendering and error image left in a fold belongs to one of its test views.
  size_t records = 0;
  for (const auto& entry : fs::recursive_directory_iterator(run / "folds")) {
    if (entry.path().parent_path().filename() == "views") ++records;
  }
  EXPECT_EQ(records, static_cast<size_t>(kViews));
  size_t errors = 0;
  for (const auto& entry : fs::recursive_directory_iterator(run / "folds")) {
    if (entry.path().parent_path().filename() == "errors") ++errors;
  }
  EXPECT_EQ(errors, static_cast<size_t>(kViews) * 2);  // 1-NCC only by default: exr + png
  EXPECT_EQ(result.evaluated_images, static_cast<size_t>(kViews));
}

TEST(EvaluateTest, RunDirectoryOfAnotherSceneIsRefused) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().truth;
  o.error_images = false;
  RunEvaluate(o);
  // Another scene: the same cameras under other names.
  const fs::path other = testing::MakeTempDir();
  scene::Scene renamed = Files().scene;
  for (scene::View& view : renamed.views) {
    view.name = "other_" + view.name;
    fs::copy_file(Files().images / view.name.substr(6), other / view.name);
  }
  scene::WriteColmap(renamed, other / "sparse", scene::ColmapFormat::kText);
  o.scene = other / "sparse";
  o.image_root = other;
  try {
    RunEvaluate(o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("holds a run of another scene"), std::string::npos)
        << e.what();
  }
  // A folder with unrelated files is not taken either.
  const fs::path unrelated = testing::MakeTempDir() / "unrelated";
  WriteTextFileAtomically(unrelated / "notes.txt", "mine");
  o = BaseOptions(unrelated);
  o.model = Files().truth;
  EXPECT_THROW(RunEvaluate(o), Error);
}

// A command that records its placeholders and copies the ground truth into {out}.
std::string RecordingCommand() {
  return "printf '%s\\n' {train} {sparse} {transforms} {images} {train_list} {test} "
         "{test_sparse} {test_transforms} {test_list} {out} {fold} {threads} > {out}/args.txt "
         "&& cp " +
         ShellQuote(Files().truth.string()) + " {out}/mesh.ply && echo reconstructed";
}

std::vector<std::string> Lines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// issue 14: an image name that climbs out of the image root never reaches a stage that links,
// renders or writes: the scene is refused with file and line, and no file outside the run
// folder changes (inode, size, mtime).
TEST(EvaluateTest, TraversingImageNamesTouchNothingOutsideTheRun) {
  const fs::path root = testing::MakeTempDir();
  const fs::path victim = root / "X" / "secret.png";
  fs::create_directories(victim.parent_path());
  WriteTextFileAtomically(victim, "precious");
  struct stat before {};
  ASSERT_EQ(::stat(victim.c_str(), &before), 0);
  const fs::path images = root / "a" / "b" / "images";
  fs::create_directories(images);
  scene::Scene hostile = Files().scene;
  for (scene::View& view : hostile.views) fs::copy_file(view.image_path, images / view.name);
  hostile.views[1].name = "../../../X/secret.png";
  scene::WriteColmap(hostile, root / "sparse", scene::ColmapFormat::kText);
  EvaluateOptions o = BaseOptions(root / "run");
  o.scene = root / "sparse";
  o.image_root = images;
  o.model = "mesh.ply";
  o.reconstruct = "cp " + ShellQuote(Files().truth.string()) + " {out}/mesh.ply";
  try {
    RunEvaluate(o);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("images.txt:"));
    EXPECT_THAT(e.what(), HasSubstr("image name '../../../X/secret.png' contains '..'"));
  }
  struct stat after {};
  ASSERT_EQ(::stat(victim.c_str(), &after), 0);
  EXPECT_EQ(after.st_ino, before.st_ino);
  EXPECT_EQ(after.st_size, before.st_size);
  EXPECT_EQ(after.st_mtim.tv_sec, before.st_mtim.tv_sec);
  EXPECT_EQ(after.st_mtim.tv_nsec, before.st_mtim.tv_nsec);
  EXPECT_EQ(after.st_nlink, 1u);
  EXPECT_EQ(ReadFileToString(victim), "precious");
}

// issue 16: a 3D Gaussian splatting model is evaluated like any model: rendered by the CPU
// rasterizer, compared with completeness = alpha >= --min-alpha, error projected onto the
// Gaussians with every original property kept.
splat::GaussianModel GaussiansOfTheTruth() {
  // One isotropic Gaussian per vertex of the ground-truth mesh, coloured by its vertex colour
  // (SH degree 0), about as wide as the mesh's cells.
  const mesh::Mesh truth = mesh::ReadPly(Files().truth);
  const auto box = mesh::BoundingBox(truth);
  const float size = 0.6f * (box[1] - box[0]).norm() / 60.0f;
  splat::GaussianModel model;
  for (size_t v = 0; v < truth.vertex_count(); ++v) {
    model.positions.push_back(truth.positions[v]);
    model.scales.push_back(Eigen::Vector3f::Constant(size));
    model.rotations.push_back(Eigen::Vector4f(1, 0, 0, 0));
    model.opacities.push_back(0.9f);
    for (int c = 0; c < 3; ++c) model.sh.push_back((truth.colors[v][c] - 0.5f) / splat::kShC0);
  }
  return model;
}

TEST(EvaluateTest, GaussianSplattingModelsAreRenderedComparedAndProjected) {
  const fs::path dir = testing::MakeTempDir();
  const splat::GaussianModel model = GaussiansOfTheTruth();
  splat::WriteInriaPly(dir / "point_cloud.ply", model);
  EvaluateOptions o = BaseOptions(dir / "run");
  o.model = dir / "point_cloud.ply";  // detected: no --representation needed
  o.projection_metric = "1-ncc";
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.exit_code, ExitCode::kOk);
  EXPECT_EQ(result.evaluated_images, static_cast<size_t>(kViews));
  // The rendering is the rasterizer's of the model as read from the file (the PLY stores
  // log-scales, so the scales read back differ from `model`'s in the last bits), written as PNG.
  const scene::View& view = Files().scene.views[2];
  Image expected = splat::RenderGaussians(splat::ReadGaussians(dir / "point_cloud.ply"),
                                          Files().scene.CameraOf(view), view.cam_from_world)
                       .color;
  io::WritePng(dir / "expected.png", expected);
  const fs::path rendered = dir / "run/folds/fold_00/renders" / fs::path(view.name).filename();
  EXPECT_EQ(ReadFileToString(rendered), ReadFileToString(dir / "expected.png"));
  // Completeness and metrics: compare with the render mask alpha >= 0.5, by hand.
  const Image render = io::ReadImage(rendered);
  Mask render_mask(render.width(), render.height(), 1);
  size_t covered = 0;
  for (int y = 0; y < render.height(); ++y) {
    for (int x = 0; x < render.width(); ++x) {
      render_mask.at(x, y) = render.at(x, y, 3) >= 0.5f ? 255 : 0;
      covered += render.at(x, y, 3) >= 0.5f;
    }
  }
  ASSERT_GT(covered, 0u);
  ASSERT_LT(covered, static_cast<size_t>(render.width() * render.height()));
  compare::CompareOptions compare_options;
  compare_options.metrics = o.metrics;
  compare::CompareWorkspace workspace;
  const compare::ImageResult by_hand = compare::ComparePhotoAndRender(
      compare_options, "x", view.image_path, rendered, io::ReadImage(view.image_path), render,
      nullptr, &render_mask, dir, &workspace);
  const auto measured = Measurements(dir / "run/per_image.csv");
  const std::string stem = fs::path(view.name).stem().string();
  EXPECT_EQ(measured.at(stem)[1], io::CsvNumber(by_hand.completeness.value));
  EXPECT_EQ(measured.at(stem)[2], io::CsvNumber(by_hand.metrics[0].mean));
  EXPECT_GT(by_hand.completeness.value, 0.5);
  // issue 30: the same rule as compare's option, without a hand-made mask.
  compare_options.min_alpha = o.min_alpha;
  const compare::ImageResult by_rule = compare::ComparePhotoAndRender(
      compare_options, "x", view.image_path, rendered, io::ReadImage(view.image_path), render,
      nullptr, nullptr, dir, &workspace);
  EXPECT_EQ(measured.at(stem)[1], io::CsvNumber(by_rule.completeness.value));
  EXPECT_EQ(measured.at(stem)[2], io::CsvNumber(by_rule.metrics[0].mean));
  // The error on the Gaussians: the model's file with a float "error" added.
  const std::string projected = ReadFileToString(dir / "run/projected/1-ncc.ply");
  EXPECT_THAT(projected, HasSubstr("property float rot_3\nproperty float error\nend_header"));
  EXPECT_EQ(splat::ReadGaussians(dir / "run/projected/1-ncc.ply").size(), model.size());

  // A stricter --min-alpha counts fewer pixels as the model's.
  EvaluateOptions strict = o;
  strict.out = dir / "strict";
  strict.min_alpha = 0.99;
  strict.projection_metric = "none";
  EXPECT_LT(RunEvaluate(strict).completeness_over_images.mean,
            result.completeness_over_images.mean);
  // Gaussians cannot be coloured; a mesh is no Gaussian model.
  EvaluateOptions coloured = o;
  coloured.out = dir / "coloured";
  coloured.colorize = true;
  coloured.scheme = "kfold:2";
  const EvaluateResult coloured_result = RunEvaluate(coloured);
  EXPECT_EQ(coloured_result.exit_code, ExitCode::kIncomplete);
  EXPECT_THAT(coloured_result.folds[0].message,
              HasSubstr("point_cloud.ply: holds 3D Gaussians; --colorize and model defects need "
                        "a mesh"));
  EvaluateOptions forced = BaseOptions(dir / "forced");
  forced.model = Files().truth;
  forced.representation = render::ViewRepresentation::kGaussians;
  const EvaluateResult forced_result = RunEvaluate(forced);
  EXPECT_EQ(forced_result.exit_code, ExitCode::kIncomplete);
  EXPECT_THAT(forced_result.folds[0].message,
              HasSubstr("truth.ply: PLY vertices have no Gaussian properties"));
}

// issue 30: `evaluate --compat 3dgs` on a Gaussian model: the default split every:8, the preset's
// values from the PNG written and the photo (composited over the training background), in
// per_image.csv, the view records, summary.json and metrics.py's files; a rerun reuses them and
// another preset recomputes the values from the same renderings.
TEST(EvaluateTest, CompatPresetAddsThePublishedNumbersBesideRephotosOwn) {
  const fs::path dir = testing::MakeTempDir();
  splat::WriteInriaPly(dir / "point_cloud.ply", GaussiansOfTheTruth());
  EvaluateOptions o = BaseOptions(dir / "run");
  o.model = dir / "point_cloud.ply";
  o.compat = metrics::CompatPreset::k3dgs;
  o.background = {1, 1, 1};
  const EvaluateResult first = RunEvaluate(o);
  ASSERT_EQ(first.exit_code, ExitCode::kOk);
  EXPECT_EQ(ReadJson(dir / "run/summary.json")["scheme"], "every:8");
  EXPECT_EQ(first.images, 1u);  // 6 photos: index 0 only

  o.scheme = "every:2";  // three test views: image 0, 2, 4 by name
  const EvaluateResult result = RunEvaluate(o);
  ASSERT_EQ(result.exit_code, ExitCode::kOk);
  ASSERT_EQ(result.evaluated_images, 3u);
  std::vector<scene::View> views = Files().scene.views;
  std::sort(views.begin(), views.end(),
            [](const scene::View& a, const scene::View& b) { return a.name < b.name; });
  std::vector<double> psnr, ssim;
  const auto rows = ReadCsv(dir / "run/per_image.csv");
  ASSERT_EQ(rows.size(), 4u);
  ASSERT_EQ(rows[0][rows[0].size() - 2], "3dgs_psnr");
  ASSERT_EQ(rows[0].back(), "3dgs_ssim");
  const nlohmann::json per_view = ReadJson(dir / "run/per_view.json");
  for (size_t i = 0; i < 3; ++i) {
    const std::string stem = fs::path(views[2 * i].name).stem().string();
    const fs::path rendered = dir / "run/folds/fold_00/renders" / (stem + ".png");
    const fs::path photo = views[2 * i].image_path;
    const metrics::CompatResult expected = metrics::ComputeCompatMetrics(
        metrics::CompatPreset::k3dgs,
        metrics::CompositeOverBackground(io::ReadImage(photo), o.background),
        io::ReadImage(rendered));
    psnr.push_back(expected.psnr);
    ssim.push_back(expected.ssim);
    EXPECT_EQ(rows[i + 1][1], stem);
    EXPECT_EQ(rows[i + 1][rows[0].size() - 2], io::CsvNumber(expected.psnr));
    EXPECT_EQ(rows[i + 1].back(), io::CsvNumber(expected.ssim));
    EXPECT_DOUBLE_EQ(per_view["rephoto"]["PSNR"][stem + ".png"].get<double>(), expected.psnr);
    EXPECT_DOUBLE_EQ(per_view["rephoto"]["SSIM"][stem + ".png"].get<double>(), expected.ssim);
  }
  const double mean_psnr = (psnr[0] + psnr[1] + psnr[2]) / 3;
  const double mean_ssim = (ssim[0] + ssim[1] + ssim[2]) / 3;
  const nlohmann::json results = ReadJson(dir / "run/results.json");
  EXPECT_NEAR(results["rephoto"]["PSNR"].get<double>(), mean_psnr, 1e-12);
  EXPECT_NEAR(results["rephoto"]["SSIM"].get<double>(), mean_ssim, 1e-12);
  EXPECT_EQ(
      ReadFileToString(dir / "run/metrics.txt"),
      fmt::format("Scene: {}\nMethod: rephoto\n  SSIM : {:>12.7f}\n  PSNR : {:>12.7f}\n\n",
                  fs::absolute(dir / "run").lexically_normal().string(), mean_ssim, mean_psnr));
  ASSERT_EQ(result.compat.size(), 2u);
  EXPECT_NEAR(result.compat[0].over_images.mean, mean_psnr, 1e-12);
  double var = 0;
  for (double v : psnr) var += (v - mean_psnr) * (v - mean_psnr) / 2;
  EXPECT_NEAR(result.compat[0].std, std::sqrt(var), 1e-12);
  const nlohmann::json summary = ReadJson(dir / "run/summary.json");
  EXPECT_EQ(summary["compat"]["preset"], "3dgs");
  EXPECT_EQ(summary["compat"]["images"], 3);
  EXPECT_EQ(summary["files"]["per_view"], "per_view.json");
  EXPECT_TRUE(summary["metrics"].contains("1-ncc"));  // rephoto's own, masked, beside them

  // What the CLI prints after a Slurm run, read back from the run folder: the same lines.
  EXPECT_EQ(ReadEvaluateResult(dir / "run").compat_text, result.compat_text);
  EXPECT_THAT(ResultText(result, dir / "run"), HasSubstr(result.compat_text));

  // A rerun reuses every view with its compat values.
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(again.counters.views_reused, 3u);
  EXPECT_EQ(ReadJson(dir / "run/results.json"), results);
  // Another preset: the views are compared again from the renderings on disk.
  o.compat = metrics::CompatPreset::kNerfstudio;
  const EvaluateResult ns = RunEvaluate(o);
  EXPECT_EQ(ns.counters.views_reused, 0u);
  EXPECT_EQ(ns.counters.views_rendered, 0u);
  EXPECT_FALSE(fs::exists(dir / "run/results.json"));
  const nlohmann::json output = ReadJson(dir / "run/output.json");
  // psnr, psnr_std, ssim, ssim_std
  EXPECT_EQ(output["results"].size(), 4u);
  EXPECT_NE(output["results"]["ssim"].get<double>(), mean_ssim);  // reflect, not zero padding
  EXPECT_EQ(ReadCsv(dir / "run/per_image.csv")[0].back(), "nerfstudio_ssim");
}

TEST(EvaluateTest, ReconstructCommandGetsQuotedPlaceholdersAndIsResumed) {
  const fs::path run = testing::MakeTempDir() / "run with 'quotes' and spaces";
  EvaluateOptions o = BaseOptions(run);
  o.reconstruct = RecordingCommand();
  o.model = "mesh.ply";
  o.scheme = "kfold:2";
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.exit_code, ExitCode::kOk);
  EXPECT_EQ(result.counters.commands_run, 2u);
  const fs::path fold1 = run / "folds/fold_01";
  const std::vector<std::string> args = Lines(fold1 / "reconstruction/args.txt");
  ASSERT_EQ(args.size(), 12u);
  EXPECT_EQ(args[0], (run / "split/fold_01/train").string());
  EXPECT_EQ(args[1], (run / "split/fold_01/train/sparse").string());
  EXPECT_EQ(args[2], (run / "split/fold_01/train/transforms.json").string());
  // {images}: only the fold's training photos (links), never a test photo.
  EXPECT_EQ(args[3], (fold1 / "train/images").string());
  std::vector<std::string> linked;
  for (const auto& entry : fs::directory_iterator(args[3])) {
    linked.push_back(entry.path().filename().string());
  }
  std::sort(linked.begin(), linked.end());
  EXPECT_EQ(linked, Lines(run / "split/fold_01/train.txt"));
  EXPECT_EQ(ReadFileToString(fs::path(args[3]) / linked[0]),
            ReadFileToString(Files().images / linked[0]));
  EXPECT_EQ(args[4], (run / "split/fold_01/train.txt").string());
  EXPECT_EQ(args[5], (run / "split/fold_01/test").string());
  EXPECT_EQ(args[8], (run / "split/fold_01/test.txt").string());
  EXPECT_EQ(args[9], (fold1 / "reconstruction").string());
  EXPECT_EQ(args[10], "1");
  EXPECT_GE(std::stoi(args[11]), 1);
  EXPECT_TRUE(fs::exists(args[1] + "/images.txt"));
  EXPECT_EQ(Lines(run / "logs/fold_01.reconstruct.log").back(), "reconstructed");

  // The same numbers as the model itself.
  EvaluateOptions m = BaseOptions(testing::MakeTempDir() / "model");
  m.model = Files().truth;
  m.scheme = "kfold:2";
  RunEvaluate(m);
  EXPECT_EQ(Measurements(run / "per_image.csv"), Measurements(m.out / "per_image.csv"));

  const nlohmann::json manifest = ReadJson(run / "manifest.json");
  EXPECT_EQ(manifest["tasks"].size(), static_cast<size_t>(kViews + 2));
  EXPECT_EQ(manifest["tasks"][0]["kind"], "reconstruct");

  // Rerun: no command, no rendering.
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(again.counters.commands_run, 0u);
  EXPECT_EQ(again.counters.folds_reused, 2u);
  EXPECT_EQ(again.counters.views_rendered, 0u);
  // A changed command template reruns the commands.
  o.reconstruct += " && true";
  const EvaluateResult changed = RunEvaluate(o);
  EXPECT_EQ(changed.counters.commands_run, 2u);
  // The model is the same file content: the views are still valid.
  EXPECT_EQ(changed.counters.views_rendered, 0u);
}

TEST(EvaluateTest, FailingCommandsFailOnlyTheirFoldNamingTheLog) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.scheme = "kfold:5";
  o.model = "mesh.ply";
  o.reconstruct =
      "case {fold} in 0) echo broken >&2; exit 3;; 1) true;; 2) echo garbage > "
      "{out}/mesh.ply;; 3) no_such_rephoto_tool;; *) cp " +
      ShellQuote(Files().truth.string()) + " {out}/mesh.ply;; esac";
  o.jobs = 2;
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.exit_code, ExitCode::kIncomplete);
  ASSERT_EQ(result.folds.size(), 5u);
  for (int f = 0; f < 4; ++f) {
    EXPECT_FALSE(result.folds[f].ok) << f;
    EXPECT_NE(result.folds[f].message.find(fmt::format("fold_0{}: reconstruct command", f)),
              std::string::npos)
        << result.folds[f].message;
    EXPECT_NE(result.folds[f].message.find(fmt::format("logs/fold_0{}.reconstruct.log", f)),
              std::string::npos)
        << result.folds[f].message;
  }
  EXPECT_NE(result.folds[0].message.find("exit status 3"), std::string::npos);
  EXPECT_NE(result.folds[0].message.find("last line: broken"), std::string::npos);
  EXPECT_NE(result.folds[1].message.find("wrote nothing"), std::string::npos);
  EXPECT_NE(result.folds[2].message.find("cannot be read"), std::string::npos);
  EXPECT_NE(result.folds[3].message.find("command not found"), std::string::npos);
  EXPECT_TRUE(result.folds[4].ok);
  EXPECT_EQ(result.folds[4].evaluated_images, result.folds[4].test_images);
  const nlohmann::json summary = ReadJson(run / "summary.json");
  EXPECT_EQ(summary["failed_folds"].size(), 4u);
  const auto per_fold = ReadCsv(run / "per_fold.csv");
  EXPECT_EQ(per_fold[1][1], "failed");
  EXPECT_EQ(per_fold[5][1], "ok");
  size_t failed_rows = 0;
  for (const auto& row : ReadCsv(run / "per_image.csv")) failed_rows += row[2] == "failed";
  EXPECT_EQ(failed_rows, static_cast<size_t>(kViews) - result.folds[4].test_images);

  // Rerun: failed folds run their command again, the good fold is reused.
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(again.counters.commands_run, 4u);
  EXPECT_EQ(again.counters.folds_reused, 1u);
}

TEST(EvaluateTest, HungCommandTimesOutFailingOnlyItsFold) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.scheme = "kfold:2";
  o.model = "mesh.ply";
  o.reconstruct = "case {fold} in 0) sleep 1000;; *) cp " + ShellQuote(Files().truth.string()) +
                  " {out}/mesh.ply;; esac";
  o.command_timeout = 0.5;
  const auto start = std::chrono::steady_clock::now();
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 60);
  EXPECT_EQ(result.exit_code, ExitCode::kIncomplete);
  ASSERT_EQ(result.folds.size(), 2u);
  EXPECT_FALSE(result.folds[0].ok);
  EXPECT_THAT(result.folds[0].message, HasSubstr("timed out after 0.5 s, --command-timeout"));
  EXPECT_TRUE(result.folds[1].ok);
  EXPECT_EQ(ReadJson(run / "run.json")["settings"]["command-timeout"], 0.5);
}

TEST(EvaluateTest, AFailedRunSaysSoInRunJson) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().truth;
  // More folds than photos: found once the scene is read and the run folder is this run's.
  o.scheme = "kfold:50";
  EXPECT_THROW(RunEvaluate(o), Error);
  const nlohmann::json record = ReadJson(run / "run.json");
  EXPECT_EQ(record["status"], "failed");
  EXPECT_THAT(record["error"].get<std::string>(), HasSubstr("kfold:50"));
}

TEST(EvaluateTest, ExternalRendererImagesAreComparedAsTheyAre) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.scheme = "kfold:2";
  // Copies the by-hand renderings of the fold's test views.
  o.render = "while read n; do cp " + ShellQuote(Files().by_hand.string()) +
             "/\"${n%.*}.png\" {out}/; done < {test_list}";
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.exit_code, ExitCode::kOk);
  EXPECT_EQ(result.counters.views_rendered, 0u);
  EXPECT_EQ(result.counters.views_compared, static_cast<size_t>(kViews));
  EvaluateOptions m = BaseOptions(testing::MakeTempDir() / "model");
  m.model = Files().truth;
  m.scheme = "kfold:2";
  RunEvaluate(m);
  EXPECT_EQ(Measurements(run / "per_image.csv"), Measurements(m.out / "per_image.csv"));
  const auto rows = ReadCsv(run / "per_image.csv");
  EXPECT_EQ(rows[1][4].rfind("folds/fold_00/reconstruction/", 0), 0u) << rows[1][4];
  EXPECT_FALSE(fs::exists(run / "folds/fold_00/renders"));
  // Resume.
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(again.counters.commands_run, 0u);
  EXPECT_EQ(again.counters.views_compared, 0u);
}

TEST(EvaluateTest, ExternalRendererGetsTheTestCamerasAtTheEvaluationSize) {
  // The by-hand renderings at half size, as a renderer told to render 80x60 would write them.
  const fs::path half = testing::MakeTempDir() / "half";
  for (const scene::View& view : Files().scene.views) {
    const std::string name = fs::path(view.name).replace_extension(".png").string();
    Image small;
    compare::ResizeImage(io::ReadImage(Files().by_hand / name), 80, 60, &small);
    io::WritePng(half / name, small);
  }
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.scheme = "kfold:2";
  o.eval_short_side = 60;
  o.render =
      "head -n 4 {test_sparse}/cameras.txt | tail -n 1 > {out}/camera.txt; "
      "while read n; do cp " +
      ShellQuote(half.string()) + "/\"${n%.*}.png\" {out}/; done < {test_list}";
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.exit_code, ExitCode::kOk);
  EXPECT_EQ(result.evaluated_images, static_cast<size_t>(kViews));
  const std::string camera = Lines(run / "folds/fold_00/reconstruction/camera.txt").at(0);
  EXPECT_NE(camera.find(" 80 60 "), std::string::npos) << camera;
  EXPECT_EQ(ReadCsv(run / "per_image.csv")[1][5], "80");
  // Close to the built-in renderer at that size (the area-downscaled 4-spp rendering is a
  // slightly smoother image than a 4-spp rendering at 80x60).
  EvaluateOptions m = BaseOptions(testing::MakeTempDir() / "model");
  m.model = Files().truth;
  m.scheme = "kfold:2";
  m.eval_short_side = 60;
  const EvaluateResult model = RunEvaluate(m);
  EXPECT_NEAR(result.metrics[0].over_images.median, model.metrics[0].over_images.median, 0.05);
  EXPECT_NEAR(result.completeness_over_images.median, model.completeness_over_images.median, 0.02);
}

TEST(EvaluateTest, RendererWithTooFewOrWrongSizeImagesFailsItsFold) {
  const fs::path run = testing::MakeTempDir() / "run";
  const fs::path small = testing::MakeTempDir() / "small.png";
  io::WritePng(small, Image(80, 60, 4, 1.f));
  EvaluateOptions o = BaseOptions(run);
  o.scheme = "kfold:4";
  // fold 0: all but the first test image; fold 1: wrong size; fold 2: a corrupt image;
  // fold 3: fine.
  o.render =
      "first=1; while read n; do s=\"${n%.*}\"; case {fold} in "
      "0) [ $first = 1 ] || cp " +
      ShellQuote(Files().by_hand.string()) +
      "/\"$s.png\" {out}/;; "
      "1) cp " +
      ShellQuote(small.string()) +
      " {out}/\"$s.png\";; "
      "2) echo garbage > {out}/\"$s.png\";; "
      "*) cp " +
      ShellQuote(Files().by_hand.string()) +
      "/\"$s.png\" {out}/;; "
      "esac; first=0; done < {test_list}";
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.exit_code, ExitCode::kIncomplete);
  ASSERT_EQ(result.folds.size(), 4u);
  EXPECT_FALSE(result.folds[0].ok);
  EXPECT_NE(result.folds[0].message.find("wrote 1 of 2 images (missing: "), std::string::npos)
      << result.folds[0].message;
  EXPECT_NE(result.folds[0].message.find("logs/fold_00.render.log"), std::string::npos);
  EXPECT_FALSE(result.folds[1].ok);
  EXPECT_NE(result.folds[1].message.find("is 80x60, expected 160x120"), std::string::npos)
      << result.folds[1].message;
  EXPECT_FALSE(result.folds[2].ok);
  EXPECT_NE(result.folds[2].message.find("wrote 1 unreadable image(s)"), std::string::npos)
      << result.folds[2].message;
  EXPECT_TRUE(result.folds[3].ok);
  EXPECT_EQ(result.folds[3].evaluated_images, 1u);
}

// Issue 7: view-dependent texturing renders a test view from the fold's training photos only.
// If the test photo were among them (scheme "none": every photo trains and tests) it would
// reproduce itself almost exactly; evaluate's folds are what makes the error honest.
TEST(EvaluateTest, ImageBasedRenderersUseOnlyTheFoldsTrainingPhotos) {
  EvaluateOptions o = BaseOptions(testing::MakeTempDir() / "vdt");
  o.model = Files().truth;
  o.representation = render::ViewRepresentation::kVdt;
  o.scheme = "kfold:3";
  o.error_images = false;
  const EvaluateResult held_out = RunEvaluate(o);
  ASSERT_EQ(held_out.exit_code, ExitCode::kOk);
  EXPECT_EQ(held_out.evaluated_images, 6u);
  o.out = testing::MakeTempDir() / "vdt_leak";
  o.scheme = "none";
  const EvaluateResult leaked = RunEvaluate(o);
  ASSERT_EQ(leaked.exit_code, ExitCode::kOk);
  const double fair = held_out.metrics[0].over_images.median;
  const double cheat = leaked.metrics[0].over_images.median;
  std::printf("vdt 1-ncc median: held out %.4f, test photo in training %.4f\n", fair, cheat);
  EXPECT_LT(cheat, 0.02);
  EXPECT_GT(fair, 3 * cheat);
  // Still a good rendering: well below the vertex-coloured ground truth's error... of flat grey.
  EXPECT_LT(fair, 0.5);
  EXPECT_GT(held_out.completeness_over_images.median, 0.8);

  // IBR needs no model: per-view depth maps (here the ground truth's, as EXR files named like
  // `rephoto render` writes them; plane-sweep estimation is tested in ibr/).
  const fs::path depth_dir = testing::MakeTempDir() / "depth";
  const render::RenderModel truth(mesh::ReadPly(Files().truth));
  for (const auto& view : Files().scene.views) {
    const auto r = render::RenderRephoto(truth, Files().scene.CameraOf(view), view.cam_from_world);
    io::WriteExr(depth_dir / (fs::path(view.name).stem().string() + ".depth.exr"), r.depth);
  }
  const fs::path ibr_run = testing::MakeTempDir() / "ibr";
  EvaluateOptions i = BaseOptions(ibr_run);
  i.representation = render::ViewRepresentation::kIbr;
  i.depth_maps = depth_dir;
  i.scheme = "kfold:3";
  i.error_images = false;
  const EvaluateResult ibr = RunEvaluate(i);
  for (const auto& fold : ibr.folds) EXPECT_TRUE(fold.ok) << fold.message;
  ASSERT_EQ(ibr.exit_code, ExitCode::kOk);
  EXPECT_EQ(ibr.evaluated_images, 6u);
  // No model, only each fold's training photos: cross-validated (a fixed --model is not).
  EXPECT_EQ(ReadJson(ibr_run / "summary.json")["cross_validated"], true);
  std::printf("ibr: completeness %.4f, 1-ncc %.4f\n", ibr.completeness_over_images.median,
              ibr.metrics[0].over_images.median);
  EXPECT_GT(ibr.completeness_over_images.median, 0.7);
  EXPECT_LT(ibr.metrics[0].over_images.median, 0.3);
  // A resumed run reuses it; --depth-maps is only for ibr, and vdt needs a model.
  EXPECT_EQ(RunEvaluate(i).counters.views_rendered, 0u);
  EvaluateOptions bad = i;
  bad.representation = render::ViewRepresentation::kVdt;
  EXPECT_THROW(RunEvaluate(bad), UsageError);
  bad = o;
  bad.depth_maps = "somewhere";
  EXPECT_THROW(RunEvaluate(bad), UsageError);
}

TEST(EvaluateTest, EvalShortSideRendersAndComparesSmaller) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().truth;
  o.eval_short_side = 60;
  o.error_images = false;
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.counters.photos_downscaled, static_cast<size_t>(kViews));
  const auto rows = ReadCsv(run / "per_image.csv");
  EXPECT_EQ(rows[1][5], "80");
  EXPECT_EQ(rows[1][6], "60");
  // The photo by its scene name, not by the path of its downscaled copy in this run's cache:
  // the same inputs evaluated in another folder give byte-identical tables.
  EXPECT_EQ(rows[1][3], Files().scene.views[0].name);
  EvaluateOptions elsewhere = o;
  elsewhere.out = testing::MakeTempDir() / "elsewhere";
  RunEvaluate(elsewhere);
  EXPECT_EQ(ReadFileToString(elsewhere.out / "per_image.csv"),
            ReadFileToString(run / "per_image.csv"));
  EXPECT_EQ(ReadFileToString(elsewhere.out / "per_fold.csv"),
            ReadFileToString(run / "per_fold.csv"));
  const io::ImageHeader header =
      io::ReadImageHeader(run / "folds/fold_00/renders" / (rows[1][1] + ".png"));
  EXPECT_EQ(header.width, 80);
  EXPECT_LT(result.metrics[0].over_images.max, 0.3);
  EXPECT_GT(result.completeness_over_images.min, 0.9);
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(again.counters.photos_downscaled, 0u);
  EXPECT_EQ(again.counters.views_reused, static_cast<size_t>(kViews));
}

TEST(EvaluateTest, TrainCountAndTrainShortSideShapeTheTrainingScene) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.scheme = "loo";
  o.train_count = 3;
  o.train_short_side = 60;
  o.model = "mesh.ply";
  o.reconstruct =
      "ls {images} > {out}/images.txt && head -n 4 {sparse}/cameras.txt | tail -n 1 "
      "> {out}/camera.txt && cp " +
      ShellQuote(Files().truth.string()) + " {out}/mesh.ply";
  o.error_images = false;
  const EvaluateResult result = RunEvaluate(o);
  ASSERT_EQ(result.folds.size(), static_cast<size_t>(kViews));
  EXPECT_EQ(result.exit_code, ExitCode::kOk);
  const fs::path fold = run / "folds/fold_02";
  const std::vector<std::string> images = Lines(fold / "reconstruction/images.txt");
  EXPECT_EQ(images.size(), 3u);
  EXPECT_EQ(Lines(fold / "train/train.txt"), images);
  const io::ImageHeader header = io::ReadImageHeader(fold / "train/images" / images[0]);
  EXPECT_EQ(header.width, 80);
  EXPECT_EQ(header.height, 60);
  const std::string camera = Lines(fold / "reconstruction/camera.txt").at(0);
  EXPECT_NE(camera.find(" 80 60 "), std::string::npos) << camera;
  // The test view is not among the training photos.
  const std::string test = Lines(run / "split/fold_02/test.txt").at(0);
  EXPECT_EQ(std::count(images.begin(), images.end(), test), 0);
  // Different folds draw different subsets (seeded by the fold index).
  EXPECT_NE(Lines(run / "folds/fold_00/train/train.txt"),
            Lines(run / "folds/fold_03/train/train.txt"));
  // Each photo is downscaled once for all folds (a shared cache, hard-linked into the folds).
  EXPECT_LE(result.counters.photos_downscaled, static_cast<size_t>(kViews));
  EXPECT_GE(result.counters.photos_downscaled, 3u);
  // Fewer training views: the fold's images folder holds exactly the new subset.
  o.train_count = 2;
  const EvaluateResult fewer = RunEvaluate(o);
  EXPECT_EQ(fewer.counters.photos_downscaled, 0u);
  EXPECT_EQ(fewer.counters.commands_run, static_cast<size_t>(kViews));
  EXPECT_EQ(Lines(fold / "reconstruction/images.txt").size(), 2u);
}

TEST(EvaluateTest, InterruptedRunResumes) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.scheme = "kfold:2";
  o.model = "mesh.ply";
  o.reconstruct = "sleep 0.5 && cp " + ShellQuote(Files().truth.string()) + " {out}/mesh.ply";
  o.error_images = false;
  std::thread interrupter([] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    RequestInterrupt(true);
  });
  try {
    RunEvaluate(o);
    interrupter.join();
    FAIL() << "not interrupted";
  } catch (const Error& e) {
    interrupter.join();
    EXPECT_NE(std::string(e.what()).find("rerun the same command to resume"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(ReadJson(run / "run.json")["status"], "interrupted");
  const EvaluateResult resumed = RunEvaluate(o);
  EXPECT_EQ(resumed.exit_code, ExitCode::kOk);
  EXPECT_EQ(resumed.evaluated_images, static_cast<size_t>(kViews));
}

TEST(EvaluateTest, ErrorIsProjectedOntoTheModelAndTheReportWritten) {
  const fs::path run = testing::MakeTempDir() / "run";
  EvaluateOptions o = BaseOptions(run);
  o.model = Files().truth;
  o.scheme = "kfold:2";
  o.report = true;
  o.projection_metric = "1-ncc";
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.counters.projections, 1u);
  const mesh::Mesh projected = mesh::ReadPly(run / "projected/1-ncc.ply");
  EXPECT_EQ(projected.vertex_count(), mesh::ReadPly(Files().truth).vertex_count());
  const auto error = std::find_if(projected.scalars.begin(), projected.scalars.end(),
                                  [](const mesh::VertexScalar& s) { return s.name == "error"; });
  ASSERT_NE(error, projected.scalars.end());
  // The ground truth's projected error is small wherever a vertex was seen.
  size_t seen = 0;
  double sum = 0;
  for (float e : error->values) {
    if (std::isnan(e)) continue;
    ++seen;
    sum += e;
  }
  EXPECT_GT(seen, projected.vertex_count() / 4);
  EXPECT_LT(sum / static_cast<double>(seen), 0.1);
  EXPECT_TRUE(fs::exists(run / "report.html"));
  const nlohmann::json run_json = ReadJson(run / "run.json");
  EXPECT_EQ(run_json["outputs"]["projected"][0], "projected/1-ncc.ply");
  EXPECT_EQ(run_json["outputs"]["report"], "report.html");
  // Resumed: the projection is still valid.
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(again.counters.projections, 0u);
}

TEST(EvaluateTest, PhotoMasksRestrictTheComparedPixels) {
  const fs::path masks = testing::MakeTempDir() / "masks";
  for (const scene::View& view : Files().scene.views) {
    Image mask(160, 120, 1, 1.f);
    for (int y = 0; y < 120; ++y) {
      for (int x = 0; x < 80; ++x) mask.at(x, y) = 0.f;  // ignore the left half
    }
    io::WritePng(masks / fs::path(view.name).replace_extension(".png"), mask);
  }
  EvaluateOptions o = BaseOptions(testing::MakeTempDir() / "masked");
  o.model = Files().truth;
  o.error_images = false;
  o.photo_masks = masks;
  RunEvaluate(o);
  EvaluateOptions u = BaseOptions(testing::MakeTempDir() / "unmasked");
  u.model = Files().truth;
  u.error_images = false;
  RunEvaluate(u);
  const auto masked = ReadCsv(o.out / "per_image.csv");
  const auto unmasked = ReadCsv(u.out / "per_image.csv");
  ASSERT_EQ(masked.size(), unmasked.size());
  for (size_t r = 1; r < masked.size(); ++r) {
    // valid_photo_windows: 9x9 windows fully inside the right half (x >= 80): 72 - 8 columns
    // fewer than without the mask (all 152 window columns), rows unchanged.
    const double ratio = std::stod(masked[r][9]) / std::stod(unmasked[r][9]);
    EXPECT_NEAR(ratio, 72.0 / 152.0, 0.02) << masked[r][1];
  }
  // A changed mask recomputes its view only.
  Image all(160, 120, 1, 1.f);
  io::WritePng(masks / "view_002.png", all);
  const EvaluateResult again = RunEvaluate(o);
  EXPECT_EQ(again.counters.views_compared, 1u);
}

TEST(EvaluateTest, UnreadablePhotoFailsOnlyItsView) {
  const fs::path dir = testing::MakeTempDir();
  for (const scene::View& view : Files().scene.views) {
    fs::copy_file(view.image_path, dir / view.name);
  }
  // Truncated after the header: the scene reads (sizes known), decoding fails.
  const std::string bytes = ReadFileToString(dir / "view_003.png");
  WriteTextFileAtomically(dir / "view_003.png", bytes.substr(0, bytes.size() / 2));
  EvaluateOptions o = BaseOptions(testing::MakeTempDir() / "run");
  o.image_root = dir;
  o.model = Files().truth;
  o.scheme = "kfold:2";
  o.error_images = false;
  const EvaluateResult result = RunEvaluate(o);
  EXPECT_EQ(result.exit_code, ExitCode::kIncomplete);
  EXPECT_EQ(result.evaluated_images, static_cast<size_t>(kViews - 1));
  size_t failed = 0;
  for (const FoldResult& fold : result.folds) {
    if (fold.ok) continue;
    ++failed;
    EXPECT_NE(fold.message.find("view_003"), std::string::npos) << fold.message;
  }
  EXPECT_EQ(failed, 1u);
  const auto rows = ReadCsv(o.out / "per_image.csv");
  for (const auto& row : rows) {
    if (row[1] == "view_003") {
      EXPECT_EQ(row[2], "failed");
    }
  }
}

TEST(EvaluateTest, BadSettingsAreUsageErrors) {
  EvaluateOptions o = BaseOptions(testing::MakeTempDir() / "run");
  EXPECT_THROW(RunEvaluate(o), UsageError);  // no model source
  o.reconstruct = "make {output}";
  o.model = "m.ply";
  try {
    RunEvaluate(o);
    FAIL() << "no error";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown placeholder {output} (known: {train}"),
              std::string::npos)
        << e.what();
  }
  o.reconstruct.clear();
  o.model = Files().truth;
  // Settings parse the representation's name once, where it enters.
  EXPECT_THROW(ApplySetting(&o, "representation", std::string("bilinear"), "--representation"),
               UsageError);
}

}  // namespace
}  // namespace rephoto::eval
