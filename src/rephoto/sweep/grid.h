// The grid of a `rephoto sweep` (paper Section 4: synthetic defects, training-set size and
// training resolution): which settings exist, what each is called, and the combined tables.
//
// Parameters a sweep can vary (values are numbers):
//   texture_noise, geometry_noise, simplify  defect strengths applied to the model
//                                            (degrade/degrade.h), 0 = none
//   seed                                     the defects' noise seed
//   train_count                              |T|, training views given to the pipeline per fold
//                                            (0 = the fold's whole training set)
//   train_short_side                         shorter side of the training photos in pixels
//                                            (0 = original); rephotos are always rendered and
//                                            compared at the evaluation resolution
// A sweep is the Cartesian product of its axes, in the order given (the last axis varies
// fastest). One axis is the plots' x axis; the combinations of the other axes are the series.
//
// Thread safety: pure functions.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rephoto::sweep {

struct SweepAxis {
  std::string parameter;       // one of the names above
  std::vector<double> values;  // in the order they are run and plotted
};

struct SweepSetting {
  // Folder-safe and readable, e.g. "train_count-8_train_short_side-480"; "base" when the
  // sweep has no axes.
  std::string name;
  std::vector<std::pair<std::string, double>> values;  // one per axis, in axis order
  double Value(std::string_view parameter) const;      // NaN when the parameter is not swept
};

// True for the parameter names above.
bool IsSweepParameter(std::string_view name);
// The names above, comma-separated (for error messages).
std::string SweepParameterList();

// Throws Error (prefixed with `context`) for an unknown parameter, an axis named twice, an axis
// without values, or values out of range (negative strengths, simplify >= 1, non-integer or
// negative counts/sizes/seeds).
void CheckAxes(const std::vector<SweepAxis>& axes, std::string_view context);

// The settings of the grid (Cartesian product, last axis fastest).
std::vector<SweepSetting> ExpandGrid(const std::vector<SweepAxis>& axes);

// Training-set sizes halved repeatedly from `full` as in the paper's Section 4.2:
// full, floor(full / 2), floor(full / 4), ... while >= minimum (minimum >= 1). Throws Error if
// full < minimum.
std::vector<double> HalvingSeries(int full, int minimum);

// A number as it appears in setting names and tables: the shortest round-trip text.
std::string FormatValue(double value);

}  // namespace rephoto::sweep
