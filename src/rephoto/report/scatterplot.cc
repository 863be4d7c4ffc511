#include "rephoto/report/scatterplot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "rephoto/report/html.h"

namespace rephoto::report {
namespace {

constexpr const char* kColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                    "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};

std::string Colour(int series) {
  return kColours[static_cast<size_t>(std::max(0, series)) % std::size(kColours)];
}

std::string C(double v) { return fmt::format("{:.1f}", v); }

// An axis: nice step (1, 2 or 5 times a power of ten) and the range rounded out to it.
struct Axis {
  double low = 0, high = 1, step = 0.2;
};

Axis MakeAxis(double low, double high) {
  if (!std::isfinite(low)) {
    low = 0;
    high = 1;
  }
  if (high - low < 1e-12 * std::max(1.0, std::abs(high))) {
    const double pad = std::max(std::abs(low) * 0.05, 1e-6);
    low -= pad;
    high += pad;
  }
  const double raw = (high - low) / 5;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / power;
  Axis a;
  a.step = (f <= 1 ? 1 : f <= 2 ? 2 : f <= 5 ? 5 : 10) * power;
  a.low = std::floor(low / a.step) * a.step;
  a.high = std::ceil(high / a.step) * a.step;
  return a;
}

std::string Tick(double t, double step) {
  return fmt::format("{:.6g}", std::abs(t) < step * 1e-9 ? 0.0 : t);
}

}  // namespace

std::string ScatterPlotSvg(const ScatterPlot& plot) {
  double x_low = std::numeric_limits<double>::infinity(), x_high = -x_low;
  double y_low = x_low, y_high = -x_low;
  for (const ScatterPoint& p : plot.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
    x_low = std::min(x_low, p.x);
    x_high = std::max(x_high, p.x);
    y_low = std::min(y_low, p.y);
    y_high = std::max(y_high, p.y);
  }
  const Axis ax = MakeAxis(x_low, x_high), ay = MakeAxis(y_low, y_high);
  const bool legend = plot.series.size() > 1;
  const double left = 70, right = 20, top = plot.note.empty() ? 30 : 46;
  const double legend_height = legend ? 18.0 * static_cast<double>(plot.series.size()) : 0;
  const double plot_width = 360, plot_height = 240, bottom = 48;
  const double width = left + plot_width + right;
  const double height = top + plot_height + bottom + legend_height;
  const auto X = [&](double v) { return left + plot_width * (v - ax.low) / (ax.high - ax.low); };
  const auto Y = [&](double v) { return top + plot_height * (ay.high - v) / (ay.high - ay.low); };

  std::string svg = fmt::format(
      "<svg class=\"boxplot scatterplot\" xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" "
      "height=\"{1}\" viewBox=\"0 0 {0} {1}\" role=\"img\" aria-label=\"{2}\">\n",
      C(width), C(height), HtmlEscape(plot.title));
  svg += fmt::format("<text class=\"title\" x=\"{}\" y=\"18\" text-anchor=\"middle\">{}</text>\n",
                     C(width / 2), HtmlEscape(plot.title));
  if (!plot.note.empty()) {
    svg +=
        fmt::format("<text class=\"legend\" x=\"{}\" y=\"34\" text-anchor=\"middle\">{}</text>\n",
                    C(width / 2), HtmlEscape(plot.note));
  }
  for (double t = ay.low; t <= ay.high + ay.step * 1e-6; t += ay.step) {
    svg += fmt::format(
        "<line class=\"grid\" x1=\"{0}\" x2=\"{1}\" y1=\"{2}\" y2=\"{2}\"/>"
        "<text class=\"tick\" x=\"{3}\" y=\"{4}\" text-anchor=\"end\">{5}</text>\n",
        C(left), C(left + plot_width), C(Y(t)), C(left - 5), C(Y(t) + 4), Tick(t, ay.step));
  }
  for (double t = ax.low; t <= ax.high + ax.step * 1e-6; t += ax.step) {
    svg += fmt::format(
        "<line class=\"grid\" x1=\"{0}\" x2=\"{0}\" y1=\"{1}\" y2=\"{2}\"/>"
        "<text class=\"tick\" x=\"{0}\" y=\"{3}\" text-anchor=\"middle\">{4}</text>\n",
        C(X(t)), C(top), C(top + plot_height), C(top + plot_height + 14), Tick(t, ax.step));
  }
  svg += fmt::format(
      "<line class=\"axis\" x1=\"{0}\" x2=\"{0}\" y1=\"{1}\" y2=\"{2}\"/>"
      "<line class=\"axis\" x1=\"{0}\" x2=\"{3}\" y1=\"{2}\" y2=\"{2}\"/>\n",
      C(left), C(top), C(top + plot_height), C(left + plot_width));
  svg += fmt::format(
      "<text class=\"label\" transform=\"translate(14,{}) rotate(-90)\" "
      "text-anchor=\"middle\">{}</text>\n",
      C(top + plot_height / 2), HtmlEscape(plot.y_label));
  svg += fmt::format("<text class=\"label\" x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
                     C(left + plot_width / 2), C(top + plot_height + 34), HtmlEscape(plot.x_label));
  for (const ScatterPoint& p : plot.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
    const std::string series = p.series >= 0 && p.series < static_cast<int>(plot.series.size())
                                   ? plot.series[p.series]
                                   : "";
    svg += fmt::format(
        "<g class=\"point-group\" data-label=\"{0}\" data-series=\"{1}\" data-x=\"{2}\" "
        "data-y=\"{3}\"><title>{0}: {4} = {5}, {6} = {7}</title><circle class=\"point\" "
        "cx=\"{8}\" cy=\"{9}\" r=\"4\" fill=\"{10}\" fill-opacity=\"0.75\" stroke=\"#000\" "
        "stroke-width=\"0.5\"/></g>\n",
        HtmlEscape(p.label), HtmlEscape(series), DataNumber(p.x), DataNumber(p.y),
        HtmlEscape(plot.x_label), DisplayNumber(p.x), HtmlEscape(plot.y_label), DisplayNumber(p.y),
        C(X(p.x)), C(Y(p.y)), Colour(p.series));
  }
  if (legend) {
    for (size_t s = 0; s < plot.series.size(); ++s) {
      const double ly = top + plot_height + bottom + 18.0 * static_cast<double>(s);
      svg += fmt::format(
          "<circle cx=\"{}\" cy=\"{}\" r=\"4\" fill=\"{}\"/><text class=\"legend\" x=\"{}\" "
          "y=\"{}\">{}</text>\n",
          C(left + 6), C(ly - 4), Colour(static_cast<int>(s)), C(left + 16), C(ly),
          HtmlEscape(plot.series[s]));
    }
  }
  return svg + "</svg>\n";
}

}  // namespace rephoto::report
