#include "rephoto/run/records.h"
#include "rephoto/report/report_page.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "rephoto/compare/compare.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/stats.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/report/boxplot.h"
#include "rephoto/report/html.h"
#include "rephoto/report/thumbnails.h"

namespace rephoto::report::internal {
namespace {

using Json = nlohmann::ordered_json;

constexpr const char* kCss = R"css(
:root { --fg: #1d1d1f; --muted: #666; --line: #d8d8dc; --bad: #b3261e; --head: #f3f3f6; }
* { box-sizing: border-box; }
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--fg);
       margin: 0 auto; padding: 16px 24px 48px; max-width: 1500px; }
h1 { font-size: 22px; margin: 8px 0 4px; }
h2 { font-size: 18px; margin: 28px 0 8px; border-bottom: 1px solid var(--line); padding-bottom: 4px; }
h3 { font-size: 15px; margin: 18px 0 6px; }
.muted, .meta { color: var(--muted); }
.meta span { margin-right: 16px; display: inline-block; }
code, .path { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 12px; word-break: break-all; }
table { border-collapse: collapse; margin: 6px 0 12px; }
th, td { border: 1px solid var(--line); padding: 3px 8px; text-align: right; white-space: nowrap; }
th { background: var(--head); font-weight: 600; }
td.text, th.text { text-align: left; white-space: normal; }
td.description { min-width: 26em; }
table.kv td { text-align: left; white-space: normal; }
table.kv td:first-child { color: var(--muted); white-space: nowrap; }
table.sortable th { cursor: pointer; user-select: none; }
table.sortable th::after { content: " \2195"; color: #aaa; font-weight: normal; }
table.sortable th[aria-sort="ascending"]::after { content: " \2191"; color: var(--fg); }
table.sortable th[aria-sort="descending"]::after { content: " \2193"; color: var(--fg); }
tr.bad td { color: var(--bad); }
td.status-bad { color: var(--bad); font-weight: 600; }
td.best { font-weight: 700; }
.warn { color: #b45309; cursor: help; }
td.note { min-width: 14em; max-width: 22em; white-space: normal; color: #6b4e16; font-size: 12px; }
table.strip td { vertical-align: top; }
table.strip img { display: block; margin: 2px 0; max-width: 220px; height: auto; border: 1px solid var(--line); }
.scroll { overflow-x: auto; max-width: 100%; }
.plots { display: flex; flex-wrap: wrap; gap: 12px; }
.plots svg { background: #fff; border: 1px solid var(--line); max-width: 100%; height: auto; }
svg text { font: 11px system-ui, sans-serif; fill: #333; }
svg text.title { font-size: 13px; font-weight: 600; }
svg .grid { stroke: #eee; }
svg .axis { stroke: #555; }
.problems { border-left: 4px solid var(--bad); padding: 4px 12px; background: #fff5f4; }
.problems li { margin: 2px 0; }
.example { margin: 10px 0 18px; }
.example .images { display: grid; grid-template-columns: repeat(4, minmax(0, 1fr)); gap: 8px; }
.example figure { margin: 0; }
.example img { width: 100%; height: auto; display: block; border: 1px solid var(--line); }
.example 
.example figcaption { font-size: 12px; color: var(--muted); }
.example .unavailable { border: 1px dashed var(--line); padding: 12px; color: var(--bad); font-size: 12px; word-break: break-all; }
details > summary { cursor: pointer; color: #0b57d0; }
)css";

constexpr const char* kErrorHook =
    "window.addEventListener('error',function(e){document.documentElement.setAttribute("
    "'data-js-error',String(e.message||e));});";

constexpr const char* kScript = R"js(
(function () {
  'use strict';
  function cellKey(cell) {
    var v = cell.getAttribute('data-v');
    if (v === null) return {text: cell.textContent.trim()};
    if (v === '') return null;
    var n = Number(v);
    return isNaN(n) ? {text: v} : {num: n};
  }
  function compareKeys(a, b) {
    if ('num' in a && 'num' in b) return a.num < b.num ? -1 : (a.num > b.num ? 1 : 0);
    var x = 'num' in a ? String(a.num) : a.text;
    var y = 'num' in b ? String(b.num) : b.text;
    return x.localeCompare(y, undefined, {numeric: true});
  }
  // Sorts the table's body rows by `column`; empty values last in both directions; ties keep
  // their current order.
  function sortBy(table, column, descending) {
    var body = table.tBodies[0];
    var keyed = Array.prototype.map.call(body.rows, function (row, i) {
      return {row: row, key: row.cells[column] ? cellKey(row.cells[column]) : null, i: i};
    });
    keyed.sort(function (p, q) {
      if (p.key === null || q.key === null) {
        if (p.key === q.key) return p.i - q.i;
        return p.key === null ? 1 : -1;
      }
      var c = compareKeys(p.key, q.key);
      if (descending) c = -c;
      return c !== 0 ? c : p.i - q.i;
    });
    keyed.forEach(function (k) { body.appendChild(k.row); });
    var headers = table.tHead.rows[0].cells;
    for (var h = 0; h < headers.length; ++h) {
      headers[h].setAttribute('aria-sort',
          h === column ? (descending ? 'descending' : 'ascending') : 'none');
    }
  }
  var tables = Array.prototype.slice.call(document.querySelectorAll('table.sortable'));
  tables.forEach(function (table) {
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, column) {
      th.tabIndex = 0;
      th.title = 'Sort by ' + th.textContent.trim();
      th.addEventListener('click', function () {
        sortBy(table, column, th.getAttribute('aria-sort') === 'ascending');
      });
      th.addEventListener('keydown', function (e) {
        if (e.key === 'Enter' || e.key === ' ') { e.preventDefault(); th.click(); }
      });
    });
  });
  // "#sort=<column>" / "#sort=-<column>": click that header of the first table that has it.
  var match = /(?:^#|&)sort=(-?)([^&]+)/.exec(window.location.hash);
  if (match) {
    var wanted = decodeURIComponent(match[2]);
    for (var t = 0; t < tables.length; ++t) {
      var found = Array.prototype.filter.call(tables[t].tHead.rows[0].cells, function (th) {
        return th.getAttribute('data-col') === wanted;
      });
      if (found.length > 0) {
        found[0].click();
        if (match[1] === '-') found[0].click();
        break;
      }
    }
  }
  document.body.setAttribute('data-ready', '1');
})();
)js";

std::string JsonText(const Json& j) {
  if (j.is_string()) return j.get<std::string>();
  if (j.is_null()) return "null";
  return j.dump();
}

std::string Shorten(std::string text, size_t length) {
  if (text.size() > length) text = text.substr(0, length) + " \u2026";
  return text;
}

// Flattens JSON to "a.b.c" -> value rows. Arrays of up to 16 scalars are joined; larger or
// nested arrays are summarised by their length.
void Flatten(const Json& j, const std::string& prefix, int depth,
             std::vector<std::pair<std::string, std::string>>* out) {
  if (j.is_object() && depth < 5) {
    for (const auto& [key, value] : j.items()) {
      Flatten(value, prefix.empty() ? key : prefix + "." + key, depth + 1, out);
    }
    return;
  }
  if (j.is_array()) {
    const bool scalars =
        std::all_of(j.begin(), j.end(), [](const Json& e) { return e.is_primitive(); });
    if (scalars && j.size() <= 16) {
      std::string joined;
      for (const Json& e : j) joined += (joined.empty() ? "" : ", ") + JsonText(e);
      out->push_back({prefix, joined.empty() ? "(none)" : joined});
    } else {
      out->push_back({prefix, fmt::format("[{} entries]", j.size())});
    }
    return;
  }
  out->push_back({prefix, Shorten(JsonText(j), 400)});
}

// A summary.json value that may be missing: "" if absent.
std::string Fact(const Json& j, std::initializer_list<const char*> path) {
  const Json* node = &j;
  for (const char* key : path) {
    if (!node->is_object() || !node->contains(key)) return "";
    node = &(*node)[key];
  }
  return JsonText(*node);
}

// summary.json's pooled value of a metric (compare: metrics.<m>.pooled; evaluate: <m>.pooled).
double Pooled(const run::RunData& run, const std::string& metric) {
  const Json& s = run.summary;
  if (!s.is_object()) return NAN;
  if (s.contains("metrics") && s["metrics"].is_object() && s["metrics"].contains(metric) &&
      s["metrics"][metric].is_object() && s["metrics"][metric].contains("pooled")) {
    return run::NumberFromJson(s["metrics"][metric]["pooled"]);
  }
  if (s.contains(metric) && s[metric].is_object() && s[metric].contains("pooled")) {
    return run::NumberFromJson(s[metric]["pooled"]);
  }
  return NAN;
}

std::string MetricLabel(const std::string& metric) {
  const auto m = metrics::ParseMetric(metric);
  if (m && metrics::HigherIsBetter(*m)) return metric + " \u2191";
  return metric;
}

// One summary table over the given units (folds or images).
std::string SummaryTable(const run::RunData& run, bool across_folds) {
  const auto values = [&](int m) { return across_folds ? run.FoldValues(m) : run.ImageValues(m); };
  const std::vector<double> completeness = values(-1);
  const bool pooled = !across_folds;
  std::string html = fmt::format(
      "<table class=\"summary\" data-unit=\"{}\"><thead><tr><th class=\"text\">{}</th>"
      "<th>mean</th><th>min</th><th>Q1</th><th>median</th><th>Q3</th><th>max</th>"
      "<th>{}</th><th>completeness<br>(mean, same {})</th>{}</tr></thead><tbody>\n",
      across_folds ? "folds" : "images", across_folds ? "across folds" : "over images",
      across_folds ? "folds" : "images", across_folds ? "folds" : "images",
      pooled ? "<th>pooled</th>" : "");
  auto row = [&](const std::string& name, const std::string& label, const std::vector<double>& v,
                 double pooled_value) {
    const Summary s = Summarize(v);
    double c_sum = 0;
    size_t c_count = 0;
    for (size_t i = 0; i < v.size(); ++i) {
      if (!std::isnan(v[i]) && !std::isnan(completeness[i])) {
        c_sum += completeness[i];
        ++c_count;
      }
    }
    const double c_mean = c_count > 0 ? c_sum / c_count : NAN;
    std::string r = fmt::format("<tr data-metric=\"{}\"><th class=\"text\">{}</th>",
                                HtmlEscape(name), HtmlEscape(label));
    for (double x : {s.mean, s.min, s.q1, s.median, s.q3, s.max}) {
      r += fmt::format("<td data-v=\"{}\">{}</td>", DataNumber(x), DisplayNumber(x));
    }
    r += fmt::format("<td>{}</td><td data-v=\"{}\">{}</td>", s.count, DataNumber(c_mean),
                     name == "completeness" ? "" : DisplayNumber(c_mean));
    if (pooled) {
      r += fmt::format("<td data-v=\"{}\">{}</td>", DataNumber(pooled_value),
                       DisplayNumber(pooled_value));
    }
    return r + "</tr>\n";
  };
  html += row("completeness", "completeness", completeness, NAN);
  for (size_t m = 0; m < run.metrics.size(); ++m) {
    html += row(run.metrics[m], MetricLabel(run.metrics[m]), values(static_cast<int>(m)),
                Pooled(run, run.metrics[m]));
  }
  return html + "</tbody></table>\n";
}

std::string Figure(const Thumbnail& t, const std::string& caption, const std::string& cls,
                   const std::string& extra = "") {
  std::string html = "<figure>";
  if (t.data_uri.empty()) {
    html += fmt::format("<div class=\"unavailable\">not available: {}</div>", HtmlEscape(t.error));
  } else {
    html += fmt::format("<img class=\"{}\" src=\"{}\" width=\"{}\" height=\"{}\" alt=\"{}\">", cls,
                        t.data_uri, t.width, t.height, HtmlEscape(caption));
  }
  return html + fmt::format("<figcaption>{}</figcaption>{}</figure>", HtmlEscape(caption), extra);
}

}  // namespace

std::string PageStart(const std::string& title) {
  return fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
      "<title>{}</title>\n<script>{}</script>\n<style>{}</style>\n</head>\n<body>\n",
      HtmlEscape(title), kErrorHook, kCss);
}

std::string PageEnd() { return fmt::format("<script>{}</script>\n</body>\n</html>\n", kScript); }

std::string SettingsHtml(const run::RunData& run, bool collapsed) {
  const Json& s = run.summary;
  std::string version = Fact(s, {"tool", "version"});
  if (version.empty()) version = Fact(s, {"tool_version"});
  if (version.empty()) version = Fact(run.run, {"tool_version"});
  if (version.empty()) version = Fact(run.run, {"tool", "version"});
  size_t ok = 0;
  for (const run::ImageRow& image : run.images) ok += image.status == "ok" ? 1 : 0;
  std::string html = "<p class=\"meta\">";
  html +=
      fmt::format("<span>run <span class=\"path\">{}</span></span>", HtmlEscape(run.dir.string()));
  html +=
      fmt::format("<span>{}</span>", run.layout == run::RunLayout::kEvaluate ? "rephoto evaluate run"
                                                                        : "rephoto compare run");
  if (!version.empty()) html += fmt::format("<span>rephoto {}</span>", HtmlEscape(version));
  for (const char* key : {"scene", "scheme"}) {
    const std::string value = Fact(s, {key});
    if (!value.empty()) html += fmt::format("<span>{} {}</span>", key, HtmlEscape(value));
  }
  if (run.layout == run::RunLayout::kEvaluate) {
    html +=
        fmt::format("<span>{} folds ({} failed)</span>", run.folds.size(), run.failed_folds.size());
  }
  html += fmt::format("<span>{} images compared of {}</span>", ok, run.images.size());
  if (s.is_object() && s.contains("cross_validated") && s["cross_validated"].is_boolean()) {
    html += fmt::format("<span class=\"cross-validated\">{}</span>",
                        s["cross_validated"].get<bool>() ? "cross-validated"
                                                         : "not cross-validated (a given model)");
  }
  std::string metric_list;
  for (const std::string& m : run.metrics) metric_list += (metric_list.empty() ? "" : ", ") + m;
  html += fmt::format("<span>metrics {}</span></p>\n", HtmlEscape(metric_list));

  std::vector<std::pair<std::string, std::string>> rows;
  // The outputs as they are on disk now: run.json is rewritten after the report (evaluate
  // writes the report before its final run.json), so its "outputs" may predate the
  // projection.
  std::vector<std::string> projected;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(run.dir / "projected", ec), end; !ec && it != end;
       it.increment(ec)) {
    if (it->path().extension() == ".ply") projected.push_back("projected/" + it->path().filename().string());
  }
  std::sort(projected.begin(), projected.end());
  if (run.run.is_object()) {
    Json j = run.run;
    // The invocation's own state (status, counters, timings, outputs) is what run.json
    // records of the process that is still writing this report: stale here, so left out
    // (run.json has the final values); the outputs come from the folder below.
    for (const char* key : {"status", "counters", "timings", "outputs"}) j.erase(key);
    // split.cross_validated says whether the split holds test photos out; whether the run is
    // cross-validated also depends on the model (a given model may have seen the test
    // photos): summary.json's "cross_validated" is the answer, shown here when they differ.
    if (s.is_object() && s.contains("cross_validated") && s["cross_validated"].is_boolean() &&
        j.contains("split") && j["split"].is_object() && j["split"].contains("cross_validated") &&
        j["split"]["cross_validated"] != s["cross_validated"]) {
      j["split"]["cross_validated"] = fmt::format(
          "{} (summary.json; the split {} test photos out, but {})",
          s["cross_validated"].get<bool>() ? "true" : "false",
          j["split"]["cross_validated"] == true ? "holds" : "does not hold",
          s["cross_validated"].get<bool>() ? "the model was reconstructed per fold"
                                           : "the model was given, not reconstructed per fold, "
                                             "and may have seen them");
    }
    Flatten(j, "run.json", 0, &rows);
  }
  rows.push_back({"outputs.projected (in the run folder)",
                  projected.empty() ? "(none)" : [&] {
                    std::string joined;
                    for (const std::string& p : projected) joined += (joined.empty() ? "" : ", ") + p;
                    return joined;
                  }()});
  if (s.is_object()) {
    // Everything but the results (shown in the tables) and the lists shown elsewhere.
    Json settings = Json::object();
    for (const auto& [key, value] : s.items()) {
      if (key == "metrics" || key == "completeness" || key == "missing" || key == "failed_folds" ||
          metrics::ParseMetric(key)) {
        continue;
      }
      settings[key] = value;
    }
    Flatten(settings, "summary.json", 0, &rows);
  }
  if (rows.empty()) return html;
  html += fmt::format(
      "<details{}><summary>Settings ({} entries from run.json and summary.json)"
      "</summary><table class=\"kv\"><tbody>\n",
      collapsed ? "" : " open", rows.size());
  for (const auto& [key, value] : rows) {
    html += fmt::format("<tr><td>{}</td><td class=\"path\">{}</td></tr>\n", HtmlEscape(key),
                        HtmlEscape(value));
  }
  return html + "</tbody></table></details>\n";
}

std::string ProblemsHtml(const run::RunData& run) {
  if (run.failed_folds.empty() && run.missing.empty()) return "";
  std::string html = "<div class=\"problems\">";
  if (!run.failed_folds.empty()) {
    html += fmt::format("<p><b>{} failed fold{}</b></p><ul class=\"failed-folds\">",
                        run.failed_folds.size(), run.failed_folds.size() == 1 ? "" : "s");
    for (const run::FailedFold& f : run.failed_folds) {
      html += fmt::format("<li><b>{}</b>: {}</li>", HtmlEscape(f.fold), HtmlEscape(f.message));
    }
    html += "</ul>";
  }
  if (!run.missing.empty()) {
    html += fmt::format("<p><b>{} image{} missing or failed</b></p><ul class=\"missing\">",
                        run.missing.size(), run.missing.size() == 1 ? "" : "s");
    constexpr size_t kShown = 50;
    for (size_t i = 0; i < run.missing.size() && i < kShown; ++i) {
      html += fmt::format("<li>{}</li>", HtmlEscape(run.missing[i]));
    }
    if (run.missing.size() > kShown) {
      html += fmt::format("<li>\u2026 and {} more (see the per-image table)</li>",
                          run.missing.size() - kShown);
    }
    html += "</ul>";
  }
  return html + "</div>\n";
}

std::string SummaryHtml(const run::RunData& run) {
  std::string html;
  if (run.AcrossFolds()) {
    html += fmt::format(
        "<h3>Across folds</h3><p class=\"muted\">Statistics of the {} ok folds' values "
        "(per_fold.csv: each fold's mean over its evaluated images).</p>\n",
        run.FoldValues(-1).size());
    html += SummaryTable(run, true);
    html += "<h3>Over images</h3>";
  }
  html += fmt::format(
      "<p class=\"muted\">Statistics of the per-image means of the {} compared images; "
      "\u2191 = higher is better; quartiles interpolate linearly; \u201cpooled\u201d is over all "
      "evaluated pixels of all images.</p>\n",
      run.ImageValues(-1).size());
  html += SummaryTable(run, false);
  return html;
}

std::string PerFoldTableHtml(const run::RunData& run) {
  if (run.layout != run::RunLayout::kEvaluate || run.folds.empty()) return "";
  std::string html =
      "<div class=\"scroll\"><table class=\"sortable per-fold\" id=\"per-fold\"><thead><tr>"
      "<th class=\"text\" data-col=\"fold\">fold</th><th class=\"text\" "
      "data-col=\"status\">status</th><th data-col=\"test_images\">test images</th>"
      "<th data-col=\"evaluated_images\">evaluated</th><th data-col=\"seconds\">seconds</th>"
      "<th data-col=\"completeness\">completeness</th>";
  for (const std::string& m : run.metrics) {
    html += fmt::format("<th data-col=\"{}\">{}</th>", HtmlEscape(m), HtmlEscape(MetricLabel(m)));
  }
  html += "<th class=\"text\" data-col=\"message\">message</th></tr></thead><tbody>\n";
  for (const run::FoldRow& fold : run.folds) {
    const bool ok = fold.status == "ok";
    html += fmt::format(
        "<tr data-fold=\"{0}\"{1}><td class=\"text\">{0}</td><td class=\"text{2}\">{3}</td>"
        "<td data-v=\"{4}\">{4}</td><td data-v=\"{5}\">{5}</td><td data-v=\"{6}\">{7}</td>"
        "<td data-v=\"{8}\">{9}</td>",
        HtmlEscape(fold.fold), ok ? "" : " class=\"bad\"", ok ? "" : " status-bad",
        HtmlEscape(fold.status), fold.test_images, fold.evaluated_images, DataNumber(fold.seconds),
        fmt::format("{:.1f}", fold.seconds), DataNumber(fold.completeness),
        DisplayNumber(fold.completeness));
    for (double v : fold.metrics) {
      html += fmt::format("<td data-v=\"{}\">{}</td>", DataNumber(v), DisplayNumber(v));
    }
    html += fmt::format("<td class=\"text\">{}</td></tr>\n", HtmlEscape(fold.message));
  }
  return html + "</tbody></table></div>\n";
}

std::string PerImageTableHtml(const run::RunData& run, const std::string& table_id) {
  const bool folds = run.layout == run::RunLayout::kEvaluate;
  std::string html =
      fmt::format("<div class=\"scroll\"><table class=\"sortable per-image\" id=\"{}\"><thead><tr>",
                  HtmlEscape(table_id));
  if (folds) html += "<th class=\"text\" data-col=\"fold\">fold</th>";
  html +=
      "<th class=\"text\" data-col=\"name\">name</th><th class=\"text\" "
      "data-col=\"status\">status</th><th data-col=\"size\">size</th>"
      "<th data-col=\"completeness\">completeness</th>";
  for (const std::string& m : run.metrics) {
    html += fmt::format("<th data-col=\"{}\">{}</th>", HtmlEscape(m), HtmlEscape(MetricLabel(m)));
  }
  html += "</tr></thead><tbody>\n";
  for (const run::ImageRow& image : run.images) {
    const bool ok = image.status == "ok";
    html +=
        fmt::format("<tr data-name=\"{}\"{}>", HtmlEscape(image.name), ok ? "" : " class=\"bad\"");
    if (folds) html += fmt::format("<td class=\"text\">{}</td>", HtmlEscape(image.fold));
    html += fmt::format("<td class=\"text\">{}</td><td class=\"text{}\">{}</td>",
                        HtmlEscape(image.name), ok ? "" : " status-bad", HtmlEscape(image.status));
    if (image.width > 0 && image.height > 0) {
      html +=
          fmt::format("<td data-v=\"{}\">{}\u00d7{}</td>",
                      static_cast<int64_t>(image.width) * image.height, image.width, image.height);
    } else {
      html += "<td data-v=\"\"></td>";
    }
    html += fmt::format("<td data-v=\"{}\">{}</td>", DataNumber(image.completeness),
                        ok ? DisplayNumber(image.completeness) : "");
    for (double v : image.metrics) {
      html += fmt::format("<td data-v=\"{}\">{}</td>", DataNumber(v), ok ? DisplayNumber(v) : "");
    }
    html += "</tr>\n";
  }
  return html + "</tbody></table></div>\n";
}

std::string ExamplesHtml(const run::RunData& run, int metric, int count, int thumbnail_width) {
  if (metric < 0 || count <= 0) return "";
  const std::string& name = run.metrics[metric];
  const auto parsed = metrics::ParseMetric(name);
  if (!parsed) return "";
  const bool higher_better = metrics::HigherIsBetter(*parsed);
  std::vector<const run::ImageRow*> candidates;
  for (const run::ImageRow& image : run.images) {
    if (image.status == "ok" && !std::isnan(image.metrics[metric])) candidates.push_back(&image);
  }
  if (candidates.empty()) {
    return fmt::format("<p class=\"muted\">No image has a {} value.</p>\n", HtmlEscape(name));
  }
  // Worst first; ties by fold and name for a deterministic choice.
  std::stable_sort(candidates.begin(), candidates.end(), [&](const run::ImageRow* a, const run::ImageRow* b) {
    const double x = a->metrics[metric], y = b->metrics[metric];
    if (x != y) return higher_better ? x < y : x > y;
    return std::tie(a->fold, a->name) < std::tie(b->fold, b->name);
  });
  const size_t n = candidates.size();
  const size_t worst = std::min<size_t>(count, (n + 1) / 2);
  const size_t best = std::min<size_t>(count, n - worst);
  std::vector<std::pair<std::string, const run::ImageRow*>> shown;
  for (size_t i = 0; i < worst; ++i)
    shown.push_back({fmt::format("worst #{}", i + 1), candidates[i]});
  for (size_t i = 0; i < best; ++i) {
    shown.push_back({fmt::format("best #{}", i + 1), candidates[n - 1 - i]});
  }
  const auto [low, high] = compare::ErrorColourRange(*parsed);
  const std::string bar = JetColourBarSvg(low, high, name + " error", 220);
  std::string html;
  // Thumbnails of all shown images in parallel (decoding full-size photos dominates).
  struct Thumbnails {
    Thumbnail photo, rephoto, mask, error;
  };
  std::vector<Thumbnails> thumbnails(shown.size());
  ForEachThumbnailJob(static_cast<int64_t>(shown.size()), [&](int64_t i,
                                                               ThumbnailScratch* scratch) {
    const run::ImageRow& image = *shown[i].second;
    const std::filesystem::path errors = run.ImageDir(image) / "errors";
    const std::string stem = image.name + "." + name;
    Thumbnails& t = thumbnails[i];
    RenderThumbnails(run.RenderPath(image), thumbnail_width, &t.rephoto, &t.mask, scratch);
    t.photo = PhotoThumbnail(run.PhotoPath(image), thumbnail_width, scratch);
    t.error = ErrorThumbnail(errors / (stem + ".exr"), errors / (stem + ".png"), *parsed,
                             thumbnail_width, scratch);
  });
  for (size_t i = 0; i < shown.size(); ++i) {
    const std::string& rank = shown[i].first;
    const run::ImageRow* image = shown[i].second;
    const Thumbnails& t = thumbnails[i];
    html += fmt::format(
        "<div class=\"example\" data-rank=\"{}\" data-name=\"{}\"><h4>{}: {}{} \u2014 {} {}, "
        "completeness {}</h4><div class=\"images\">",
        HtmlEscape(rank), HtmlEscape(image->name), HtmlEscape(rank),
        image->fold.empty() ? "" : HtmlEscape(image->fold) + " / ", HtmlEscape(image->name),
        HtmlEscape(name), DisplayNumber(image->metrics[metric]),
        DisplayNumber(image->completeness));
    html += Figure(t.photo, "photo", "photo");
    html += Figure(t.rephoto, "rephoto", "rephoto");
    html += Figure(t.mask, "mask (rephoto alpha, white = covered)", "mask");
    html += Figure(t.error,
                   fmt::format("{} error, range {} to {} (grey checkerboard = not evaluated)", name,
                               DisplayNumber(low), DisplayNumber(high)),
                   "error", bar);
    html += "</div></div>\n";
  }
  return html;
}

}  // namespace rephoto::report::internal
