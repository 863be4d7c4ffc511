// rephoto report RUN_DIR [RUN_DIR ...] --out report.html [--labels a,b,...] [--title T]
//                [--metric M] [--examples N] [--thumbnail-width PX] [--keep-order]
//                [--reference GT [--tolerances T,...] [--accuracy-fraction F]
//                 [--geometry-samples N]]
// One run directory: report::WriteRunReport (a single --labels entry becomes the title when
// --title is not given); several: report::WriteCollectionReport (ranking table, boxplots per
// run, best/worst images of each). See src/rephoto/report/report.h.
// --reference (several runs): each run's model(s) against a ground-truth surface, the primary
// metric vs. geometric accuracy and their correlations (paper Fig. 8; report.h
// CollectionOptions::geometry_reference).
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/geometry/geometry.h"
#include "rephoto/report/report.h"

namespace rephoto::cli {
namespace {

struct ReportArguments {
  std::vector<std::string> runs;
  std::string out;
  std::vector<std::string> labels;
  std::string title;
  std::string metric = "1-ncc";
  int examples = -1;         // -1: the default of the report type
  int thumbnail_width = -1;  // -1: the default of the report type
  bool keep_order = false;
  std::string csv;
  double completeness_margin = report::CollectionOptions{}.completeness_margin;
  std::string reference;
  geometry::GeometryOptions geometry;
  std::vector<std::filesystem::path> image_folders;
};

CommandRunner SetupReport(CLI::App& app) {
  auto args = std::make_shared<ReportArguments>();
  app.add_option("runs", args->runs,
                 "Run directories (`rephoto evaluate` or `rephoto compare` outputs); several "
                 "give one comparison report")
      ->required()
      ->check(CLI::ExistingDirectory);
  app.add_option("--out", args->out, "The HTML file to write")->required();
  app.add_option("--labels", args->labels,
                 "Comma-separated labels of the runs (default: the directory names)")
      ->delimiter(',');
  app.add_option("--title", args->title, "Title of the report");
  app.add_option("--metric", args->metric,
                 "Primary metric: ranks the runs and picks the worst/best images")
      ->capture_default_str();
  app.add_option("--examples", args->examples,
                 "Worst and best images shown (each; default 3 for one run, 1 per run for "
                 "several)")
      ->check(CLI::Range(0, 100));
  app.add_option("--thumbnail-width", args->thumbnail_width,
                 "Maximum width of the embedded images in pixels (default 480 / 320)")
      ->check(CLI::Range(16, 4096));
  app.add_option("--csv", args->csv,
                 "Several runs: also write the ranking table as CSV (medians, notes)");
  app.add_option("--completeness-margin", args->completeness_margin,
                 "Several runs: mark runs whose median completeness is more than this below the "
                 "most complete run's (accuracy alone does not compare them)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--reference", args->reference,
                 "Several runs: ground-truth surface (mesh or point cloud); adds each run's "
                 "geometric accuracy, completeness and F-score, a scatterplot of the primary "
                 "metric vs. accuracy and their Pearson/Spearman correlations");
  app.add_option("--tolerances", args->geometry.tolerances,
                 "With --reference: distance thresholds (reference units, comma-separated)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--accuracy-fraction", args->geometry.accuracy_fraction,
                 "With --reference: accuracy is the distance within which this fraction of the "
                 "model lies")
      ->capture_default_str();
  app.add_option("--geometry-samples", args->geometry.samples,
                 "With --reference: area-uniform samples per surface")
      ->capture_default_str();
  app.add_option("--image-folders", args->image_folders,
                 "Folders outside the run directories whose photos and renderings the report may "
                 "show (the photos' folder); paths in the runs' files leading anywhere else are "
                 "not followed")
      ->delimiter(',')
      ->check(CLI::ExistingDirectory);
  app.add_flag("--keep-order", args->keep_order,
               "Several runs: keep the given order instead of ranking by the primary metric");

  return [args] {
    if (!args->labels.empty() && args->labels.size() != args->runs.size()) {
      throw UsageError(fmt::format("--labels: {} labels for {} run directories",
                                   args->labels.size(), args->runs.size()));
    }
    if (!args->reference.empty()) {
      REPHOTO_CHECK_USAGE(args->runs.size() >= 2,
                          "--reference: the geometric comparison needs two or more runs (for one "
                          "model: rephoto geometry MODEL --reference {})",
                          args->reference);
      REPHOTO_CHECK_USAGE(std::filesystem::is_regular_file(args->reference),
                          "--reference {}: no such file", args->reference);
      args->geometry.Check();
    }
    if (args->runs.size() == 1) {
      report::ReportOptions options;
      options.title = args->title;
      options.primary_metric = args->metric;
      if (args->examples >= 0) options.example_images = args->examples;
      if (args->thumbnail_width > 0) options.thumbnail_width = args->thumbnail_width;
      if (options.title.empty() && !args->labels.empty()) options.title = args->labels[0];
      options.image_folders = args->image_folders;
      report::WriteRunReport(args->runs[0], args->out, options);
    } else {
      std::vector<report::CollectionEntry> entries;
      for (size_t i = 0; i < args->runs.size(); ++i) {
        report::CollectionEntry entry;
        entry.run_dir = args->runs[i];
        if (!args->labels.empty()) entry.label = args->labels[i];
        entries.push_back(std::move(entry));
      }
      report::CollectionOptions options;
      options.title = args->title;
      options.primary_metric = args->metric;
      options.rank = !args->keep_order;
      options.ranking_csv = args->csv;
      options.completeness_margin = args->completeness_margin;
      options.geometry_reference = args->reference;
      options.geometry_options = args->geometry;
      options.image_folders = args->image_folders;
      if (args->examples >= 0) options.example_images = args->examples;
      if (args->thumbnail_width > 0) options.thumbnail_width = args->thumbnail_width;
      report::WriteCollectionReport(entries, args->out, options);
    }
    fmt::print("Report written to {}\n", args->out);
    return static_cast<int>(ExitCode::kOk);
  };
}

REPHOTO_COMMAND(90, "report",
                "Write a self-contained HTML report (tables, boxplots, worst/best images) of one "
                "run directory, or a comparison of several",
                SetupReport);

}  // namespace
}  // namespace rephoto::cli
