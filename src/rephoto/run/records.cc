#include "rephoto/run/records.h"

#include <charconv>
#include <cmath>
#include <exception>
#include <limits>

#include "rephoto/core/file.h"

namespace rephoto::run {
namespace fs = std::filesystem;

Json JsonNumber(double value) {
  if (std::isnan(value)) return nullptr;
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  return value;
}

double NumberFromJson(const Json& value) {
  if (value.is_number()) return value.get<double>();
  if (value.is_string()) {
    const std::string& s = value.get_ref<const std::string&>();
    if (s == "inf" || s == "+inf") return std::numeric_limits<double>::infinity();
    if (s == "-inf") return -std::numeric_limits<double>::infinity();
  }
  return std::numeric_limits<double>::quiet_NaN();
}

std::optional<double> ParseCsvNumber(std::string_view field) {
  if (field.empty()) return std::numeric_limits<double>::quiet_NaN();
  if (field == "inf" || field == "+inf") return std::numeric_limits<double>::infinity();
  if (field == "-inf") return -std::numeric_limits<double>::infinity();
  double value = 0;
  const char* end = field.data() + field.size();
  const auto [ptr, ec] = std::from_chars(field.data(), end, value);
  if (ec != std::errc() || ptr != end) return std::nullopt;
  return value;
}

Json SummaryJson(const Summary& s, std::string_view count_key) {
  Json j;
  j["mean"] = JsonNumber(s.mean);
  j["min"] = JsonNumber(s.min);
  j["q1"] = JsonNumber(s.q1);
  j["median"] = JsonNumber(s.median);
  j["q3"] = JsonNumber(s.q3);
  j["max"] = JsonNumber(s.max);
  j[std::string(count_key)] = s.count;
  return j;
}

std::optional<Json> ReadJsonRecord(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return std::nullopt;
  try {
    return Json::parse(ReadFileToString(path));
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

void WriteJsonRecord(const fs::path& path, const Json& json) {
  WriteTextFileAtomically(path, json.dump(2) + "\n");
}

}  // namespace rephoto::run
