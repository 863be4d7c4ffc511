// The summary table `rephoto compare` and `rephoto evaluate` print on standard output: one row
// for completeness and one per metric, with the summary's mean, min, median and max and the
// pooled value (4 decimals; "-" for NaN, "inf"/"-inf"), columns 14 + 5 x 11 characters wide.
// The files (summary.json, per_image.csv) are the results; this is for a person at a terminal.
//
// Thread safety: pure functions.
#pragma once

#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/core/stats.h"

namespace rephoto::run {

struct SummaryRow {
  std::string name;  // "completeness", or a metric name
  Summary summary;
  double pooled = std::numeric_limits<double>::quiet_NaN();
  bool show_pooled = true;  // false: the pooled column stays empty (completeness)
};

// A number of the table: "0.1234", "-" for NaN, "inf"/"-inf".
std::string FormatTableValue(double value);

// `unit` heads the first column ("over images", ""), `mean` the mean column ("mean",
// "fold mean"). Each line ends with '\n'.
std::string FormatSummaryTable(std::string_view unit, std::string_view mean,
                               const std::vector<SummaryRow>& rows);

}  // namespace rephoto::run
