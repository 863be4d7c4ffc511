// CSV (RFC 4180) writing and reading for rephoto's tables (per_image.csv, ...).
//
// Fields are separated by ',' and rows end with '\n'. A field is quoted ("...") when it holds a
// comma, a double quote, a line break, or leading/trailing spaces; quotes inside are doubled.
// Numbers are written with the shortest text that reads back to the same double; NaN (not
// evaluated) is written as an empty field, infinities as "inf" / "-inf".
//
// Thread safety: the free functions are reentrant; a CsvWriter is a plain value, one writer per
// thread.
#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace rephoto::io {

// `field` quoted if needed (see above).
std::string CsvField(std::string_view field);

// The shortest round-trip text of `value`; "" for NaN.
std::string CsvNumber(double value);

// Builds a CSV document row by row.
class CsvWriter {
 public:
  // Appends one row; fields are quoted as needed.
  void AddRow(std::span<const std::string> fields);
  void AddRow(std::initializer_list<std::string> fields) {
    AddRow(std::span<const std::string>(fields.begin(), fields.size()));
  }
  const std::string& text() const { return text_; }

 private:
  std::string text_;
};

// Parses a CSV document into rows of fields (quoted fields may hold commas, doubled quotes and
// line breaks; "\r\n" line ends are accepted). `name` is used in error messages, which name the
// line of an unterminated quote. A final line break does not start an empty row.
std::vector<std::vector<std::string>> ParseCsv(std::string_view text, const std::string& name);

// ParseCsv of the file at `path` (named in messages); throws Error naming it when it cannot be
// read.
std::vector<std::vector<std::string>> ReadCsvFile(const std::filesystem::path& path);

}  // namespace rephoto::io
