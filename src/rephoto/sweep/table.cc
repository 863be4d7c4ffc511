#include "rephoto/sweep/table.h"

#include <algorithm>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/io/csv.h"
#include "rephoto/run/run_table.h"

namespace rephoto::sweep {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

SweepTable ReadSweepTable(const std::vector<SweepSetting>& settings,
                          const std::vector<std::filesystem::path>& run_dirs) {
  REPHOTO_CHECK(settings.size() == run_dirs.size(), "sweep: {} settings but {} run directories",
                settings.size(), run_dirs.size());
  SweepTable table;
  table.columns = {"completeness"};
  for (size_t s = 0; s < settings.size(); ++s) {
    SettingRows rows;
    rows.setting = settings[s];
    const auto path = run_dirs[s] / "per_fold.csv";
    if (std::filesystem::exists(path)) {
      // per_fold.csv by the run folder's one reading rule (run/run_table.h); the measurements
      // are its number columns (completeness and the metrics).
      const run::RunTable csv = run::ReadRunTable(path);
      const int fold_column = csv.Find("fold"), status_column = csv.Find("status");
      REPHOTO_CHECK(fold_column >= 0 && status_column >= 0 && csv.Find("completeness") >= 0,
                    "{}: missing the fold, status or completeness column", path.string());
      for (const auto& name : csv.columns) {
        if (run::KindOfColumn(name) == run::ColumnKind::kNumber && name != "seconds" &&
            std::find(table.columns.begin(), table.columns.end(), name) == table.columns.end()) {
          table.columns.push_back(name);
        }
      }
      for (size_t r = 0; r < csv.rows.size(); ++r) {
        FoldRow row{.fold = csv.Text(r, fold_column),
                    .status = csv.Text(r, status_column),
                    .values = {}};
        for (const auto& column : table.columns) {
          const int c = csv.Find(column);
          row.values.push_back(c < 0 ? kNaN : csv.Number(r, c));
        }
        rows.folds.push_back(std::move(row));
      }
    }
    table.settings.push_back(std::move(rows));
  }
  // Summaries once every column is known (earlier rows get NaN for later-found columns).
  for (auto& rows : table.settings) {
    rows.failed_folds = 0;
    rows.across_folds.clear();
    for (auto& fold : rows.folds) fold.values.resize(table.columns.size(), kNaN);
    for (size_t c = 0; c < table.columns.size(); ++c) {
      std::vector<double> values;
      for (const auto& fold : rows.folds) {
        if (fold.status == "ok") values.push_back(fold.values[c]);
      }
      rows.across_folds.push_back(Summarize(values));
    }
    for (const auto& fold : rows.folds) rows.failed_folds += fold.status != "ok";
  }
  return table;
}

std::string SweepPerFoldCsv(const SweepTable& table, const std::vector<SweepAxis>& axes) {
  io::CsvWriter csv;
  std::vector<std::string> header = {"setting"};
  for (const auto& axis : axes) header.push_back(axis.parameter);
  header.insert(header.end(), {"fold", "status"});
  header.insert(header.end(), table.columns.begin(), table.columns.end());
  csv.AddRow(header);
  for (const auto& rows : table.settings) {
    for (const auto& fold : rows.folds) {
      std::vector<std::string> fields = {rows.setting.name};
      for (const auto& axis : axes) {
        fields.push_back(io::CsvNumber(rows.setting.Value(axis.parameter)));
      }
      fields.push_back(fold.fold);
      fields.push_back(fold.status);
      for (double v : fold.values) fields.push_back(io::CsvNumber(v));
      csv.AddRow(fields);
    }
  }
  return csv.text();
}

std::string SweepSummaryCsv(const SweepTable& table, const std::vector<SweepAxis>& axes) {
  io::CsvWriter csv;
  std::vector<std::string> header = {"setting"};
  for (const auto& axis : axes) header.push_back(axis.parameter);
  header.insert(header.end(), {"folds", "failed_folds"});
  for (const auto& column : table.columns) {
    for (const char* stat : {"median", "q1", "q3", "min", "max", "mean"}) {
      header.push_back(column + "_" + stat);
    }
  }
  header.insert(header.end(), table.geometry_columns.begin(), table.geometry_columns.end());
  csv.AddRow(header);
  for (const auto& rows : table.settings) {
    std::vector<std::string> fields = {rows.setting.name};
    for (const auto& axis : axes)
      fields.push_back(io::CsvNumber(rows.setting.Value(axis.parameter)));
    const size_t evaluated = rows.across_folds.empty() ? 0 : rows.across_folds[0].count;
    fields.push_back(std::to_string(evaluated));
    fields.push_back(std::to_string(rows.failed_folds));
    for (size_t c = 0; c < table.columns.size(); ++c) {
      const Summary& s = c < rows.across_folds.size() ? rows.across_folds[c] : Summary{};
      const bool any = s.count > 0;
      for (double v : {s.median, s.q1, s.q3, s.min, s.max, s.mean}) {
        fields.push_back(any ? io::CsvNumber(v) : "");
      }
    }
    for (size_t c = 0; c < table.geometry_columns.size(); ++c) {
      fields.push_back(c < rows.geometry.size() ? io::CsvNumber(rows.geometry[c]) : "");
    }
    csv.AddRow(fields);
  }
  return csv.text();
}

}  // namespace rephoto::sweep
