#include "rephoto/report/report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "rephoto/compare/compare.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/progress.h"
#include "rephoto/core/stats.h"
#include "rephoto/io/csv.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/report/boxplot.h"
#include "rephoto/report/geometry_section.h"
#include "rephoto/report/html.h"
#include "rephoto/report/report_page.h"
#include "rephoto/report/thumbnails.h"
#include "rephoto/report/view3d.h"
#include "rephoto/run/run_data.h"

namespace rephoto::report {
namespace fs = std::filesystem;
using namespace internal;

namespace {

bool HigherIsBetter(const std::string& metric) {
  const auto m = metrics::ParseMetric(metric);
  return m && metrics::HigherIsBetter(*m);
}

std::string DirName(const fs::path& dir) {
  fs::path p = dir;
  if (p.filename().empty()) p = p.parent_path();
  return p.filename().string();
}

// The primary metric's index, falling back to the first metric (with a warning).
int PrimaryIndex(const run::RunData& run, const std::string& primary) {
  const int index = run.MetricIndex(primary);
  if (index >= 0 || run.metrics.empty()) return index;
  LogWarning(fmt::format("{}: no \"{}\" column; ranking images by {}", run.dir.string(), primary,
                         run.metrics[0]));
  return 0;
}

// <section id="view3d">: the 3D view and what it shows.
std::string View3dSectionHtml(const View3dData& data, const std::string& metric) {
  return fmt::format(
      "<section id=\"view3d-section\"><h2>The error on the model</h2><p class=\"muted\">The "
      "{} error of the evaluation photos projected onto the model (paper Fig. 5 and 9; "
      "projected/{}.ply), the photos' cameras and, when given, the suggested next views. "
      "Switch to \u201cseen by no photo\u201d to see what no photo covers.</p>\n{}</section>\n",
      HtmlEscape(metric), HtmlEscape(metric), View3dHtml(data, "view3d"));
}

std::string PlotsHtml(const std::vector<BoxPlot>& plots) {
  std::string html = "<div class=\"plots\">\n";
  for (const BoxPlot& plot : plots) html += BoxPlotSvg(plot);
  return html + "</div>\n";
}

}  // namespace

void WriteRunReport(const fs::path& run_dir, const fs::path& out_html,
                    const ReportOptions& options) {
  run::RunData run = run::LoadRun(run_dir);
  run.image_folders = options.image_folders;
  const std::string title =
      options.title.empty() ? "rephoto report: " + DirName(run_dir) : options.title;
  std::string html = PageStart(title);
  html += fmt::format("<header><h1>{}</h1>\n", HtmlEscape(title));
  html += SettingsHtml(run, /*collapsed=*/true);
  html += "</header>\n";
  html += ProblemsHtml(run);

  html += "<section id=\"summary\"><h2>Summary</h2>\n" + SummaryHtml(run) + "</section>\n";

  std::vector<BoxPlot> plots;
  const std::string unit = run.Unit();
  for (int m = -1; m < static_cast<int>(run.metrics.size()); ++m) {
    const std::string name = m < 0 ? "completeness" : run.metrics[m];
    BoxPlot plot;
    plot.title = fmt::format("{} {} {}", name, run.AcrossFolds() ? "across" : "over", unit);
    plot.y_label = name + (m >= 0 && HigherIsBetter(name) ? " (higher = better)" : "");
    plot.categories = {fmt::format("{} {}", run.Values(m).size(), unit)};
    plot.series = {name};
    plot.boxes.push_back({0, 0, run.Values(m)});
    plots.push_back(std::move(plot));
  }
  html += fmt::format(
      "<section id=\"plots\"><h2>Boxplots {} {}</h2><p class=\"muted\">Box Q1\u2013Q3, black line "
      "median, diamond mean, whiskers min and max, dots the single values.</p>\n",
      run.AcrossFolds() ? "across" : "over", unit);
  html += PlotsHtml(plots) + "</section>\n";
  // The 3D view and the example images are independent (each decodes its own images); they are
  // made concurrently and put into the page in this order.
  bool with_view = false;
  std::string view_html, examples_html;
  auto view3d = [&] {
    if (!options.view3d) return;
    const int primary = PrimaryIndex(run, options.primary_metric);
    const std::string metric = primary >= 0 ? run.metrics[primary] : options.primary_metric;
    // A projected PLY that cannot be read costs the view, not the report.
    std::vector<View3dModel> models;
    try {
      models =
          LoadRunView3dModels(run, metric, options.view3d_thumbnail_width, options.view3d_limits);
    } catch (const Error& e) {
      LogWarning(std::string("report: no 3D view: ") + e.what());
      view_html += fmt::format(
          "<section id=\"view3d-section\"><h2>The error on the model</h2><p "
          "class=\"problems\">No 3D view: {}</p></section>\n",
          HtmlEscape(e.what()));
    }
    if (!models.empty()) {
      for (View3dModel& m : models) {
        m.label = models.size() == 1 ? DirName(run_dir) : DirName(run_dir) + " " + m.label;
      }
      View3dData data;
      data.models = std::move(models);
      view_html += View3dSectionHtml(data, metric);
      with_view = true;
    }
  };
  const int primary = PrimaryIndex(run, options.primary_metric);
  auto examples = [&] {
    if (primary < 0 || options.example_images <= 0) return;
    examples_html = fmt::format("<section id=\"examples\"><h2>Worst and best images by {}</h2>\n",
                                HtmlEscape(run.metrics[primary]));
    examples_html += ExamplesHtml(run, primary, options.example_images, options.thumbnail_width);
    examples_html += "</section>\n";
  };
  ParallelInvoke(view3d, examples);
  html += view_html;
  html += examples_html;
  if (run.layout == run::RunLayout::kEvaluate && !run.folds.empty()) {
    html += fmt::format("<section id=\"folds\"><h2>Per fold ({})</h2>\n", run.folds.size()) +
            PerFoldTableHtml(run) + "</section>\n";
  }
  html += fmt::format(
      "<section id=\"images\"><h2>Per image ({})</h2><p class=\"muted\">Click a column header "
      "to sort (again: descending).</p>\n",
      run.images.size());
  html += PerImageTableHtml(run, "per-image") + "</section>\n";
  if (with_view) html += View3dScripts();
  html += PageEnd();
  WriteTextFileAtomically(out_html, html);
}

namespace {

// One run of a collection, loaded, with what the ranking needs.
struct Loaded {
  CollectionEntry entry;
  run::RunData run;
  int primary = -1;
  double primary_median = NAN;
  double completeness_median = NAN;
  size_t count = 0;
  std::string note;                // why the accuracy does not compare (empty: it does)
  geometry::RunGeometry geometry;  // with options.geometry_reference
};

// The runs of a collection and the metrics they have (union, first-seen order).
struct Collection {
  std::vector<Loaded> runs;
  std::vector<std::string> metric_names;
  bool sweep = false;          // the entries have settings
  bool with_geometry = false;  // options.geometry_reference given
};

Collection LoadCollection(const std::vector<CollectionEntry>& entries, const fs::path& out_html,
                          const CollectionOptions& options) {
  Collection c;
  c.sweep = entries[0].setting.has_value();
  for (const CollectionEntry& e : entries) {
    REPHOTO_CHECK(e.setting.has_value() == c.sweep,
                  "{}: entry \"{}\" ({}) {} a setting while entry \"{}\" {}; give every entry a "
                  "setting (a sweep) or none",
                  out_html.string(), e.label, e.run_dir.string(), c.sweep ? "lacks" : "has",
                  entries[0].label, c.sweep ? "has one" : "has none");
  }
  for (const CollectionEntry& e : entries) {
    Loaded l{e, run::LoadRun(e.run_dir)};
    l.run.image_folders = options.image_folders;
    if (l.entry.label.empty()) l.entry.label = DirName(e.run_dir);
    l.primary = l.run.MetricIndex(options.primary_metric);
    const std::vector<double> primary_values =
        l.primary >= 0 ? l.run.Values(l.primary) : std::vector<double>{};
    const Summary s = Summarize(primary_values);
    l.primary_median = s.median;
    l.count = s.count;
    l.completeness_median = Summarize(l.run.Values(-1)).median;
    for (const std::string& m : l.run.metrics) {
      if (std::find(c.metric_names.begin(), c.metric_names.end(), m) == c.metric_names.end()) {
        c.metric_names.push_back(m);
      }
    }
    c.runs.push_back(std::move(l));
  }
  REPHOTO_CHECK(
      std::any_of(c.runs.begin(), c.runs.end(), [](const Loaded& l) { return l.primary >= 0; }),
      "{}: no run has the primary metric \"{}\"", out_html.string(), options.primary_metric);
  if (options.rank) {
    const bool higher_better = HigherIsBetter(options.primary_metric);
    std::stable_sort(c.runs.begin(), c.runs.end(), [&](const Loaded& a, const Loaded& b) {
      const bool a_nan = std::isnan(a.primary_median), b_nan = std::isnan(b.primary_median);
      if (a_nan || b_nan) return !a_nan && b_nan;
      return higher_better ? a.primary_median > b.primary_median
                           : a.primary_median < b.primary_median;
    });
  }
  c.with_geometry = !options.geometry_reference.empty();
  if (c.with_geometry) {
    options.geometry_options.Check();
    REPHOTO_CHECK(fs::is_regular_file(options.geometry_reference),
                  "{}: the geometric reference does not exist or is not a file",
                  options.geometry_reference.string());
    for (Loaded& l : c.runs) {
      l.geometry = geometry::EvaluateRunGeometry(l.entry.run_dir, options.geometry_reference,
                                                 options.geometry_options);
      if (!l.geometry.available) LogWarning("geometry: " + l.geometry.message);
    }
  }
  return c;
}

// False only when summary.json says "cross_validated": false.
bool CrossValidated(const run::RunData& run) {
  return !(run.summary.is_object() && run.summary.contains("cross_validated") &&
           run.summary["cross_validated"].is_boolean() && !run.summary["cross_validated"]);
}

// Each run's note: completeness well below the most complete run's, or not cross-validated
// beside runs that are (a collection of fixed models alone, the demo's, compares fairly among
// itself).
void AddNotes(const fs::path& out_html, const CollectionOptions& options,
              std::vector<Loaded>& runs) {
  REPHOTO_CHECK(options.completeness_margin >= 0 && options.completeness_margin <= 1,
                "{}: completeness margin {} is not in [0, 1]", out_html.string(),
                options.completeness_margin);
  double best_completeness = NAN;
  for (const Loaded& l : runs) {
    if (!std::isnan(l.completeness_median) && !(l.completeness_median <= best_completeness)) {
      best_completeness = l.completeness_median;
    }
  }
  const bool mixed = std::any_of(runs.begin(), runs.end(),
                                 [&](const Loaded& l) { return CrossValidated(l.run); }) &&
                     std::any_of(runs.begin(), runs.end(),
                                 [&](const Loaded& l) { return !CrossValidated(l.run); });
  for (Loaded& l : runs) {
    std::vector<std::string> notes;
    if (!std::isnan(l.completeness_median) &&
        l.completeness_median < best_completeness - options.completeness_margin) {
      notes.push_back(fmt::format(
          "completeness {:.3f} is more than {:g} below the most complete run's {:.3f}: its "
          "accuracy covers fewer pixels and does not compare",
          l.completeness_median, options.completeness_margin, best_completeness));
    }
    if (mixed && !CrossValidated(l.run)) {
      notes.push_back("not cross-validated: the model may have seen the test photos");
    }
    for (const std::string& n : notes) l.note += (l.note.empty() ? "" : "; ") + n;
  }
}

std::string SettingName(const CollectionOptions& options) {
  return options.setting_name.empty() ? "setting" : options.setting_name;
}

// The median of metric `m` of a run; NaN when the run does not have it.
double MetricMedian(const Loaded& l, const std::string& m) {
  const int index = l.run.MetricIndex(m);
  return index >= 0 ? Summarize(l.run.Values(index)).median : NAN;
}

std::string RankingTableHtml(const Collection& c, const CollectionOptions& options) {
  const std::vector<Loaded>& runs = c.runs;
  bool any_series = false;
  for (const Loaded& l : runs) any_series = any_series || !l.entry.series.empty();
  std::string html = fmt::format(
      "<section id=\"ranking\"><h2>{}</h2><p class=\"muted\">Medians {}; completeness next to "
      "the primary metric: accuracy compares only between runs of similar completeness "
      "(\u26a0 marks runs whose completeness is more than {} below the most complete run's, or "
      "that are not cross-validated). Click a column header to sort.</p>\n<div "
      "class=\"scroll\"><table "
      "class=\"sortable ranking\" id=\"ranking-table\"><thead><tr><th data-col=\"rank\">#</th>"
      "<th class=\"text\" data-col=\"label\">run</th>",
      options.rank ? "Ranking" : "Runs",
      "across folds (evaluate runs with several folds) or over images",
      fmt::format("{:g}", options.completeness_margin));
  if (any_series) html += "<th class=\"text\" data-col=\"series\">series</th>";
  // The note right after the run it is about (at the far right it was off-screen at 1280 px
  // beside eight metric columns).
  bool any_note = false;
  for (const Loaded& l : runs) any_note = any_note || !l.note.empty();
  if (any_note) html += "<th class=\"text\" data-col=\"note\">note</th>";
  if (c.sweep) {
    html += fmt::format("<th data-col=\"setting\">{}</th>", HtmlEscape(SettingName(options)));
  }
  html += fmt::format(
      "<th data-col=\"count\">n</th><th data-col=\"{0}\">{0} median</th>"
      "<th data-col=\"completeness\">completeness median</th>",
      HtmlEscape(options.primary_metric));
  for (const std::string& m : c.metric_names) {
    if (m == options.primary_metric) continue;
    html += fmt::format("<th data-col=\"{0}\">{0}</th>", HtmlEscape(m));
  }
  if (c.with_geometry) html += GeometryHeaderCells(options.geometry_options);
  bool any_description = false;
  for (const Loaded& l : runs) any_description = any_description || !l.entry.description.empty();
  html += "<th data-col=\"failed_folds\">failed folds</th><th data-col=\"missing\">missing</th>";
  if (any_description) html += "<th class=\"text\" data-col=\"description\">description</th>";
  html += "</tr></thead><tbody>\n";
  for (size_t i = 0; i < runs.size(); ++i) {
    const Loaded& l = runs[i];
    html += fmt::format(
        "<tr data-label=\"{}\"><td data-v=\"{}\">{}</td><td class=\"text\"><a "
        "href=\"#entry-{}\">{}</a>{}</td>",
        HtmlEscape(l.entry.label), i + 1, i + 1, i, HtmlEscape(l.entry.label),
        l.note.empty()
            ? ""
            : " <span class=\"warn\" title=\"" + HtmlEscape(l.note) + "\">\u26a0</span>");
    if (any_series) html += fmt::format("<td class=\"text\">{}</td>", HtmlEscape(l.entry.series));
    if (any_note) html += fmt::format("<td class=\"text note\">{}</td>", HtmlEscape(l.note));
    if (c.sweep) {
      html += fmt::format("<td data-v=\"{}\">{}</td>", DataNumber(*l.entry.setting),
                          fmt::format("{:g}", *l.entry.setting));
    }
    html += fmt::format("<td data-v=\"{0}\">{0} {1}</td>", l.count, l.run.Unit());
    html += fmt::format(
        "<td data-v=\"{}\"{}>{}</td><td data-v=\"{}\">{}</td>", DataNumber(l.primary_median),
        i == 0 && options.rank ? " class=\"best\"" : "", DisplayNumber(l.primary_median),
        DataNumber(l.completeness_median), DisplayNumber(l.completeness_median));
    for (const std::string& m : c.metric_names) {
      if (m == options.primary_metric) continue;
      const double median = MetricMedian(l, m);
      html += fmt::format("<td data-v=\"{}\">{}</td>", DataNumber(median), DisplayNumber(median));
    }
    if (c.with_geometry) html += GeometryRowCells(l.geometry, options.geometry_options);
    html += fmt::format("<td data-v=\"{0}\">{0}</td><td data-v=\"{1}\">{1}</td>",
                        l.run.failed_folds.size(), l.run.missing.size());
    if (any_description) {
      html +=
          fmt::format("<td class=\"text description\">{}</td>", HtmlEscape(l.entry.description));
    }
    html += "</tr>\n";
  }
  html += "</tbody></table></div></section>\n";
  return html;
}

void WriteRankingCsv(const Collection& c, const CollectionOptions& options) {
  io::CsvWriter csv;
  std::vector<std::string> header = {"rank", "label", "n", options.primary_metric + "_median",
                                     "completeness_median"};
  for (const std::string& m : c.metric_names) {
    if (m != options.primary_metric) header.push_back(m + "_median");
  }
  if (c.with_geometry) {
    for (const std::string& column : geometry::RunGeometryColumns(options.geometry_options)) {
      header.push_back(column);
    }
  }
  for (const char* column : {"failed_folds", "missing", "cross_validated", "note"}) {
    header.emplace_back(column);
  }
  csv.AddRow(header);
  for (size_t i = 0; i < c.runs.size(); ++i) {
    const Loaded& l = c.runs[i];
    std::vector<std::string> row = {std::to_string(i + 1), l.entry.label, std::to_string(l.count),
                                    io::CsvNumber(l.primary_median),
                                    io::CsvNumber(l.completeness_median)};
    for (const std::string& m : c.metric_names) {
      if (m == options.primary_metric) continue;
      row.push_back(io::CsvNumber(MetricMedian(l, m)));
    }
    if (c.with_geometry) {
      for (double v : geometry::RunGeometryValues(l.geometry, options.geometry_options)) {
        row.push_back(io::CsvNumber(v));
      }
    }
    row.push_back(std::to_string(l.run.failed_folds.size()));
    row.push_back(std::to_string(l.run.missing.size()));
    row.push_back(CrossValidated(l.run) ? "true" : "false");
    row.push_back(l.note);
    csv.AddRow(row);
  }
  WriteTextFileAtomically(options.ranking_csv, csv.text());
}

// Boxplots of the primary metric, completeness and the other metrics: per entry, or per setting
// and series (a sweep, series in the caller's order).
std::vector<BoxPlot> CollectionPlots(const Collection& c,
                                     const std::vector<CollectionEntry>& entries,
                                     const CollectionOptions& options) {
  const std::vector<Loaded>& runs = c.runs;
  std::vector<std::string> categories, series;
  std::vector<std::pair<int, int>> position(runs.size());  // (category, series)
  if (c.sweep) {
    std::vector<double> settings;
    for (const Loaded& l : runs) settings.push_back(*l.entry.setting);
    std::sort(settings.begin(), settings.end());
    settings.erase(std::unique(settings.begin(), settings.end()), settings.end());
    for (double s : settings) categories.push_back(fmt::format("{:g}", s));
    for (const CollectionEntry& e : entries) {
      if (std::find(series.begin(), series.end(), e.series) == series.end()) {
        series.push_back(e.series);
      }
    }
    for (size_t i = 0; i < runs.size(); ++i) {
      position[i] = {
          static_cast<int>(
              std::lower_bound(settings.begin(), settings.end(), *runs[i].entry.setting) -
              settings.begin()),
          static_cast<int>(std::find(series.begin(), series.end(), runs[i].entry.series) -
                           series.begin())};
    }
  } else {
    for (size_t i = 0; i < runs.size(); ++i) {
      categories.push_back(runs[i].entry.label);
      position[i] = {static_cast<int>(i), 0};
    }
    series = {""};
  }
  std::vector<BoxPlot> plots;
  std::vector<std::string> plotted = {options.primary_metric, "completeness"};
  for (const std::string& m : c.metric_names) {
    if (m != options.primary_metric) plotted.push_back(m);
  }
  for (const std::string& name : plotted) {
    BoxPlot plot;
    plot.title = name;
    plot.y_label = name + (HigherIsBetter(name) ? " (higher = better)" : "");
    plot.x_label = c.sweep ? SettingName(options) : "";
    plot.categories = categories;
    plot.series = series;
    plot.connect_medians = c.sweep;
    for (size_t i = 0; i < runs.size(); ++i) {
      const int index = name == "completeness" ? -1 : runs[i].run.MetricIndex(name);
      if (name != "completeness" && index < 0) continue;
      plot.boxes.push_back({position[i].first, position[i].second, runs[i].run.Values(index)});
    }
    plots.push_back(std::move(plot));
  }
  return plots;
}

// The 3D view over the runs with projected errors of the primary metric ("" when none has).
std::string CollectionView3dHtml(const Collection& c, const CollectionOptions& options) {
  if (!options.view3d) return "";
  View3dData data;
  std::string problems;
  for (const Loaded& l : c.runs) {
    std::vector<View3dModel> models;
    try {
      models = LoadRunView3dModels(l.run, options.primary_metric, options.view3d_thumbnail_width,
                                   options.view3d_limits);
    } catch (const Error& e) {  // costs this run's entry in the view, not the report
      LogWarning(std::string("report: no 3D view of ") + l.entry.label + ": " + e.what());
      problems += "<li>" + HtmlEscape(l.entry.label) + ": " + HtmlEscape(e.what()) + "</li>";
    }
    for (View3dModel& model : models) {
      model.label = models.size() == 1 ? l.entry.label : l.entry.label + " " + model.label;
      data.models.push_back(std::move(model));
    }
  }
  if (data.models.empty()) return "";
  if (!options.suggestions.empty()) data.suggested = LoadSuggestedCameras(options.suggestions);
  std::string html = View3dSectionHtml(data, options.primary_metric);
  if (!problems.empty()) {
    html += "<div class=\"problems\"><p>Not in the 3D view:</p><ul>" + problems + "</ul></div>\n";
  }
  return html;
}

// Stems of per_image.csv names ("view_000"), as the side-by-side strip matches photos by.
std::string ImageKey(const run::ImageRow& image) { return image.name; }

// The side-by-side strip (see CollectionOptions::side_by_side).
std::string SideBySideHtml(const Collection& c, const CollectionOptions& options) {
  const std::optional<metrics::Metric> parsed = metrics::ParseMetric(options.primary_metric);
  if (!parsed || c.runs.size() < 2) return "";
  std::vector<std::string> chosen = options.side_by_side;
  if (chosen.empty()) {
    // Photos every run evaluated, by the spread of their primary metric across the runs.
    std::map<std::string, std::vector<double>> values;
    for (const Loaded& l : c.runs) {
      if (l.primary < 0) return "";
      for (const run::ImageRow& image : l.run.images) {
        if (image.status == "ok" && std::isfinite(image.metrics[l.primary])) {
          values[ImageKey(image)].push_back(image.metrics[l.primary]);
        }
      }
    }
    std::vector<std::pair<double, std::string>> spread;
    for (const auto& [name, v] : values) {
      if (v.size() != c.runs.size()) continue;
      const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
      spread.push_back({*hi - *lo, name});
    }
    std::sort(spread.begin(), spread.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    for (size_t i = 0; i < spread.size() && i < static_cast<size_t>(options.side_by_side_count);
         ++i) {
      chosen.push_back(spread[i].second);
    }
  }
  if (chosen.empty()) return "";
  struct Cell {
    const Loaded* run = nullptr;
    const run::ImageRow* image = nullptr;
    Thumbnail rephoto, error;
  };
  struct Row {
    std::string name;
    Thumbnail photo;
    std::vector<Cell> cells;
  };
  std::vector<Row> rows;
  for (const std::string& name : chosen) {
    Row row{name, {}, {}};
    for (const Loaded& l : c.runs) {
      Cell cell{&l, nullptr, {}, {}};
      for (const run::ImageRow& image : l.run.images) {
        if (ImageKey(image) == name) cell.image = &image;
      }
      row.cells.push_back(cell);
    }
    rows.push_back(std::move(row));
  }
  const int width = options.side_by_side_width;
  std::vector<std::pair<size_t, size_t>> jobs;  // (row, cell); cell == runs.size(): the photo
  for (size_t r = 0; r < rows.size(); ++r) {
    for (size_t k = 0; k <= c.runs.size(); ++k) jobs.push_back({r, k});
  }
  ForEachThumbnailJob(static_cast<int64_t>(jobs.size()), [&](int64_t i,
                                                              ThumbnailScratch* scratch) {
    Row& row = rows[jobs[i].first];
    if (jobs[i].second == c.runs.size()) {
      for (const Cell& cell : row.cells) {
        if (cell.image && cell.image->status == "ok") {
          row.photo = PhotoThumbnail(cell.run->run.PhotoPath(*cell.image), width, scratch);
          break;
        }
      }
      return;
    }
    Cell& cell = row.cells[jobs[i].second];
    if (cell.image == nullptr || cell.image->status != "ok") return;
    Thumbnail mask;
    RenderThumbnails(cell.run->run.RenderPath(*cell.image), width, &cell.rephoto, &mask, scratch);
    const fs::path errors = cell.run->run.ImageDir(*cell.image) / "errors";
    const std::string stem = cell.image->name + "." + options.primary_metric;
    cell.error = ErrorThumbnail(errors / (stem + ".exr"), errors / (stem + ".png"), *parsed,
                                width, scratch);
  });
  const auto [low, high] = compare::ErrorColourRange(*parsed);
  auto image = [](const Thumbnail& t, const std::string& alt) {
    if (t.data_uri.empty()) {
      return fmt::format("<div class=\"unavailable\">{}</div>",
                         HtmlEscape(t.error.empty() ? "not available" : t.error));
    }
    return fmt::format("<img src=\"{}\" width=\"{}\" height=\"{}\" alt=\"{}\">", t.data_uri,
                       t.width, t.height, HtmlEscape(alt));
  };
  std::string html = fmt::format(
      "<section id=\"side-by-side\"><h2>Side by side</h2><p class=\"muted\">{} Per run: its "
      "rephoto (top) and {} error image (bottom, range {} to {}, grey checkerboard = not "
      "evaluated).</p>\n<div class=\"scroll\"><table class=\"strip\"><thead><tr><th "
      "class=\"text\">photo</th>",
      options.side_by_side.empty()
          ? "The photos on which the runs disagree most (largest spread of the primary metric)."
          : "The chosen photos.",
      HtmlEscape(options.primary_metric), DisplayNumber(low), DisplayNumber(high));
  for (const Loaded& l : c.runs) {
    html += fmt::format("<th class=\"text\">{}</th>", HtmlEscape(l.entry.label));
  }
  html += "</tr></thead><tbody>\n";
  for (const Row& row : rows) {
    html += fmt::format("<tr class=\"strip-row\" data-name=\"{0}\"><td class=\"text\"><b>{0}</b>{1}</td>",
                        HtmlEscape(row.name), image(row.photo, "photo"));
    for (const Cell& cell : row.cells) {
      if (cell.image == nullptr) {
        html += "<td class=\"text muted\">not in this run</td>";
        continue;
      }
      const double value = cell.run->primary >= 0 ? cell.image->metrics[cell.run->primary] : NAN;
      html += fmt::format("<td class=\"text\" data-run=\"{}\">{} {}<br>{}{}</td>",
                          HtmlEscape(cell.run->entry.label), HtmlEscape(options.primary_metric),
                          DisplayNumber(value), image(cell.rephoto, "rephoto"),
                          image(cell.error, "error"));
    }
    html += "</tr>\n";
  }
  return html + "</tbody></table></div></section>\n";
}

// Per entry: problems, examples, per-image table and settings.
std::string EntriesHtml(const Collection& c, const CollectionOptions& options) {
  std::string html = "<section id=\"entries\"><h2>Runs</h2>\n";
  for (size_t i = 0; i < c.runs.size(); ++i) {
    const Loaded& l = c.runs[i];
    html += fmt::format(
        "<div class=\"entry\" id=\"entry-{}\"><h3>{}{}</h3>", i, HtmlEscape(l.entry.label),
        l.entry.description.empty()
            ? ""
            : " <span class=\"muted\">\u2014 " + HtmlEscape(l.entry.description) + "</span>");
    html += SettingsHtml(l.run, /*collapsed=*/true);
    html += ProblemsHtml(l.run);
    if (l.primary >= 0 && options.example_images > 0) {
      html += ExamplesHtml(l.run, l.primary, options.example_images, options.thumbnail_width);
    }
    html += fmt::format("<details><summary>Summary and per-image table ({} images)</summary>\n",
                        l.run.images.size());
    html += SummaryHtml(l.run);
    html += PerImageTableHtml(l.run, fmt::format("per-image-{}", i));
    html += "</details></div>\n";
  }
  return html + "</section>\n";
}

}  // namespace

void WriteCollectionReport(const std::vector<CollectionEntry>& entries, const fs::path& out_html,
                           const CollectionOptions& options) {
  REPHOTO_CHECK(!entries.empty(), "{}: no runs given for the report", out_html.string());
  Collection c = LoadCollection(entries, out_html, options);
  AddNotes(out_html, options, c.runs);
  const std::string title = options.title.empty()
                                ? fmt::format("rephoto comparison of {} runs", c.runs.size())
                                : options.title;
  std::string html = PageStart(title);
  html += fmt::format(
      "<header><h1>{}</h1><p class=\"meta\"><span>{} runs</span><span>primary "
      "metric {}{}</span>{}</p></header>\n",
      HtmlEscape(title), c.runs.size(), HtmlEscape(options.primary_metric),
      HigherIsBetter(options.primary_metric) ? " (higher is better)" : " (lower is better)",
      c.sweep ? fmt::format("<span>sweep over {}</span>", HtmlEscape(SettingName(options))) : "");
  html += RankingTableHtml(c, options);
  if (!options.ranking_csv.empty()) WriteRankingCsv(c, options);
  html +=
      "<section id=\"plots\"><h2>Boxplots</h2><p class=\"muted\">Each box: the run's values "
      "across folds (evaluate runs with several folds) or over images. Box Q1\u2013Q3, "
      "black line median, diamond mean, whiskers min and max.</p>\n" +
      PlotsHtml(CollectionPlots(c, entries, options)) + "</section>\n";
  if (c.with_geometry) {
    std::vector<GeometryRun> geometry_runs;
    for (const Loaded& l : c.runs) {
      geometry_runs.push_back({l.entry.label, l.entry.series, l.primary_median, l.geometry});
    }
    html += GeometrySectionHtml(geometry_runs, options.geometry_reference.string(),
                                options.geometry_options, options.primary_metric);
  }
  const std::string view3d = CollectionView3dHtml(c, options);
  html += view3d;
  html += SideBySideHtml(c, options);
  html += EntriesHtml(c, options);
  for (const CollectionOptions::Section& section : options.sections) {
    html += fmt::format("<section id=\"{}\"><h2>{}</h2>\n", HtmlEscape(section.id),
                        HtmlEscape(section.title));
    if (!section.note.empty()) html += "<p>" + HtmlEscape(section.note) + "</p>\n";
    html += section.body_html + "</section>\n";
  }
  if (!view3d.empty()) html += View3dScripts();
  html += PageEnd();
  WriteTextFileAtomically(out_html, html);
}

}  // namespace rephoto::report
