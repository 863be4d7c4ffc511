#include "rephoto/report/boxplot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include "rephoto/core/colormap.h"
#include "rephoto/report/html.h"

namespace rephoto::report {
namespace {

constexpr const char* kSeriesColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                          "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};

std::string Colour(int series) {
  return kSeriesColours[static_cast<size_t>(series) % std::size(kSeriesColours)];
}

// A "nice" tick step (1, 2 or 5 times a power of ten) giving about `count` ticks over `range`.
double NiceStep(double range, int count) {
  const double raw = range / count;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  const double fraction = raw / power;
  const double nice = fraction <= 1 ? 1 : fraction <= 2 ? 2 : fraction <= 5 ? 5 : 10;
  return nice * power;
}

std::string Coordinate(double v) { return fmt::format("{:.1f}", v); }

std::string Truncate(const std::string& text, size_t length) {
  if (text.size() <= length) return text;
  return text.substr(0, length - 1) + "\u2026";
}

// Characters (UTF-8 code points) of a label.
size_t DisplayLength(const std::string& text) {
  size_t n = 0;
  for (unsigned char c : text) n += (c & 0xC0) != 0x80;
  return n;
}

// Where everything goes: the y axis range and the pixel geometry of one plot.
struct Layout {
  double axis_low = 0, axis_high = 1, step = 1;  // y axis range and tick step
  int series = 1;                                // at least 1
  double box_width = 26, slot = 56;              // box width, width of one category
  bool rotate = false;                           // category labels rotated
  double left = 62, right = 16, top = 30, bottom = 40;
  std::vector<std::pair<double, int>> legend;  // per series: (x offset from `left`, line)
  double legend_height = 0, plot_height = 200;
  double width = 0, height = 0;
  double y0 = 0;  // top of the plotting area

  double Y(double v) const {
    if (v == std::numeric_limits<double>::infinity()) return y0;
    if (v == -std::numeric_limits<double>::infinity()) return y0 + plot_height;
    return y0 + plot_height * (axis_high - v) / (axis_high - axis_low);
  }
  double X(int category, int s) const {
    const double centre = left + (category + 0.5) * slot;
    return centre + (s - (series - 1) / 2.0) * (box_width + 6);
  }
};

// The finite range of all values, padded when it is empty or a single value, extended to
// whole tick steps.
void ComputeYAxis(const BoxPlot& plot, Layout& layout) {
  double low = std::numeric_limits<double>::infinity();
  double high = -low;
  for (const BoxPlotBox& box : plot.boxes) {
    for (double v : box.values) {
      if (std::isfinite(v)) {
        low = std::min(low, v);
        high = std::max(high, v);
      }
    }
  }
  if (!std::isfinite(low)) {
    low = 0;
    high = 1;
  }
  if (high - low < 1e-12) {
    const double pad = std::max(std::abs(low) * 0.05, 1e-3);
    low -= pad;
    high += pad;
  }
  layout.step = NiceStep(high - low, 5);
  layout.axis_low = std::floor(low / layout.step) * layout.step;
  layout.axis_high = std::ceil(high / layout.step) * layout.step;
}

Layout ComputeLayout(const BoxPlot& plot) {
  Layout layout;
  ComputeYAxis(plot, layout);
  const int categories = std::max<int>(1, static_cast<int>(plot.categories.size()));
  layout.series = std::max<int>(1, static_cast<int>(plot.series.size()));
  layout.box_width = layout.series > 1 ? 16 : 26;
  layout.slot = std::max(56.0, layout.series * (layout.box_width + 6) + 22);
  for (const std::string& c : plot.categories) {
    layout.rotate = layout.rotate || DisplayLength(c) * 6.5 > layout.slot - 4;
  }
  // Rotated labels are shown whole (never cut): the bottom margin grows with the longest
  // label and the left margin with any label that would run past the left edge (text width
  // estimated at 6.5 px per character; rotation by 35 degrees).
  layout.bottom = 40;
  if (layout.rotate) {
    const double sin35 = 0.5736, cos35 = 0.8192;
    double longest = 0;
    for (size_t c = 0; c < plot.categories.size(); ++c) {
      const double length = 6.5 * static_cast<double>(DisplayLength(plot.categories[c]));
      longest = std::max(longest, length);
      layout.left = std::max(layout.left, length * cos35 - (c + 0.5) * layout.slot + 2);
    }
    layout.bottom = std::max(86.0, 24 + longest * sin35 + 8);
  }
  layout.bottom += plot.x_label.empty() ? 0 : 16;
  // Legend entries left to right, wrapped onto further lines (text width estimated at 6.5 px
  // per character of the 11 px font).
  double x = 0;
  int line = 0;
  for (const std::string& name : plot.series) {
    const double entry = 16 + 6.5 * std::min<size_t>(name.size(), 28) + 14;
    if (x > 0 && x + entry > std::max(300.0, categories * layout.slot)) {
      x = 0;
      ++line;
    }
    layout.legend.push_back({x, line});
    x += entry;
  }
  layout.legend_height = plot.series.size() > 1
                             ? 18.0 * (layout.legend.empty() ? 0 : layout.legend.back().second + 1)
                             : 0;
  layout.width = std::max(categories == 1 ? 200.0 : 300.0,
                          layout.left + layout.right + categories * layout.slot);
  layout.height = layout.top + layout.legend_height + layout.plot_height + layout.bottom;
  layout.y0 = layout.top + layout.legend_height;
  return layout;
}

std::string LegendSvg(const BoxPlot& plot, const Layout& layout) {
  std::string svg;
  if (plot.series.size() <= 1) return svg;
  for (size_t s = 0; s < plot.series.size(); ++s) {
    const double lx = layout.left + layout.legend[s].first;
    const double ly = layout.top + 4 + 18.0 * layout.legend[s].second;
    svg += fmt::format(
        "<rect x=\"{}\" y=\"{}\" width=\"12\" height=\"10\" fill=\"{}\" fill-opacity=\"0.35\" "
        "stroke=\"{}\"/><text class=\"legend\" x=\"{}\" y=\"{}\">{}</text>\n",
        Coordinate(lx), Coordinate(ly), Colour(static_cast<int>(s)), Colour(static_cast<int>(s)),
        Coordinate(lx + 16), Coordinate(ly + 9), HtmlEscape(Truncate(plot.series[s], 28)));
  }
  return svg;
}

// Grid lines with tick labels, the two axis lines, the y label, the category labels and the
// x label.
std::string AxesSvg(const BoxPlot& plot, const Layout& layout) {
  std::string svg;
  const double left = layout.left, right = layout.right, width = layout.width;
  const double y0 = layout.y0, plot_height = layout.plot_height, step = layout.step;
  for (double t = layout.axis_low; t <= layout.axis_high + step * 1e-6; t += step) {
    const double y = layout.Y(t);
    const double shown = std::abs(t) < step * 1e-9 ? 0.0 : t;
    svg += fmt::format(
        "<line class=\"grid\" x1=\"{0}\" x2=\"{1}\" y1=\"{2}\" y2=\"{2}\"/>"
        "<text class=\"tick\" x=\"{3}\" y=\"{4}\" text-anchor=\"end\">{5}</text>\n",
        Coordinate(left), Coordinate(width - right), Coordinate(y), Coordinate(left - 5),
        Coordinate(y + 4), fmt::format("{:.6g}", shown));
  }
  svg += fmt::format(
      "<line class=\"axis\" x1=\"{0}\" x2=\"{0}\" y1=\"{1}\" y2=\"{2}\"/>"
      "<line class=\"axis\" x1=\"{0}\" x2=\"{3}\" y1=\"{2}\" y2=\"{2}\"/>\n",
      Coordinate(left), Coordinate(y0), Coordinate(y0 + plot_height), Coordinate(width - right));
  svg += fmt::format(
      "<text class=\"label\" transform=\"translate(14,{}) rotate(-90)\" "
      "text-anchor=\"middle\">{}</text>\n",
      Coordinate(y0 + plot_height / 2), HtmlEscape(plot.y_label));
  for (size_t c = 0; c < plot.categories.size(); ++c) {
    const double x = left + (c + 0.5) * layout.slot;
    const double y = y0 + plot_height + 14;
    if (layout.rotate) {
      svg += fmt::format(
          "<text class=\"category\" transform=\"translate({},{}) rotate(-35)\" "
          "text-anchor=\"end\">{}<title>{}</title></text>\n",
          Coordinate(x + 4), Coordinate(y), HtmlEscape(plot.categories[c]),
          HtmlEscape(plot.categories[c]));
    } else {
      svg += fmt::format(
          "<text class=\"category\" x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
          Coordinate(x), Coordinate(y), HtmlEscape(plot.categories[c]));
    }
  }
  if (!plot.x_label.empty()) {
    svg += fmt::format("<text class=\"label\" x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
                       Coordinate(left + (width - left - right) / 2), Coordinate(layout.height - 6),
                       HtmlEscape(plot.x_label));
  }
  return svg;
}

// A dashed line through each series' medians, left to right (sweeps).
std::string MedianLinesSvg(const BoxPlot& plot, const std::vector<Summary>& stats,
                           const Layout& layout) {
  std::string svg;
  for (int s = 0; s < layout.series; ++s) {
    std::vector<std::pair<int, double>> points;
    for (size_t b = 0; b < plot.boxes.size(); ++b) {
      if (plot.boxes[b].series == s && stats[b].count > 0 && std::isfinite(stats[b].median)) {
        points.push_back({plot.boxes[b].category, stats[b].median});
      }
    }
    std::sort(points.begin(), points.end());
    if (points.size() < 2) continue;
    std::string path;
    for (const auto& [category, median] : points) {
      path += fmt::format("{}{},{}", path.empty() ? "M" : " L", Coordinate(layout.X(category, s)),
                          Coordinate(layout.Y(median)));
    }
    svg += fmt::format(
        "<path class=\"median-line\" d=\"{}\" fill=\"none\" stroke=\"{}\" "
        "stroke-dasharray=\"4 3\"/>\n",
        path, Colour(s));
  }
  return svg;
}

// One <g class="box">: statistics as data-* attributes and tooltip, whiskers with caps, the
// Q1..Q3 box, the median line, the mean diamond and, for small sets, the values as dots.
std::string BoxSvg(const BoxPlot& plot, const BoxPlotBox& box, const Summary& s,
                   const Layout& layout) {
  const std::string colour = Colour(box.series);
  const double x = layout.X(box.category, box.series);
  const double half = layout.box_width / 2;
  auto Y = [&](double v) { return layout.Y(v); };
  const std::string category =
      box.category < static_cast<int>(plot.categories.size()) ? plot.categories[box.category] : "";
  const std::string series_name =
      box.series < static_cast<int>(plot.series.size()) ? plot.series[box.series] : "";
  std::string svg = fmt::format(
      "<g class=\"box\" data-category=\"{}\" data-series=\"{}\" data-count=\"{}\" "
      "data-mean=\"{}\" data-min=\"{}\" data-q1=\"{}\" data-median=\"{}\" data-q3=\"{}\" "
      "data-max=\"{}\">",
      HtmlEscape(category), HtmlEscape(series_name), s.count, DataNumber(s.mean), DataNumber(s.min),
      DataNumber(s.q1), DataNumber(s.median), DataNumber(s.q3), DataNumber(s.max));
  svg +=
      fmt::format("<title>{}{}{}: n={} min={} Q1={} median={} Q3={} max={} mean={}</title>",
                  HtmlEscape(category), series_name.empty() ? "" : " / ", HtmlEscape(series_name),
                  s.count, DisplayNumber(s.min), DisplayNumber(s.q1), DisplayNumber(s.median),
                  DisplayNumber(s.q3), DisplayNumber(s.max), DisplayNumber(s.mean));
  // Whiskers with caps.
  svg += fmt::format(
      "<line x1=\"{0}\" x2=\"{0}\" y1=\"{1}\" y2=\"{2}\" stroke=\"{5}\"/>"
      "<line x1=\"{0}\" x2=\"{0}\" y1=\"{3}\" y2=\"{4}\" stroke=\"{5}\"/>",
      Coordinate(x), Coordinate(Y(s.max)), Coordinate(Y(s.q3)), Coordinate(Y(s.q1)),
      Coordinate(Y(s.min)), colour);
  for (double v : {s.min, s.max}) {
    svg +=
        fmt::format("<line x1=\"{0}\" x2=\"{1}\" y1=\"{2}\" y2=\"{2}\" stroke=\"{3}\"/>",
                    Coordinate(x - half / 2), Coordinate(x + half / 2), Coordinate(Y(v)), colour);
  }
  svg += fmt::format(
      "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\" fill-opacity=\"0.3\" "
      "stroke=\"{}\"/>",
      Coordinate(x - half), Coordinate(Y(s.q3)), Coordinate(layout.box_width),
      Coordinate(std::max(0.5, Y(s.q1) - Y(s.q3))), colour, colour);
  svg += fmt::format(
      "<line class=\"median\" x1=\"{0}\" x2=\"{1}\" y1=\"{2}\" y2=\"{2}\" stroke=\"#000\" "
      "stroke-width=\"2\"/>",
      Coordinate(x - half), Coordinate(x + half), Coordinate(Y(s.median)));
  if (std::isfinite(s.mean)) {
    const double my = Y(s.mean);
    svg += fmt::format(
        "<path d=\"M{0},{1} L{2},{3} L{0},{4} L{5},{3} Z\" fill=\"#fff\" stroke=\"#000\"/>",
        Coordinate(x), Coordinate(my - 3), Coordinate(x + 3), Coordinate(my), Coordinate(my + 3),
        Coordinate(x - 3));
  }
  // Dots for small sets, in a deterministic spread beside the box.
  if (box.values.size() <= 40) {
    int i = 0;
    for (double v : box.values) {
      if (std::isnan(v)) continue;
      // Beside the box for one series, inside it (spread over its width) for several.
      const double dx = layout.series == 1 ? half + 3 + (i % 3) * 2.5
                                           : (static_cast<double>(i % 5) - 2) * half / 3;
      ++i;
      svg += fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"1.8\" fill=\"{}\"/>", Coordinate(x + dx),
                         Coordinate(Y(v)), colour);
    }
  }
  svg += "</g>\n";
  return svg;
}

}  // namespace

std::string BoxPlotSvg(const BoxPlot& plot) {
  std::vector<Summary> stats;
  for (const BoxPlotBox& box : plot.boxes) stats.push_back(Summarize(box.values));
  const Layout layout = ComputeLayout(plot);
  std::string svg = fmt::format(
      "<svg class=\"boxplot\" xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" "
      "height=\"{1}\" viewBox=\"0 0 {0} {1}\" role=\"img\" aria-label=\"{2}\">\n",
      Coordinate(layout.width), Coordinate(layout.height), HtmlEscape(plot.title));
  svg += fmt::format("<text class=\"title\" x=\"{}\" y=\"18\" text-anchor=\"middle\">{}</text>\n",
                     Coordinate(layout.width / 2), HtmlEscape(plot.title));
  svg += LegendSvg(plot, layout);
  svg += AxesSvg(plot, layout);
  if (plot.connect_medians) svg += MedianLinesSvg(plot, stats, layout);
  for (size_t b = 0; b < plot.boxes.size(); ++b) {
    if (stats[b].count > 0) svg += BoxSvg(plot, plot.boxes[b], stats[b], layout);
  }
  svg += "</svg>\n";
  return svg;
}

std::string JetColourBarSvg(double low, double high, const std::string& label, int width) {
  std::string stops;
  constexpr int kStops = 16;
  for (int i = 0; i <= kStops; ++i) {
    const float t = static_cast<float>(i) / kStops;
    const auto rgb = JetColor(t);
    stops += fmt::format("<stop offset=\"{:.4f}\" stop-color=\"rgb({},{},{})\"/>", t,
                         std::lround(rgb[0] * 255), std::lround(rgb[1] * 255),
                         std::lround(rgb[2] * 255));
  }
  // The gradient id depends only on the content: bars with the same range share one gradient.
  std::string id = "jet-" + DataNumber(low) + "-" + DataNumber(high);
  for (char& c : id) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  const int height = 34;
  return fmt::format(
      "<svg class=\"colourbar\" xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" "
      "height=\"{1}\" viewBox=\"0 0 {0} {1}\" role=\"img\" aria-label=\"{2} colour bar\">"
      "<defs><linearGradient id=\"{3}\">{4}</linearGradient></defs>"
      "<rect x=\"0\" y=\"0\" width=\"{0}\" height=\"14\" fill=\"url(#{3})\"/>"
      "<text x=\"0\" y=\"28\">{5}</text><text x=\"{6}\" y=\"28\" text-anchor=\"middle\">{2}</text>"
      "<text x=\"{0}\" y=\"28\" text-anchor=\"end\">{7}</text></svg>",
      width, height, HtmlEscape(label), id, stops, DisplayNumber(low), width / 2,
      (high >= low ? "\u2265 " : "\u2264 ") + DisplayNumber(high));
}

}  // namespace rephoto::report
