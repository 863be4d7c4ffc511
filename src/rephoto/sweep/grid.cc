#include "rephoto/sweep/grid.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/io/csv.h"

namespace rephoto::sweep {
namespace {

constexpr std::string_view kParameters[] = {"texture_noise", "geometry_noise", "simplify",
                                            "seed",          "train_count",    "train_short_side"};

bool IsIntegerParameter(std::string_view name) {
  return name == "seed" || name == "train_count" || name == "train_short_side";
}

}  // namespace

double SweepSetting::Value(std::string_view parameter) const {
  for (const auto& [name, value] : values) {
    if (name == parameter) return value;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

bool IsSweepParameter(std::string_view name) {
  return std::find(std::begin(kParameters), std::end(kParameters), name) != std::end(kParameters);
}

std::string SweepParameterList() {
  std::string list;
  for (auto name : kParameters) {
    if (!list.empty()) list += ", ";
    list += name;
  }
  return list;
}

void CheckAxes(const std::vector<SweepAxis>& axes, std::string_view context) {
  for (size_t a = 0; a < axes.size(); ++a) {
    const auto& axis = axes[a];
    REPHOTO_CHECK(IsSweepParameter(axis.parameter), "{}: unknown sweep parameter '{}' (known: {})",
                  context, axis.parameter, SweepParameterList());
    for (size_t b = 0; b < a; ++b) {
      REPHOTO_CHECK(axes[b].parameter != axis.parameter, "{}: sweep parameter '{}' given twice",
                    context, axis.parameter);
    }
    REPHOTO_CHECK(!axis.values.empty(), "{}: sweep parameter '{}' has no values", context,
                  axis.parameter);
    for (double v : axis.values) {
      REPHOTO_CHECK(std::isfinite(v) && v >= 0, "{}: {} value {} must be a number >= 0", context,
                    axis.parameter, v);
      if (axis.parameter == "simplify") {
        REPHOTO_CHECK(v < 1, "{}: simplify value {} must be below 1", context, v);
      }
      if (IsIntegerParameter(axis.parameter)) {
        REPHOTO_CHECK(v == std::floor(v) && v < 1e15, "{}: {} value {} must be a whole number",
                      context, axis.parameter, v);
      }
    }
  }
}

std::string FormatValue(double value) { return io::CsvNumber(value); }

std::vector<SweepSetting> ExpandGrid(const std::vector<SweepAxis>& axes) {
  if (axes.empty()) return {SweepSetting{.name = "base", .values = {}}};
  std::vector<SweepSetting> settings;
  std::vector<size_t> index(axes.size(), 0);
  while (true) {
    SweepSetting setting;
    for (size_t a = 0; a < axes.size(); ++a) {
      const double value = axes[a].values[index[a]];
      setting.values.emplace_back(axes[a].parameter, value);
      if (!setting.name.empty()) setting.name += '_';
      setting.name += axes[a].parameter + "-" + FormatValue(value);
    }
    settings.push_back(std::move(setting));
    // Odometer increment, last axis fastest.
    size_t a = axes.size();
    while (a > 0) {
      --a;
      if (++index[a] < axes[a].values.size()) break;
      index[a] = 0;
      if (a == 0) return settings;
    }
  }
}

std::vector<double> HalvingSeries(int full, int minimum) {
  REPHOTO_CHECK(minimum >= 1, "the smallest training-set size must be >= 1 (got {})", minimum);
  REPHOTO_CHECK(full >= minimum,
                "the training set has {} views, fewer than the smallest size to sweep ({})", full,
                minimum);
  std::vector<double> series;
  for (int n = full; n >= minimum; n /= 2) {
    series.push_back(n);
    if (n == 1) break;
  }
  return series;
}

}  // namespace rephoto::sweep
