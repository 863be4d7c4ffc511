#include "rephoto/run/run_table.h"

#include <cmath>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/csv.h"
#include "rephoto/metrics/compat.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/run/records.h"

namespace rephoto::run {
namespace fs = std::filesystem;

ColumnKind KindOfColumn(std::string_view column) {
  static constexpr std::string_view kIntegers[] = {
      "width",          "height",           "resized",
      "test_images",    "evaluated_images", "valid_photo_windows",
      "valid_both_windows"};
  for (std::string_view name : kIntegers) {
    if (column == name) return ColumnKind::kInteger;
  }
  if (column == "completeness" || column == "seconds") return ColumnKind::kNumber;
  if (metrics::ParseMetric(column)) return ColumnKind::kNumber;
  // evaluate --compat: "<preset>_<metric>" ("3dgs_psnr", "nerfstudio_ssim").
  const size_t underscore = column.find('_');
  if (underscore != std::string_view::npos &&
      metrics::ParseCompatPreset(column.substr(0, underscore)) &&
      metrics::ParseMetric(column.substr(underscore + 1))) {
    return ColumnKind::kNumber;
  }
  constexpr std::string_view kEvaluated = "_evaluated";
  if (column.size() > kEvaluated.size() &&
      column.substr(column.size() - kEvaluated.size()) == kEvaluated &&
      metrics::ParseMetric(column.substr(0, column.size() - kEvaluated.size()))) {
    return ColumnKind::kInteger;
  }
  return ColumnKind::kText;
}

int RunTable::Find(std::string_view column) const {
  for (size_t i = 0; i < columns.size(); ++i) {
    if (columns[i] == column) return static_cast<int>(i);
  }
  return -1;
}

int RunTable::Column(std::string_view column) const {
  const int index = Find(column);
  REPHOTO_CHECK(index >= 0, "{}: no column \"{}\"", file.string(), column);
  return index;
}

const std::string& RunTable::Text(size_t row, int column) const {
  return std::get<std::string>(rows.at(row).at(column));
}
int64_t RunTable::Integer(size_t row, int column) const {
  return std::get<int64_t>(rows.at(row).at(column));
}
double RunTable::Number(size_t row, int column) const {
  return std::get<double>(rows.at(row).at(column));
}

RunTable ParseRunTable(std::string_view text, const fs::path& file) {
  std::vector<std::vector<std::string>> fields = io::ParseCsv(text, file.string());
  REPHOTO_CHECK(!fields.empty(), "{}: empty file (no header line)", file.string());
  RunTable table;
  table.file = file;
  table.columns = std::move(fields[0]);
  std::vector<ColumnKind> kinds;
  for (const std::string& column : table.columns) kinds.push_back(KindOfColumn(column));
  const size_t width = table.columns.size();
  table.rows.reserve(fields.size() - 1);
  for (size_t r = 1; r < fields.size(); ++r) {
    std::vector<std::string>& in = fields[r];
    REPHOTO_CHECK(in.size() <= width, "{}: line {}: {} fields, the header has {}", file.string(),
                  r + 1, in.size(), width);
    std::vector<Cell> row;
    row.reserve(width);
    for (size_t c = 0; c < width; ++c) {
      std::string field = c < in.size() ? std::move(in[c]) : std::string();
      switch (kinds[c]) {
        case ColumnKind::kText:
          row.emplace_back(std::move(field));
          break;
        case ColumnKind::kNumber: {
          const std::optional<double> value = ParseCsvNumber(field);
          REPHOTO_CHECK(value.has_value(), "{}: line {}: column \"{}\": \"{}\" is not a number",
                        file.string(), r + 1, table.columns[c], field);
          row.emplace_back(*value);
          break;
        }
        case ColumnKind::kInteger: {
          const std::optional<double> value = ParseCsvNumber(field);
          const bool ok = value.has_value() &&
                          (std::isnan(*value) ||
                           (*value == std::floor(*value) && std::abs(*value) < 9e15));
          REPHOTO_CHECK(ok, "{}: line {}: column \"{}\": \"{}\" is not an integer",
                        file.string(), r + 1, table.columns[c], field);
          row.emplace_back(std::isnan(*value) ? int64_t{0} : static_cast<int64_t>(*value));
          break;
        }
      }
    }
    table.rows.push_back(std::move(row));
  }
  return table;
}

RunTable ReadRunTable(const fs::path& file) {
  return ParseRunTable(ReadFileToString(file), file);
}

}  // namespace rephoto::run
