#include "rephoto/report/scatterplot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <regex>

namespace rephoto::report {
namespace {

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(ScatterPlot, OnePointPerFiniteRunEscapedAndInsideTheAxes) {
  ScatterPlot plot;
  plot.title = "1-ncc vs. accuracy";
  plot.x_label = "accuracy";
  plot.y_label = "1-ncc";
  plot.series = {"a", "b<c>"};
  plot.points = {{0.001, 0.2, "run <1>", 0},
                 {0.004, 0.5, "run 2", 1},
                 {NAN, 0.3, "no geometry", 0},
                 {0.002, INFINITY, "infinite", 0}};
  const std::string svg = ScatterPlotSvg(plot);
  EXPECT_EQ(svg.rfind("<svg class=\"boxplot scatterplot\"", 0), 0u);
  EXPECT_EQ(Count(svg, "class=\"point-group\""), 2u);
  EXPECT_NE(svg.find("data-label=\"run &lt;1&gt;\" data-series=\"a\" data-x=\"0.001\" "
                     "data-y=\"0.2\""),
            std::string::npos);
  EXPECT_NE(svg.find("data-series=\"b&lt;c&gt;\""), std::string::npos);
  EXPECT_EQ(svg.find("no geometry"), std::string::npos);
  // Points lie inside the plotting area: x in [70, 430], y in [30, 270].
  const std::regex circle("class=\"point\" cx=\"([0-9.]+)\" cy=\"([0-9.]+)\"");
  size_t circles = 0;
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), circle); it != std::sregex_iterator();
       ++it) {
    const double cx = std::stod((*it)[1]), cy = std::stod((*it)[2]);
    EXPECT_GE(cx, 70);
    EXPECT_LE(cx, 430);
    EXPECT_GE(cy, 30);
    EXPECT_LE(cy, 270);
    ++circles;
  }
  EXPECT_EQ(circles, 2u);
  // No points: still a valid, empty plot.
  const std::string empty = ScatterPlotSvg(ScatterPlot{});
  EXPECT_EQ(Count(empty, "point-group"), 0u);
  EXPECT_NE(empty.find("</svg>"), std::string::npos);
}

}  // namespace
}  // namespace rephoto::report
