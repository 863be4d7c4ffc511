#include "rephoto/service/pages.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "rephoto/service/api.h"
#include "rephoto/service/submissions.h"
#include "rephoto/compare/compare.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/report/html.h"

namespace rephoto::service {
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
      "curl -H 'Authorization: Bearer TOKEN' -H 'Content-Type: application/x-tar' \\\n"
      "  --data-binary @renders.tar \\\n"
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
  const auto& photos = board->at("photos");
  std::string body = fmt::format(
      "<p id=\"ranking\">Ranking rule <b>{}</b>: {} ({}). Scores over {} {} test photos; "
      "completeness is over those photos (a missing render counts as not covered). Each "
      "participant's best submission per method is shown.</p>"
      "<table class=\"sortable\" id=\"leaderboard\"><thead><tr><th>rank</th><th>method</th>"
      "<th>participant</th><th>{} filled</th><th>{} mean (covered)</th><th>completeness</th>{}"
      "</tr></thead><tbody>",
      HtmlEscape(board->at("ranking").at("rule").get<std::string>()),
      HtmlEscape(board->at("ranking").at("text").get<std::string>()),
      board->at("higher_is_better") ? "higher is better" : "lower is better",
      photos.at("count").get<size_t>(),
      photos.at("subset") == "all" ? "" : HtmlEscape(photos.at("subset").get<std::string>()),
      HtmlEscape(headline), HtmlEscape(headline), OtherMetricHeaders(store, name, headline));
  const auto row = [&](const nlohmann::json& entry, const std::string& rank) {
    const std::string id = entry.at("id");
    std::string others;
    for (const auto& [metric, mean] : entry.at("metrics").items()) {
      if (metric != headline) others += NumberCell(mean);
    }
    return fmt::format(
        "<tr data-id=\"{}\"><td class=\"num\" data-value=\"{}\">{}</td>"
        "<td><a href=\"/submissions/{}\">{}</a></td><td>{}</td>{}{}{}{}</tr>",
        id, rank, rank, id, HtmlEscape(entry.at("method").get<std::string>()),
        HtmlEscape(entry.at("participant").get<std::string>()),
        NumberCell(entry.at("headline").at("filled")), NumberCell(entry.at("headline").at("mean")),
        NumberCell(entry.at("completeness")), others);
  };
  for (const auto& entry : board->at("entries")) {
    body += row(entry, std::to_string(entry.at("rank").get<int>()));
  }
  body += "</tbody></table>";
  if (!board->at("unranked").empty()) {
    body += "<h2>Below the minimum completeness (not ranked)</h2><table id=\"unranked\"><tbody>";
    for (const auto& entry : board->at("unranked")) body += row(entry, "-");
    body += "</tbody></table>";
  }
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
  if (status != "done" || !submission->contains("scores")) return Page("Submission " + id, body);
  // Aggregates only: per-photo numbers are for the participant, through the API with its token.
  body +=
      "<h2>Scores</h2><table id=\"scores\"><thead><tr><th>photos</th><th>count</th>"
      "<th>completeness</th><th>metric</th><th>mean (covered)</th><th>filled</th></tr></thead>"
      "<tbody>";
  for (const auto& [subset, scores] : submission->at("scores").items()) {
    for (const auto& [metric, mean] : scores.at("means").items()) {
      body +=
          fmt::format("<tr><td>{}</td><td class=\"num\">{}</td>{}<td>{}</td>{}{}</tr>",
                      HtmlEscape(subset), scores.at("photos").get<size_t>(),
                      NumberCell(scores.at("completeness")), HtmlEscape(metric), NumberCell(mean),
                      NumberCell(scores.at("filled").value(metric, nlohmann::json())));
    }
  }
  body += "</tbody></table>";
  return Page("Submission " + id, body);
}

std::string NotFoundPage() { return Page("Not found", "<p>There is no such page.</p>"); }

}  // namespace rephoto::service
