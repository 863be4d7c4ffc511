// Reading a run folder (its contract: docs/run-folder.md). Used by `rephoto report` and the
// benchmark's pages.
//
// Thread safety: LoadRun is reentrant; a RunData is a value.
//
// Reading a run directory (the `rephoto evaluate` or `rephoto compare` layout, see
// docs/run-folder.md and compare/compare.h) into memory for the reports.
//
// Both layouts have per_image.csv and summary.json; an evaluate run (per_image.csv starts with
// a "fold" column, or summary.json has schema "rephoto.evaluate/...") also has per_fold.csv and
// run.json, and its images' outputs live in folds/<fold>/. Metric columns are the per_image.csv
// columns whose name is a metric name (metrics::ParseMetric), in file order.
//
// Thread safety: reentrant (reads files only; RunData is a plain value type).
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "rephoto/core/stats.h"
#include "rephoto/run/run_table.h"

namespace rephoto::run {

enum class RunLayout { kCompare, kEvaluate };

struct ImageRow {
  std::string fold;    // evaluate: the "fold" column as written (e.g. "fold_00"); compare: ""
  std::string name;    // image name (file stem, may contain '/')
  std::string status;  // "ok", "missing_render", "missing_photo", "failed", ...
  std::string photo;   // paths as written in per_image.csv (may be empty)
  std::string render;
  int width = 0;  // 0 when not compared
  int height = 0;
  double completeness = 0;      // NaN when not compared
  std::vector<double> metrics;  // per RunData::metrics; NaN = not evaluated
};

struct FoldRow {
  std::string fold;    // as in per_fold.csv
  std::string status;  // "ok" | "failed"
  int test_images = 0;
  int evaluated_images = 0;
  double seconds = 0;
  double completeness = 0;      // NaN when nothing was evaluated
  std::vector<double> metrics;  // per RunData::metrics; NaN = none
  std::string message;          // why the fold failed (optional "message" column)
};

struct FailedFold {
  std::string fold;
  std::string message;
};

struct RunData {
  RunLayout layout = RunLayout::kCompare;
  std::filesystem::path dir;
  nlohmann::ordered_json summary;        // summary.json (null when absent)
  nlohmann::ordered_json run;            // run.json (null when absent or a compare run)
  std::vector<std::string> metrics;      // metric names, per_image.csv column order
  std::vector<ImageRow> images;          // per_image.csv order
  std::vector<FoldRow> folds;            // per_fold.csv order (empty for compare runs)
  std::vector<FailedFold> failed_folds;  // from summary.json, else per_fold.csv status/message
  std::vector<std::string> missing;      // one line per missing/failed image or entry
  // per_image.csv and per_fold.csv with every column, typed by run_table.h's rule (what
  // Python's rephoto.load_run returns); fold_table is empty for compare runs.
  RunTable image_table, fold_table;

  // Index of `metric` in `metrics`, or -1.
  int MetricIndex(const std::string& metric) const;
  // True when boxplots and the main summary are across folds: an evaluate run with more than
  // one fold. Otherwise they are over images.
  bool AcrossFolds() const { return layout == RunLayout::kEvaluate && folds.size() > 1; }
  // "folds" or "images" (the unit of Values()).
  const char* Unit() const { return AcrossFolds() ? "folds" : "images"; }
  // The values one box summarises: metric index m (or -1 = completeness) of each ok fold when
  // AcrossFolds(), else of each image with status "ok". NaN entries are kept (Summarize
  // ignores them).
  std::vector<double> Values(int metric) const;
  std::vector<double> ImageValues(int metric) const;  // always over ok images
  std::vector<double> FoldValues(int metric) const;   // over ok folds
  // Where an image's outputs are: RUN for compare runs, RUN/folds/<fold dir> for evaluate runs
  // (a fold written as a number n means "fold_%02d").
  std::filesystem::path ImageDir(const ImageRow& image) const;
  // Besides RUN, the folders whose photos and renderings RenderPath and PhotoPath may return:
  // the folders the user named (evaluate's image root, `rephoto report --image-folders`). A
  // path read from the run's files that leads anywhere else is not followed (hostile files).
  std::vector<std::filesystem::path> image_folders;
  // `path` when it lies inside RUN or one of image_folders (symbolic links and ".." resolved),
  // else empty.
  std::filesystem::path Readable(const std::filesystem::path& path) const;
  // The rendering of an image as a readable path: absolute as written, else relative to the
  // image's folder, RUN, RUN's parent (`rephoto compare --photos photos --out run` run from
  // that folder) or the current directory (the first that exists), and Readable; empty if
  // none.
  std::filesystem::path RenderPath(const ImageRow& image) const;
  // The photo likewise; evaluate runs name each photo by its scene name (view_000.png): that
  // name's file is the one run.json's inputs.photos lists for it (where evaluate read it).
  std::filesystem::path PhotoPath(const ImageRow& image) const;
};

// Reads `dir`. Throws Error naming the file (and line/column) when per_image.csv is missing
// or malformed, per_fold.csv of an evaluate run is missing or malformed, or a JSON file is not
// valid JSON. run.json is optional.
RunData LoadRun(const std::filesystem::path& dir);

}  // namespace rephoto::run
