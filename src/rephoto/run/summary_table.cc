#include "rephoto/run/summary_table.h"

#include <fmt/format.h>

#include <cmath>

namespace rephoto::run {

std::string FormatTableValue(double value) {
  if (std::isnan(value)) return "-";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  return fmt::format("{:.4f}", value);
}

std::string FormatSummaryTable(std::string_view unit, std::string_view mean,
                               const std::vector<SummaryRow>& rows) {
  std::string text =
      fmt::format("{:<14} {:>10} {:>10} {:>10} {:>10} {:>10}\n", unit, mean, "min", "median",
                  "max", "pooled");
  for (const SummaryRow& row : rows) {
    const Summary& s = row.summary;
    text += fmt::format("{:<14} {:>10} {:>10} {:>10} {:>10} {:>10}\n", row.name,
                        FormatTableValue(s.mean), FormatTableValue(s.min),
                        FormatTableValue(s.median), FormatTableValue(s.max),
                        row.show_pooled ? FormatTableValue(row.pooled) : "");
  }
  return text;
}

}  // namespace rephoto::run
