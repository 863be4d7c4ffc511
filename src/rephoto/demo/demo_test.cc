#include "rephoto/demo/demo.h"

#include <gtest/gtest.h>

#include <cmath>

#include "rephoto/compare/compare.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"
#include "rephoto/render/render.h"
#include "rephoto/testing/testing.h"

namespace rephoto::demo {
namespace {

TEST(Demo, SmallDemoRanksGroundTruthFirstAndWritesItsOutputs) {
  DemoOptions options;
  options.out = testing::MakeTempDir() / "demo";
  options.scene.image_width = 240;
  options.scene.image_height = 180;
  options.scene.camera_count = 4;
  options.scene.ground_cells = 120;
  options.scene.object_bands = 60;
  options.photo_samples_per_pixel = 4;
  options.metrics = {metrics::Metric::kOneMinusNcc, metrics::Metric::kCbCr};
  const DemoResult result = RunDemo(options);
  ASSERT_EQ(result.ranking.size(), 6u);
  EXPECT_EQ(result.ranking.front().name, "ground_truth");
  for (const auto& r : result.ranking) {
    EXPECT_EQ(r.result.evaluated_images, 4u) << r.name;
    EXPECT_EQ(r.result.folds.size(), 4u) << r.name;  // kfold:4 over 4 photos
    EXPECT_TRUE(r.result.missing_photos.empty());
    EXPECT_TRUE(std::filesystem::exists(r.model));
    EXPECT_TRUE(std::filesystem::exists(r.run_dir / "per_fold.csv"));
    EXPECT_TRUE(std::filesystem::exists(r.run_dir / "report.html"));
    // Error images of 1-NCC only: 4 views, an EXR and a PNG each.
    size_t error_files = 0;
    for (const auto& entry : std::filesystem::recursive_directory_iterator(r.run_dir / "folds")) {
      if (entry.path().parent_path().filename() != "errors") continue;
      EXPECT_NE(entry.path().filename().string().find(".1-ncc."), std::string::npos)
          << entry.path();
      ++error_files;
    }
    EXPECT_EQ(error_files, 8u) << r.name;
  }
  // The ground truth covers everything the photos show.
  EXPECT_GT(result.ranking.front().result.completeness_across_folds.median, 0.99);
  EXPECT_TRUE(std::filesystem::exists(options.out / "report.html"));
  EXPECT_TRUE(std::filesystem::exists(options.out / "ranking.csv"));
  EXPECT_TRUE(std::filesystem::exists(options.out / "demo.json"));
  EXPECT_TRUE(std::filesystem::exists(options.out / "scene" / "sparse" / "cameras.txt"));
  // The acquisition step: the photos of one side (2 of the 4 on the ring) and 3 suggested
  // views, shown in the comparison report with their rephotos.
  ASSERT_TRUE(result.suggestions.has_value());
  EXPECT_EQ(result.suggestions->photos_so_far, 2u);
  EXPECT_GT(result.suggestions->unseen_fraction, 0.05);
  EXPECT_GT(result.suggestions->covered_fraction, 0.7);
  const std::filesystem::path next = options.out / "next_photos";
  for (const char* file :
       {"photos_so_far/sparse/images.txt", "sparse/images.txt", "transforms.json",
        "suggestions.json", "report.html", "renders/suggest_00.png", "renders/suggest_02.png"}) {
    EXPECT_TRUE(std::filesystem::is_regular_file(next / file)) << file;
  }
  const std::string html = ReadFileToString(options.out / "report.html");
  EXPECT_NE(html.find("id=\"next-photos\""), std::string::npos);
  // Evaluate runs name photos by their scene names; the reports find them all the same.
  EXPECT_EQ(html.find("not available: no photo"), std::string::npos);
  EXPECT_EQ(ReadFileToString(result.ranking.front().run_dir / "report.html")
                .find("not available: no photo"),
            std::string::npos);
  size_t rows = 0;
  for (size_t at = html.find("<tr class=\"suggestion\""); at != std::string::npos;
       at = html.find("<tr class=\"suggestion\"", at + 1)) {
    ++rows;
  }
  EXPECT_EQ(rows, 3u);
  // Issue 32: the suggestions weigh the ground truth's projected error, so each has a mean
  // error (the column was all "–"); the report's 3D view shows the runs and the suggestions.
  EXPECT_EQ(html.find("data-mean-error=\"\""), std::string::npos);
  EXPECT_NE(html.find("<div class=\"view3d\" id=\"view3d\">"), std::string::npos);
  EXPECT_NE(html.find("\"role\":\"suggested\""), std::string::npos);
  EXPECT_NE(html.find("<section id=\"side-by-side\">"), std::string::npos);
}

}  // namespace
}  // namespace rephoto::demo

namespace rephoto::demo {
namespace {

// Issue 4's self-consistency check: the procedural ground truth rendered at a camera and
// compared with itself (once as the photo without alpha, once as the RGBA rephoto) gives zero
// error for every metric and full completeness.
TEST(Demo, GroundTruthRephotoComparedWithItselfHasZeroError) {
  synth::DemoSceneOptions scene_options;
  scene_options.image_width = 200;
  scene_options.image_height = 150;
  scene_options.camera_count = 2;
  scene_options.ground_cells = 100;
  scene_options.object_bands = 50;
  const auto dir = testing::MakeTempDir();
  const scene::Scene scene = synth::MakeDemoScene(scene_options, dir / "photos");
  render::RenderModel model(synth::MakeDemoMesh(scene_options));
  for (const auto& view : scene.views) {
    const render::Rephoto r =
        render::RenderRephoto(model, scene.CameraOf(view), view.cam_from_world);
    Image rgb(r.color.width(), r.color.height(), 3);
    for (size_t p = 0; p < rgb.pixel_count(); ++p) {
      for (int c = 0; c < 3; ++c) rgb.data()[3 * p + c] = r.color.data()[4 * p + c];
    }
    io::WritePng(dir / "photos" / view.name, rgb);
    io::WritePng(dir / "renders" / view.name, r.color);
  }
  compare::CompareOptions options;
  options.photos = dir / "photos";
  options.renders = dir / "renders";
  options.out = dir / "run";
  const compare::CompareResult result = compare::RunCompare(options);
  ASSERT_EQ(result.images.size(), 2u);
  for (const auto& image : result.images) {
    EXPECT_EQ(image.completeness.value, 1.0) << image.name;
    for (size_t m = 0; m < options.metrics.size(); ++m) {
      const double value = image.metrics[m].mean;
      switch (options.metrics[m]) {
        case metrics::Metric::kPsnr:
          EXPECT_TRUE(std::isinf(value)) << image.name;
          break;
        case metrics::Metric::kSsim:
          EXPECT_EQ(value, 1.0) << image.name;
          break;
        default:
          EXPECT_EQ(value, 0.0) << metrics::MetricName(options.metrics[m]) << " " << image.name;
      }
      EXPECT_GT(image.metrics[m].evaluated, 1000u);
    }
  }
}

}  // namespace
}  // namespace rephoto::demo
