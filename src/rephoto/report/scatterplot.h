// Scatterplots as inline SVG (no scripts, no external resources), e.g. each run's primary
// rephoto error against its geometric accuracy (paper Fig. 8).
//
// Each point is a <circle class="point"> inside a <g class="point-group"> whose data-label,
// data-series, data-x and data-y attributes hold its label and values (full precision, see
// html.h DataNumber) and whose <title> is a tooltip. Points with a non-finite coordinate are
// left out (the caller reports how many were plotted). Axes are linear with "nice" ticks
// covering all finite values; several series get their colours (the boxplots' palette order)
// and a legend. The SVG carries the class "boxplot scatterplot" so that it takes the reports'
// plot styles. Thread safety: pure function.
#pragma once

#include <string>
#include <vector>

namespace rephoto::report {

struct ScatterPoint {
  double x = 0;
  double y = 0;
  std::string label;  // tooltip and data-label
  int series = 0;     // index into ScatterPlot::series
};

struct ScatterPlot {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::vector<std::string> series;  // legend names; zero or one series draws no legend
  std::vector<ScatterPoint> points;
  std::string note;  // one line under the title (e.g. the correlations); "" = none
};

// The <svg> element (text escaped).
std::string ScatterPlotSvg(const ScatterPlot& plot);

}  // namespace rephoto::report
