// The combined tables of a sweep, built from the evaluate run directory of each setting
// (the per_fold.csv of the run-directory layout in eval/evaluate.h).
//
//   sweep_per_fold.csv  one row per (setting, fold): setting, one column per swept parameter,
//                       fold, status, completeness, then each metric (the fold's mean).
//   sweep.csv           one row per setting: setting, the parameters, folds (evaluated),
//                       failed_folds, then for completeness and each metric X the statistics
//                       across the setting's evaluated folds: X_median, X_q1, X_q3, X_min,
//                       X_max, X_mean (core/stats.h Summarize; empty when no fold evaluated),
//                       and, when the sweep has a geometric reference, the setting's
//                       geometry::RunGeometryColumns (geo_accuracy, geo_completeness@t, ...:
//                       geometry/run_geometry.h; empty when the run has no model).
// Rows follow the order of the settings; metric columns the order of the first run that has
// them. A setting whose run directory has no per_fold.csv (not run yet, or failed before any
// fold finished) gives a row with folds = 0 and empty statistics.
//
// Thread safety: reentrant (reads the run folders; SweepSummaryCsv and SweepPerFoldCsv are pure).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/core/stats.h"
#include "rephoto/sweep/grid.h"

namespace rephoto::sweep {

struct FoldRow {
  std::string fold;
  std::string status;          // "ok" or "failed"
  std::vector<double> values;  // completeness then metrics (SweepTable::columns order), NaN = none
};

struct SettingRows {
  SweepSetting setting;
  std::vector<FoldRow> folds;
  std::vector<Summary> across_folds;  // per column, over the folds with status "ok"
  size_t failed_folds = 0;
  std::vector<double> geometry;  // per SweepTable::geometry_columns (NaN = none)
};

struct SweepTable {
  std::vector<std::string> columns;  // "completeness", then metric names
  std::vector<SettingRows> settings;
  std::vector<std::string> geometry_columns;  // empty without a geometric reference
};

// Reads the per_fold.csv of each setting's run directory (run_dirs[i] for settings[i]).
// Throws Error naming the file when a per_fold.csv exists but is malformed.
SweepTable ReadSweepTable(const std::vector<SweepSetting>& settings,
                          const std::vector<std::filesystem::path>& run_dirs);

// The two CSV documents described above.
std::string SweepPerFoldCsv(const SweepTable& table, const std::vector<SweepAxis>& axes);
std::string SweepSummaryCsv(const SweepTable& table, const std::vector<SweepAxis>& axes);

}  // namespace rephoto::sweep
