// The one rule by which a run folder's tables (per_image.csv, per_fold.csv; their columns:
// docs/run-folder.md) are read, by C++ (run_data.h LoadRun, the benchmark service's scores and
// API) and by Python (rephoto.load_run calls ReadRunTable through the bindings).
//
// Every column has a kind, decided by its name alone (KindOfColumn):
//   text     fold, name, status, photo, render, message, and any column this version does not
//            know (kept as written, so a newer file still reads)
//   integer  width, height, resized, test_images, evaluated_images, valid_photo_windows,
//            valid_both_windows, <metric>_evaluated: an empty field is 0 (nothing measured)
//   number   completeness, seconds, the metric names (metrics::ParseMetric) and evaluate
//            --compat's <preset>_<metric> (metrics::ParseCompatPreset, "3dgs_psnr"): an empty
//            field is NaN (not evaluated), "inf" / "+inf" / "-inf" are infinities
// A field of an integer or number column that is not such a value is an Error naming the file,
// the line and the column; so is a row with more fields than the header. A row with fewer
// fields reads the missing ones as empty.
//
// Thread safety: reentrant (reads its file only); a RunTable is a plain value.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace rephoto::run {

enum class ColumnKind { kText, kInteger, kNumber };

ColumnKind KindOfColumn(std::string_view column);

// One field, typed by its column's kind: std::string (text), int64_t (integer), double (number).
using Cell = std::variant<std::string, int64_t, double>;

struct RunTable {
  std::filesystem::path file;        // for messages
  std::vector<std::string> columns;  // header, in file order
  std::vector<std::vector<Cell>> rows;  // each of columns.size() cells

  // Index of `column`, or -1.
  int Find(std::string_view column) const;
  // Index of `column`; Error naming the file when there is no such column.
  int Column(std::string_view column) const;
  // The typed value of row `row`, column index `column` (must be of that kind).
  const std::string& Text(size_t row, int column) const;
  int64_t Integer(size_t row, int column) const;
  double Number(size_t row, int column) const;
};

// Parses `text` (a CSV document, io/csv.h) by the rule above; `file` names it in messages.
// Error for a document without a header line.
RunTable ParseRunTable(std::string_view text, const std::filesystem::path& file);

// Reads and parses `file`. Error when it cannot be read.
RunTable ReadRunTable(const std::filesystem::path& file);

}  // namespace rephoto::run
