#include "rephoto/report/geometry_section.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "rephoto/geometry/correlation.h"
#include "rephoto/report/html.h"
#include "rephoto/report/scatterplot.h"

namespace rephoto::report::internal {
namespace {

std::string Cell(double v, const std::string& title = "") {
  return fmt::format("<td data-v=\"{}\"{}>{}</td>", DataNumber(v),
                     title.empty() ? "" : " title=\"" + HtmlEscape(title) + "\"", DisplayNumber(v));
}

// A correlation coefficient, or why there is none.
std::string Coefficient(double r, size_t runs) {
  if (!std::isnan(r)) return DisplayNumber(r);
  return runs < 2 ? "\u2013 (fewer than 2 runs)" : "\u2013 (a constant series)";
}

}  // namespace

std::string GeometryHeaderCells(const geometry::GeometryOptions& options) {
  std::string html =
      "<th data-col=\"geo_accuracy\" title=\"geometric accuracy: the distance "
      "within which " +
      fmt::format("{:g}", 100 * options.accuracy_fraction) +
      " % of the model lies from the reference (lower = better)\">geo "
      "accuracy</th>";
  for (double t : options.tolerances) {
    html += fmt::format(
        "<th data-col=\"geo_completeness@{0:g}\" title=\"fraction of the reference within {0:g} "
        "of the model\">geo completeness @{0:g}</th><th data-col=\"geo_f_score@{0:g}\" "
        "title=\"F-score at {0:g}\">F @{0:g}</th>",
        t);
  }
  return html;
}

std::string GeometryRowCells(const geometry::RunGeometry& run,
                             const geometry::GeometryOptions& options) {
  const std::string why = run.available ? "" : run.message;
  std::string html = Cell(run.available ? run.accuracy : NAN, why);
  for (size_t t = 0; t < options.tolerances.size(); ++t) {
    const bool ok = run.available && t < run.tolerances.size();
    html += Cell(ok ? run.tolerances[t].completeness : NAN, why);
    html += Cell(ok ? run.tolerances[t].f_score : NAN, why);
  }
  return html;
}

std::vector<GeometryCorrelation> GeometryCorrelations(const std::vector<GeometryRun>& runs,
                                                      const geometry::GeometryOptions& options) {
  using Measure = std::function<double(const geometry::RunGeometry&)>;
  std::vector<std::pair<std::string, Measure>> measures = {
      {"accuracy", [](const geometry::RunGeometry& g) { return g.accuracy; }}};
  for (size_t t = 0; t < options.tolerances.size(); ++t) {
    measures.push_back({fmt::format("completeness@{:g}", options.tolerances[t]),
                        [t](const geometry::RunGeometry& g) {
                          return t < g.tolerances.size() ? g.tolerances[t].completeness : NAN;
                        }});
    measures.push_back(
        {fmt::format("f_score@{:g}", options.tolerances[t]), [t](const geometry::RunGeometry& g) {
           return t < g.tolerances.size() ? g.tolerances[t].f_score : NAN;
         }});
  }
  std::vector<GeometryCorrelation> result;
  for (const auto& [name, measure] : measures) {
    std::vector<double> x, y;
    for (const GeometryRun& r : runs) {
      const double v = r.geometry.available ? measure(r.geometry) : NAN;
      if (std::isnan(v) || std::isnan(r.primary)) continue;
      x.push_back(v);
      y.push_back(r.primary);
    }
    result.push_back({name, geometry::Pearson(x, y), geometry::Spearman(x, y), x.size()});
  }
  return result;
}

std::string GeometrySectionHtml(const std::vector<GeometryRun>& runs, const std::string& reference,
                                const geometry::GeometryOptions& options,
                                const std::string& primary_metric) {
  const std::vector<GeometryCorrelation> correlations = GeometryCorrelations(runs, options);
  ScatterPlot plot;
  plot.title = fmt::format("{} vs. geometric accuracy", primary_metric);
  plot.x_label =
      fmt::format("geometric accuracy ({:g} %, reference units)", 100 * options.accuracy_fraction);
  plot.y_label = primary_metric + " median";
  for (const GeometryRun& r : runs) {
    if (std::find(plot.series.begin(), plot.series.end(), r.series) == plot.series.end()) {
      plot.series.push_back(r.series);
    }
  }
  for (const GeometryRun& r : runs) {
    if (!r.geometry.available) continue;
    const int series = static_cast<int>(
        std::find(plot.series.begin(), plot.series.end(), r.series) - plot.series.begin());
    plot.points.push_back({r.geometry.accuracy, r.primary, r.label, series});
  }
  const GeometryCorrelation& a = correlations.front();
  plot.note = fmt::format("Pearson {}, Spearman {}, {} runs", DisplayNumber(a.pearson),
                          DisplayNumber(a.spearman), a.runs);

  size_t unavailable = 0;
  std::string reasons;
  for (const GeometryRun& r : runs) {
    if (r.geometry.available) continue;
    ++unavailable;
    reasons += "<li>" + HtmlEscape(r.label) + ": " + HtmlEscape(r.geometry.message) + "</li>";
  }
  std::string html = fmt::format(
      "<section id=\"geometry\"><h2>Geometry beside appearance</h2><p class=\"muted\">Each "
      "run's model(s) against the reference <code>{}</code>: accuracy is the distance within "
      "which {:g} % of the model lies from the reference (lower = better), completeness the "
      "fraction of the reference within a tolerance of the model; per-fold models are "
      "evaluated each and averaged. Correlations of the {} median with each geometric measure "
      "over the runs that have both (the paper's Fig. 8 reports 0.63 Pearson / 0.69 Spearman "
      "for 1-NCC vs. Middlebury accuracy).</p>\n",
      HtmlEscape(reference), 100 * options.accuracy_fraction, HtmlEscape(primary_metric));
  if (unavailable > 0) {
    html += fmt::format(
        "<details><summary>{} run(s) without a geometric result</summary><ul>{}"
        "</ul></details>\n",
        unavailable, reasons);
  }
  html += "<div class=\"plots\">\n" + ScatterPlotSvg(plot) + "</div>\n";
  html +=
      "<table id=\"geometry-correlations\"><thead><tr><th class=\"text\">measure</th>"
      "<th>Pearson r</th><th>Spearman \u03c1</th><th>runs</th></tr></thead><tbody>\n";
  for (const GeometryCorrelation& c : correlations) {
    html += fmt::format(
        "<tr data-measure=\"{0}\" data-pearson=\"{1}\" data-spearman=\"{2}\" "
        "data-runs=\"{3}\"><td class=\"text\">{0}</td><td>{4}</td><td>{5}</td><td>{3}</td>"
        "</tr>\n",
        HtmlEscape(c.measure), DataNumber(c.pearson), DataNumber(c.spearman), c.runs,
        Coefficient(c.pearson, c.runs), Coefficient(c.spearman, c.runs));
  }
  return html + "</tbody></table></section>\n";
}

}  // namespace rephoto::report::internal
