// Boxplots as inline SVG (no scripts, no external resources).
//
// A box shows the five-number summary of core/stats.h (Summarize: linear-interpolation
// quartiles, numpy's default): the box spans Q1..Q3 with a line at the median, whiskers reach
// the minimum and maximum (no outlier rule, as in the paper's Fig. 6/7), a small diamond marks
// the mean, and when a box has at most 40 values they are drawn as dots beside it.
// Boxes sit at categories along x (entries of a collection, or the settings of a sweep) and,
// with several series, side by side within a category in the series' colour, with a legend.
// Each box is a <g class="box"> whose data-* attributes hold its statistics (full precision,
// see DataNumber) and whose <title> is a tooltip with the same numbers.
// Non-finite values: NaN is ignored; +-infinity (psnr of identical images) is drawn at the
// plot's edge. The y range covers all finite values.
//
// Thread safety: pure functions.
#pragma once

#include <string>
#include <vector>

#include "rephoto/core/stats.h"

namespace rephoto::report {

struct BoxPlotBox {
  int category = 0;            // index into BoxPlot::categories
  int series = 0;              // index into BoxPlot::series
  std::vector<double> values;  // the values summarised (NaN ignored)
};

struct BoxPlot {
  std::string title;                    // above the plot
  std::string x_label;                  // below the category labels ("" = none)
  std::string y_label;                  // left, rotated
  std::vector<std::string> categories;  // x positions, left to right
  std::vector<std::string> series;      // legend names; a single series draws no legend
  std::vector<BoxPlotBox> boxes;
  bool connect_medians = false;  // a line through each series' medians (sweeps)
};

// The <svg> element (text escaped). Boxes without any value are left out.
std::string BoxPlotSvg(const BoxPlot& plot);

// SVG colour bar of the jet colour map from `low` (left, dark blue) to `high` (right, dark
// red) with both values labelled; `label` names the metric.
std::string JetColourBarSvg(double low, double high, const std::string& label, int width = 240);

}  // namespace rephoto::report
