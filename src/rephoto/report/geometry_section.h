// The geometric part of a comparison report (paper Fig. 8), internal to report.cc: each run's
// geometric accuracy, completeness and F-score (geometry/run_geometry.h) as ranking-table
// cells, a scatterplot of the primary metric's median against the geometric accuracy, and the
// Pearson and Spearman correlations (geometry/correlation.h) with the number of runs.
//
// Thread safety: pure functions (HTML text from values).
#pragma once

#include <string>
#include <vector>

#include "rephoto/geometry/geometry.h"
#include "rephoto/geometry/run_geometry.h"

namespace rephoto::report::internal {

struct GeometryRun {
  std::string label;
  std::string series;
  double primary = 0;  // the run's median primary metric (NaN = none)
  geometry::RunGeometry geometry;
};

// <th> cells for the ranking table: accuracy, then completeness and F-score per tolerance.
std::string GeometryHeaderCells(const geometry::GeometryOptions& options);
// The matching <td> cells of one run (sortable data-v; "–" when unavailable, with the reason
// as a tooltip).
std::string GeometryRowCells(const geometry::RunGeometry& run,
                             const geometry::GeometryOptions& options);

// One correlation: the primary metric against one geometric measure over the runs that have
// both values.
struct GeometryCorrelation {
  std::string measure;  // "accuracy", "completeness@0.01", "f_score@0.01"
  double pearson = 0;   // NaN when undefined (fewer than 2 runs, or a constant series)
  double spearman = 0;
  size_t runs = 0;
};
std::vector<GeometryCorrelation> GeometryCorrelations(const std::vector<GeometryRun>& runs,
                                                      const geometry::GeometryOptions& options);

// <section id="geometry">: the reference, the scatterplot (primary vs. accuracy, one point per
// run with both values) and the correlation table (id "geometry-correlations", one row per
// measure, data-pearson/data-spearman/data-runs attributes).
std::string GeometrySectionHtml(const std::vector<GeometryRun>& runs, const std::string& reference,
                                const geometry::GeometryOptions& options,
                                const std::string& primary_metric);

}  // namespace rephoto::report::internal
