#include "rephoto/benchmark/pages.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "rephoto/benchmark/api.h"
#include "rephoto/benchmark/submissions.h"
#include "rephoto/compare/compare.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/report/boxplot.h"
#include "rephoto/report/html.h"

namespace rephoto::benchmark {
namespace {

using report::HtmlEscape;

// Sorting by clicking a header of a table.sortable: numbers by value (data-value), else text.
const char* const kSortScript = R"js(
document.querySelectorAll('table.sortable th').forEach((th, column) => {
  th.addEventListener('click', () => {
    const body = th.closest('table').tBodies[0];
    const up = th.dataset.order !== 'asc';
    th.dataset.order = up ? 'asc' : 'desc';
    const key = row => {
      const cell = row.cells[column];
      const v = cell.dataset.value;
      return v === undefined ? cell.textContent : (v === '' ? NaN : Number(v));
    };
    const rows = Array.from(body.rows);
    rows.sort((a, b) => {
      const x = key(a), y = key(b);
      if (typeof x === 'number' && typeof y === 'number') {
        if (isNaN(x) || isNaN(y)) return isNaN(x) - isNaN(y);
        return up ? x - y : y - x;
      }
      return up ? String(x).localeCompare(y) : String(y).localeCompare(x);
    });
    rows.forEach(row => body.appendChild(row));
  });
});
)js";

std::string Page(const std::string& title, const std::string& body) {
  return fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
      "<meta name=\"viewport\" content=\"width=device-width\"><link rel=\"icon\" href=\"data:,\">"
      "<title>{0}</title><style>"
      "body{{font-family:sans-serif;margin:1.5em;max-width:70em}}"
      "table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:.2em .5em}}"
      "th{{cursor:pointer;background:#eee}}td.num{{text-align:right}}"
      "pre{{background:#f4f4f4;padding:.5em;overflow-x:auto}}img.err{{max-width:240px}}"
      "</style></head><body><nav><a href=\"/\">datasets</a></nav><h1>{0}</h1>\n{1}"
      "<script>{2}</script></body></html>\n",
      HtmlEscape(title), body, kSortScript);
}

std::string NumberCell(const nlohmann::json& value) {
  const double number = JsonNumber(value);
  return fmt::format("<td class=\"num\" data-value=\"{}\">{}</td>",
                     std::isnan(number) ? "" : report::DataNumber(number),
                     report::DisplayNumber(number));
}

// Percent-encodes everything but unreserved characters (for metric names like "cb+cr").
std::string UrlComponent(const std::string& text) {
  std::string out;
  for (unsigned char c : text) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~') {
      out += static_cast<char>(c);
    } else {
      out += fmt::format("%{:02X}", c);
    }
  }
  return out;
}

std::string FileLinks(const nlohmann::json& files) {
  std::string html = "<ul class=\"downloads\">";
  for (const auto& file : files) {
    html += fmt::format(
        "<li><a href=\"{}\">{}</a> ({} bytes)</li>", HtmlEscape(file.at("url").get<std::string>()),
        HtmlEscape(file.at("name").get<std::string>()), file.at("size").get<int64_t>());
  }
  return html + "</ul>";
}

// Header cells "<metric> mean" of the dataset's other metrics, sorted by name: the order in
// which nlohmann::json iterates a summary's metrics, as the rows write them.
std::string OtherMetricHeaders(Store& store, const std::string& dataset_name,
                               const std::string& headline) {
  const auto dataset = store.FindDataset(dataset_name);
  std::vector<std::string> names;
  for (const auto& metric : dataset->info.at("settings").at("metrics")) {
    if (metric != headline) names.push_back(metric.get<std::string>());
  }
  std::sort(names.begin(), names.end());
  std::string html;
  for (const std::string& metric : names) html += "<th>" + HtmlEscape(metric) + " mean</th>";
  return html;
}

}  // namespace

std::string DatasetListPage(Store& store) {
  std::string body =
      "<table class=\"sortable\" id=\"datasets\"><thead><tr><th>dataset</th><th>training "
      "photos</th><th>test cameras</th><th>leaderboard</th></tr></thead><tbody>";
  for (const auto& dataset : DatasetListJson(store)) {
    const std::string name = dataset.at("name");
    body += fmt::format(
        "<tr><td><a href=\"/datasets/{0}\">{1}</a><br>{2}</td><td class=\"num\">{3}</td>"
        "<td class=\"num\">{4}</td><td><a href=\"/datasets/{0}/leaderboard\">leaderboard</a>"
        "</td></tr>",
        UrlComponent(name), HtmlEscape(name),
        HtmlEscape(dataset.at("description").get<std::string>()),
        dataset.at("training_images").get<int>(), dataset.at("test_images").get<int>());
  }
  return Page("Benchmark datasets", body + "</tbody></table>");
}

std::optional<std::string> DatasetPage(Store& store, const std::string& name) {
  const auto dataset = DatasetJson(store, name);
  if (!dataset) return std::nullopt;
  const std::string url_name = UrlComponent(name);
  std::string body = fmt::format("<p>{}</p><h2>Downloads</h2>{}",
                                 HtmlEscape(dataset->at("description").get<std::string>()),
                                 FileLinks(dataset->at("files")));
  const auto& settings = dataset->at("settings");
  body += fmt::format(
      "<h2>Evaluation</h2><p>Metrics: {}; headline metric <b>{}</b>; window {}. "
      "<a href=\"/datasets/{}/leaderboard\">Leaderboard</a></p>",
      HtmlEscape(settings.at("metrics").dump()),
      HtmlEscape(settings.at("headline").get<std::string>()), settings.at("window").get<int>(),
      url_name);
  body += fmt::format(
      "<h2>How to submit</h2><p>Render every test camera of <code>test-cameras.tar</code> "
      "(COLMAP text or transforms.json) as an RGBA PNG (alpha = rendered), JPEG or EXR named by "
      "its stem (<code>test_images.txt</code>), at the camera's size, pack them in a .tar or "
      ".zip and post it with your token:</p><pre>tar cf renders.tar -C renders .\n"
      "curl -H 'Authorization: Bearer TOKEN' --data-binary @renders.tar \\\n"
      "  'http://HOST/api/datasets/{}/submissions?method=MyMethod'\n"
      "curl http://HOST/api/submissions/ID</pre>",
      url_name);
  body +=
      "<h2>Test cameras</h2><table class=\"sortable\" id=\"test-images\"><thead><tr><th>stem"
      "</th><th>width</th><th>height</th></tr></thead><tbody>";
  for (const auto& image : dataset->at("test_images")) {
    body += fmt::format(
        "<tr><td>{}</td><td class=\"num\" data-value=\"{}\">{}</td>"
        "<td class=\"num\" data-value=\"{}\">{}</td></tr>",
        HtmlEscape(image.at("stem").get<std::string>()), image.at("width").get<int>(),
        image.at("width").get<int>(), image.at("height").get<int>(), image.at("height").get<int>());
  }
  return Page("Dataset " + name, body + "</tbody></table>");
}

std::optional<std::string> LeaderboardPage(Store& store, const std::string& name) {
  const auto board = LeaderboardJson(store, name);
  if (!board) return std::nullopt;
  const std::string headline = board->at("headline");
  std::string body = fmt::format(
      "<p>Ordered by the mean of <b>{}</b> over the test photos ({}); completeness is over all "
      "test photos (a missing render counts as not covered).</p>"
      "<table class=\"sortable\" id=\"leaderboard\"><thead><tr><th>rank</th><th>method</th>"
      "<th>participant</th><th>{} mean</th><th>{} median</th><th>completeness</th>{}</tr>"
      "</thead><tbody>",
      HtmlEscape(headline), board->at("higher_is_better") ? "higher is better" : "lower is better",
      HtmlEscape(headline), HtmlEscape(headline), OtherMetricHeaders(store, name, headline));
  report::BoxPlot plot{.title = headline + " per test photo", .y_label = headline};
  for (const auto& entry : board->at("entries")) {
    const std::string id = entry.at("id");
    std::string others;
    for (const auto& [metric, mean] : entry.at("metrics").items()) {
      if (metric != headline) others += NumberCell(mean);
    }
    body += fmt::format(
        "<tr data-id=\"{}\"><td class=\"num\" data-value=\"{}\">{}</td>"
        "<td><a href=\"/submissions/{}\">{}</a></td><td>{}</td>{}{}{}{}</tr>",
        id, entry.at("rank").get<int>(), entry.at("rank").get<int>(), id,
        HtmlEscape(entry.at("method").get<std::string>()),
        HtmlEscape(entry.at("participant").get<std::string>()),
        NumberCell(entry.at("headline").at("mean")), NumberCell(entry.at("headline").at("median")),
        NumberCell(entry.at("completeness")), others);
    const auto submission = SubmissionJson(store, id);
    report::BoxPlotBox box{.category = static_cast<int>(plot.categories.size())};
    for (const auto& row : submission->at("images")) {
      if (row.contains(headline)) box.values.push_back(JsonNumber(row.at(headline)));
    }
    plot.categories.push_back(entry.at("method").get<std::string>());
    plot.boxes.push_back(std::move(box));
  }
  body += "</tbody></table>";
  if (!plot.boxes.empty()) body += "<h2>Per-photo errors</h2>" + report::BoxPlotSvg(plot);
  return Page("Leaderboard " + name, body);
}

std::optional<std::string> SubmissionPage(Store& store, const std::string& id) {
  const auto submission = SubmissionJson(store, id);
  if (!submission) return std::nullopt;
  const std::string status = submission->at("status");
  std::string body = fmt::format(
      "<p>Dataset <a href=\"/datasets/{0}\">{1}</a> (<a href=\"/datasets/{0}/leaderboard\">"
      "leaderboard</a>), method <b>{2}</b> by {3}.</p><p>Status: <b id=\"status\">{4}</b> {5}"
      "</p><p>{6}</p>",
      UrlComponent(submission->at("dataset").get<std::string>()),
      HtmlEscape(submission->at("dataset").get<std::string>()),
      HtmlEscape(submission->at("method").get<std::string>()),
      HtmlEscape(submission->at("participant").get<std::string>()), HtmlEscape(status),
      HtmlEscape(submission->at("reason").get<std::string>()),
      HtmlEscape(submission->at("description").get<std::string>()));
  if (status != "done") return Page("Submission " + id, body);
  const auto dataset = store.FindDataset(submission->at("dataset"));
  const nlohmann::json& settings = dataset->info.at("settings");
  const std::string headline = settings.at("headline");
  body +=
      "<h2>Per test photo</h2><table class=\"sortable\" id=\"images\"><thead><tr>"
      "<th>name</th><th>status</th><th>completeness</th>";
  for (const auto& metric : settings.at("metrics")) {
    body += "<th>" + HtmlEscape(metric.get<std::string>()) + "</th>";
  }
  body += "<th>" + HtmlEscape(headline) + " error</th></tr></thead><tbody>";
  const auto [low, high] = compare::ErrorColourRange(*metrics::ParseMetric(headline));
  for (const auto& row : submission->at("images")) {
    const std::string name = row.at("name");
    body += "<tr><td>" + HtmlEscape(name) + "</td><td>" +
            HtmlEscape(row.at("status").get<std::string>()) + "</td>" +
            NumberCell(row.value("completeness", nlohmann::json()));
    for (const auto& metric : settings.at("metrics")) {
      body += NumberCell(row.value(metric.get<std::string>(), nlohmann::json()));
    }
    const bool has_error_image = ErrorImagePath(store, id, name + "." + headline).has_value();
    body += has_error_image ? fmt::format(
                                  "<td><img class=\"err\" alt=\"{0} error of {1}\" "
                                  "src=\"/api/submissions/{2}/errors/{3}.{4}.png\"></td></tr>",
                                  HtmlEscape(headline), HtmlEscape(name), id, UrlComponent(name),
                                  UrlComponent(headline))
                            : "<td></td></tr>";
  }
  body += "</tbody></table><p>Error images: " + report::JetColourBarSvg(low, high, headline) +
          " (transparent: not evaluated). They show the error of the uploaded renders against "
          "the secret photos, never the photos.</p>";
  return Page("Submission " + id, body);
}

std::string NotFoundPage() { return Page("Not found", "<p>There is no such page.</p>"); }

std::optional<std::filesystem::path> ErrorImagePath(Store& store, const std::string& id,
                                                    const std::string& stem_and_metric) {
  if (!IsSubmissionId(id)) return std::nullopt;
  const size_t dot = stem_and_metric.rfind('.');
  if (dot == std::string::npos) return std::nullopt;
  const std::string stem = stem_and_metric.substr(0, dot);
  const std::string metric = stem_and_metric.substr(dot + 1);
  const auto submission = store.FindSubmission(id);
  if (!submission || submission->status != SubmissionStatus::kDone) return std::nullopt;
  const auto dataset = store.FindDataset(submission->dataset);
  if (!dataset) return std::nullopt;
  bool known_stem = false, known_metric = false;
  for (const auto& image : dataset->info.at("test_images")) known_stem |= image.at("stem") == stem;
  for (const auto& name : dataset->info.at("settings").at("metrics"))
    known_metric |= name == metric;
  if (!known_stem || !known_metric) return std::nullopt;
  const std::filesystem::path path =
      SubmissionRunFolder(store.root(), id) / "errors" / (stem + "." + metric + ".png");
  if (!std::filesystem::is_regular_file(path)) return std::nullopt;
  return path;
}

}  // namespace rephoto::benchmark
