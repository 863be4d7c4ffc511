// report.html: one self-contained HTML file per run or per collection of runs.
//
// The file has inline CSS and JavaScript, images as base64 data URIs and plots as inline SVG;
// it loads nothing from the network and opens offline in any browser. All text taken from the
// run's files (names, paths, messages, settings) is HTML-escaped.
//
// Run report (WriteRunReport), for one run directory of `rephoto evaluate` or `rephoto compare`
// (layouts: run_data.h):
//   - header: title, run directory, layout, tool version and the run's settings (run.json
//     "settings"/"config", summary.json "parameters" and top-level facts, flattened to a
//     key/value table);
//   - failed folds with their messages, missing or failed images;
//   - summary table: for completeness and each metric the mean, min, Q1, median, Q3, max and
//     count across folds (evaluate runs with several folds; from per_fold.csv) and over images
//     (from per_image.csv, images with status ok), statistics as core/stats.h Summarize; every
//     metric row carries the mean completeness of the same folds/images next to it;
//   - boxplots (SVG, boxplot.h): one per metric and one for completeness, across folds or over
//     images as above (dots show the single values when there are at most 40);
//   - the `example_images` worst and best images by the primary metric (psnr and ssim: higher
//     is better): photo, rephoto, mask (the rephoto's alpha) and jet error image side by side,
//     thumbnails at most `thumbnail_width` wide, with the colour bar and the range of the
//     error images (compare::ErrorColourRange);
//   - evaluate runs: the per-fold table (status, image counts, seconds, completeness, metrics,
//     message of a failed fold);
//   - the per-image table, sortable by clicking any column header (click again: descending;
//     empty values stay last); rows of missing or failed images show their status.
// Collection report (WriteCollectionReport), for several runs:
//   - a ranking table, one row per entry: label, series/setting (sweeps), count of
//     folds/images, the median of the primary metric with the median completeness next to it,
//     the median of each other metric, failed folds, missing images and the description (when
//     any entry has one); sorted by the median primary metric, best first (entries without a
//     value last) when `rank`; a note marks runs that are not comparable by accuracy alone
//     (completeness more than `completeness_margin` below the most complete run's, or not
//     cross-validated), and `ranking_csv` receives the same table;
//   - boxplots per metric and completeness: one box per entry, or for sweeps (entries with a
//     `setting`) one box per setting along x and per series, medians connected, like the
//     paper's Fig. 7; values are across folds for evaluate runs with several folds, else over
//     images;
//   - per entry, the `example_images` worst and best images (as above) and, collapsed, its
//     per-image table and settings.
// Sorting hook for tests and links: a URL fragment "#sort=<column>" (or "#sort=-<column>" for
// descending) clicks that column's header of the first table that has it after loading;
// <column> is the header's data-col (e.g. "name", "completeness", "1-ncc"). When the script
// has run, <body> gets data-ready="1"; an uncaught script error is recorded in
// <html data-js-error="...">. The page writes nothing to the console.
//
// Failure behaviour: a run directory that cannot be read (no per_image.csv, malformed CSV or
// JSON, evaluate run without per_fold.csv) throws rephoto::Error naming the file; unreadable
// photos, renderings or error images only replace that thumbnail by the reason. The HTML is
// written atomically (core/file.h); parent folders are created.
//
// Thread safety: reentrant (reads the run folders; writes only the files named: the report and,
// when asked, the ranking CSV, atomically); concurrent calls must write different files.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "rephoto/geometry/geometry.h"
#include "rephoto/report/view3d.h"

namespace rephoto::report {

struct ReportOptions {
  std::string title;                     // "" = "rephoto report: <run directory name>"
  std::string primary_metric = "1-ncc";  // ranks the example images; absent: the first metric
  int example_images = 3;                // that many worst and that many best images (0 = none)
  int thumbnail_width = 480;             // pixels; thumbnails are never enlarged
  // Folders outside the run folder whose photos, renderings and models may be shown (the ones
  // the user named: the photos' folder); paths in the run's files leading elsewhere are not
  // followed.
  std::vector<std::filesystem::path> image_folders;
  // The interactive 3D view (view3d.h, section "The error on the model") when the run has
  // projected/<primary metric>.ply: the model coloured by the error, the run's cameras (from
  // RUN/split), thumbnails of the evaluated photos `view3d_thumbnail_width` wide (0 = none).
  // A projected PLY that cannot be read replaces the view by the reason (the report is still
  // written).
  bool view3d = true;
  int view3d_thumbnail_width = 200;
  View3dLimits view3d_limits;
};

// One run directory (evaluate or compare layout) -> one self-contained HTML file.
void WriteRunReport(const std::filesystem::path& run_dir, const std::filesystem::path& out_html,
                    const ReportOptions& options = {});

struct CollectionEntry {
  std::string label;        // shown in tables and on the plots' x axis ("" = directory name)
  std::string description;  // one line, shown in the ranking table
  std::filesystem::path run_dir;
  std::string series;             // sweeps: one line/group per series, empty = none
  std::optional<double> setting;  // sweeps: x value; all entries or none must have one
};

struct CollectionOptions {
  std::string title;                     // "" = "rephoto comparison of N runs"
  std::string primary_metric = "1-ncc";  // must be a metric of at least one entry
  std::string setting_name;              // x-axis label for sweeps ("" = "setting")
  // Sort the ranking table by the median primary metric (across folds, or over images for
  // single-fold/compare runs), best first; false keeps the entries' order.
  bool rank = true;
  int example_images = 1;
  int thumbnail_width = 320;
  // Accuracy is meaningless without completeness (paper Section 4.2): a run whose median
  // completeness is more than this below the most complete run's is marked in the ranking
  // ("note" column and a warning sign) as not comparable by accuracy alone. Runs that are not
  // cross-validated (summary.json "cross_validated": false: a fixed model that may have seen
  // the test photos) are marked too when the collection also holds cross-validated runs (fixed
  // models alone compare fairly among themselves). In [0, 1].
  double completeness_margin = 0.05;
  // When set, the ranking table is also written as CSV (rank, label, n, primary median,
  // completeness median, the other metrics' medians, failed folds, missing, cross_validated,
  // note), for spreadsheets and scripts such as examples/experiments/table1.sh.
  std::filesystem::path ranking_csv;
  // Geometry beside appearance (paper Fig. 8): with a reference surface (mesh or point cloud),
  // each run's model(s) are evaluated against it (geometry/run_geometry.h: per-fold models
  // averaged, cached in RUN/geometry/<key>.json) with these options; the ranking table and
  // `ranking_csv` gain the geometric accuracy and, per tolerance, completeness and F-score
  // (the CSV also precision and recall: columns geometry::RunGeometryColumns), and a section
  // "geometry" shows the primary metric's median vs. the accuracy as a scatterplot
  // (scatterplot.h) with the Pearson and Spearman correlations and the number of runs.
  // Runs without a model (compare runs, image-based rendering) show no values and the reason.
  std::filesystem::path geometry_reference;
  geometry::GeometryOptions geometry_options;
  // Sections made elsewhere, after the runs, each <section id="`id`"><h2>`title`</h2>
  // <p>`note`</p> `body_html` </section> (note escaped, omitted when empty; body_html is trusted
  // HTML). The demo adds "Where to photograph next" (acquisition guidance, paper Sections 5.2
  // and 6.2) from suggest/suggest_page.h.
  struct Section {
    std::string id, title, note, body_html;
  };
  std::vector<Section> sections;
  // As ReportOptions::image_folders, for every run.
  std::vector<std::filesystem::path> image_folders;
  // The 3D view (as ReportOptions::view3d): one view with a selector over the runs that have
  // projected/<primary metric>.ply; the suggested views of the `rephoto suggest` folder
  // `suggestions` (suggestions.json + sparse/) are shown as highlighted frusta with every run.
  bool view3d = true;
  int view3d_thumbnail_width = 160;
  View3dLimits view3d_limits{.max_faces = 60000, .max_points = 100000};
  std::filesystem::path suggestions;
  // Side by side (section "side-by-side"): for each photo named here (per_image.csv names),
  // one row with its photo and each run's rephoto and error image (the primary metric's, same
  // colour range for all). Empty: the `side_by_side_count` photos evaluated by every run
  // whose primary metric differs most between the runs (max - min), where the methods
  // disagree. Thumbnails `side_by_side_width` wide.
  std::vector<std::string> side_by_side;
  int side_by_side_count = 3;
  int side_by_side_width = 200;
};

// Several runs (the demo's reconstructions; a sweep's settings) -> one HTML: ranking table,
// boxplots per entry (or vs setting per series), and the best/worst images of each entry.
// Throws Error for no entries, an unreadable run directory (naming it), entries of which only
// some have a setting, or a primary metric that no entry has.
void WriteCollectionReport(const std::vector<CollectionEntry>& entries,
                           const std::filesystem::path& out_html,
                           const CollectionOptions& options = {});

}  // namespace rephoto::report
