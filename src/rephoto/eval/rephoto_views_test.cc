// The view stage's pipeline (rephoto_views.h): the same files as one view at a time, and error
// images of some metrics only.
#include "rephoto/eval/rephoto_views.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "rephoto/core/file.h"
#include "rephoto/core/parallel.h"
#include "rephoto/eval/evaluate.h"
#include "rephoto/eval/evaluate_fixture.h"
#include "rephoto/testing/testing.h"

namespace rephoto::eval {
namespace {

namespace fs = std::filesystem;

// issue 18: the views go through a pipeline (render the next, compare this one, write the
// previous one's error images in the background). With one thread there is no pipeline; both
// orders give the same renderings, error images and tables, byte for byte, and run.json
// separates the steps' summed seconds from the view stage's wall time.
TEST(RephotoViewsTest, PipelinedViewsWriteTheFilesOfOneViewAtATime) {
  const fs::path root = testing::MakeTempDir();
  EvaluateOptions o = EvaluateTestOptions(root / "pipelined");
  o.model = EvaluateTestScene().truth;
  o.scheme = "kfold:2";
  o.metrics = {metrics::Metric::kOneMinusNcc, metrics::Metric::kCbCr, metrics::Metric::kDssim};
  o.error_image_metrics = metrics::AllMetrics();  // every file the view stage can write
  o.depth_images = true;
  o.report = false;
  const EvaluateResult pipelined = RunEvaluate(o);
  EvaluateOptions sequential = o;
  sequential.out = root / "sequential";
  {
    ThreadLimit one(1);
    RunEvaluate(sequential);
  }
  EXPECT_EQ(pipelined.evaluated_images, static_cast<size_t>(kTestViews));
  size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(o.out / "folds")) {
    const std::string folder = entry.path().parent_path().filename().string();
    if (!entry.is_regular_file() || (folder != "errors" && folder != "renders")) continue;
    const fs::path other = sequential.out / fs::relative(entry.path(), o.out);
    EXPECT_EQ(ReadFileToString(entry.path()), ReadFileToString(other)) << entry.path();
    ++files;
  }
  // Per view: a rendering and its depth, and an EXR and a PNG per metric.
  EXPECT_EQ(files, kTestViews * (2 + 2 * o.metrics.size()));
  for (const char* table : {"per_image.csv", "per_fold.csv"}) {
    EXPECT_EQ(ReadFileToString(o.out / table), ReadFileToString(sequential.out / table)) << table;
  }
  const nlohmann::json timings =
      nlohmann::json::parse(ReadFileToString(o.out / "run.json"))["timings"];
  for (const char* step : {"render", "photos", "compare", "write", "views"}) {
    EXPECT_GT(timings["rephoto"][step].get<double>(), 0.0) << step;
  }
  EXPECT_GT(pipelined.timings.write, 0.0);

  // Error images of some metrics only (and of the projection metric, which the projection
  // reads): the same files as before for those, none for the others, the same tables.
  EvaluateOptions some = o;
  some.out = root / "some";
  some.error_image_metrics = {metrics::Metric::kCbCr};
  some.projection_metric = "1-ncc";
  EXPECT_EQ(ErrorImageMetrics(some),
            (std::vector<metrics::Metric>{metrics::Metric::kOneMinusNcc, metrics::Metric::kCbCr}));
  RunEvaluate(some);
  size_t error_files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(some.out / "folds")) {
    if (!entry.is_regular_file() || entry.path().parent_path().filename() != "errors") continue;
    EXPECT_EQ(ReadFileToString(entry.path()),
              ReadFileToString(o.out / fs::relative(entry.path(), some.out)))
        << entry.path();
    ++error_files;
  }
  EXPECT_EQ(error_files, static_cast<size_t>(kTestViews) * 2 * 2);  // cb+cr and 1-ncc, EXR and PNG
  EXPECT_EQ(ReadFileToString(some.out / "per_image.csv"),
            ReadFileToString(o.out / "per_image.csv"));
  EvaluateOptions bad = o;
  bad.metrics = {metrics::Metric::kOneMinusNcc};
  bad.error_image_metrics = {metrics::Metric::kDssim};
  EXPECT_THROW(RunEvaluate(bad), UsageError);
  fs::remove_all(root);
}

TEST(RephotoViewsTest, ByDefaultOnlyTheHeadlineAndProjectionMetricsImagesAndReadDepthsAreWritten) {
  using metrics::Metric;
  EvaluateOptions o;
  o.metrics = {Metric::kCbCr, Metric::kDssim, Metric::kOneMinusNcc};
  o.projection_metric = "dssim";
  EXPECT_EQ(ErrorImageMetrics(o), (std::vector<Metric>{Metric::kDssim, Metric::kOneMinusNcc}));
  o.metrics = {Metric::kCbCr, Metric::kDssim};  // no 1-NCC: the first metric is the headline
  o.projection_metric = "none";
  EXPECT_EQ(ErrorImageMetrics(o), (std::vector<Metric>{Metric::kCbCr}));
  o.error_image_metrics = metrics::AllMetrics();
  EXPECT_TRUE(ErrorImageMetrics(o).empty());  // all, as compare::CompareOptions reads it
  EXPECT_EQ(WrittenErrorImageMetrics(o), o.metrics);
  o.error_images = false;
  EXPECT_TRUE(WrittenErrorImageMetrics(o).empty());

  // Depth maps: where the projection reads them (the model itself, projected), or when asked.
  EvaluateOptions d;
  EXPECT_TRUE(WritesDepthImages(d, /*gaussians=*/false));
  EXPECT_FALSE(WritesDepthImages(d, /*gaussians=*/true));
  d.projection_metric = "none";
  EXPECT_FALSE(WritesDepthImages(d, false));
  d.depth_images = true;
  EXPECT_TRUE(WritesDepthImages(d, true));
  EvaluateOptions vdt;
  vdt.representation = render::ViewRepresentation::kVdt;
  EXPECT_FALSE(WritesDepthImages(vdt, false));
}

}  // namespace
}  // namespace rephoto::eval
