#include "rephoto/suggest/suggest_page.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/report/html.h"
#include "rephoto/report/report_page.h"
#include "rephoto/report/thumbnails.h"

namespace rephoto::suggest {
namespace fs = std::filesystem;
using report::DataNumber;
using report::DisplayNumber;
using report::HtmlEscape;
using report::RenderThumbnails;
using report::Thumbnail;
namespace internal = report::internal;
using Json = nlohmann::json;

namespace {

double Number(const Json& j, const char* key) {
  const Json v = j.value(key, Json());
  return v.is_number() ? v.get<double>() : NAN;
}

std::string Vector(const Json& j, const char* key) {
  const Json v = j.value(key, Json());
  if (!v.is_array()) return "\u2013";
  std::string text;
  for (const Json& x : v) {
    text += (text.empty() ? "" : ", ") +
            (x.is_number() ? fmt::format("{:.4g}", x.get<double>()) : std::string("?"));
  }
  return "(" + text + ")";
}

std::string Percent(double part, double whole) {
  return whole > 0 && std::isfinite(part) ? fmt::format("{:.1f} %", 100 * part / whole) : "\u2013";
}

}  // namespace

std::string SuggestionsSectionHtml(const fs::path& dir, int thumbnail_width, int heading_level) {
  const fs::path file = dir / "suggestions.json";
  Json json;
  try {
    json = Json::parse(ReadFileToString(file));
  } catch (const Json::exception& e) {
    throw Error(fmt::format("{}: not valid JSON: {}", file.string(), e.what()));
  }
  REPHOTO_CHECK(json.is_object() && json.contains("suggestions") && json["suggestions"].is_array(),
                "{}: expected an object with a \"suggestions\" list", file.string());
  const double total = Number(json, "total_area");
  const double unobserved = Number(json, "unobserved_area");
  const double covered = Number(json, "unobserved_area_covered");
  const std::string h = fmt::format("h{}", std::clamp(heading_level, 1, 6));
  std::string html = "<p class=\"meta\">";
  for (const char* key : {"scene", "model", "run"}) {
    const Json v = json.value(key, Json());
    if (v.is_string()) {
      html += fmt::format("<span>{} {}</span>", key, HtmlEscape(v.get<std::string>()));
    }
  }
  html += "</p>\n";
  html += fmt::format(
      "<section id=\"suggest-summary\"><{0}>Coverage</{0}><p>{1} of the model's surface is seen "
      "by no photo; the {2} suggested views see <strong>{3}</strong> of it together.</p><p "
      "class=\"muted\">Each suggestion is a pose at the photos' distance from the model, "
      "chosen greedily to see the most unseen or high-error surface not seen by the earlier "
      "suggestions. The rephoto shows what to photograph.</p></section>\n",
      h, Percent(unobserved, total), json["suggestions"].size(), Percent(covered, unobserved));
  html += fmt::format(
      "<section id=\"suggestions\"><{0}>Suggested views</{0}>\n<table "
      "id=\"suggestions-table\"><thead><tr><th class=\"text\">view</th><th "
      "class=\"text\">rephoto</th><th class=\"text\">pose</th><th>unseen surface "
      "covered</th><th>vertices seen</th><th>mean error</th></tr></thead><tbody>\n",
      h);
  for (const Json& s : json["suggestions"]) {
    REPHOTO_CHECK(s.is_object() && s.value("name", Json()).is_string(),
                  "{}: a suggestion without a name", file.string());
    const std::string name = s["name"].get<std::string>();
    const fs::path p = name;
    REPHOTO_CHECK(!name.empty() && p.is_relative() && p == p.filename() && name != "." &&
                      name != ".." && name.find('\\') == std::string::npos,
                  "{}: suggestion name \"{}\" is not a plain file name", file.string(), name);
    Thumbnail rephoto, mask;
    RenderThumbnails(dir / "renders" / p, thumbnail_width, &rephoto, &mask);
    const std::string image =
        rephoto.data_uri.empty()
            ? "<span class=\"muted\">" + HtmlEscape(rephoto.error) + "</span>"
            : fmt::format("<img src=\"{}\" width=\"{}\" height=\"{}\" alt=\"{}\">",
                          rephoto.data_uri, rephoto.width, rephoto.height, HtmlEscape(name));
    const double area = Number(s, "unobserved_area");
    const double mean_error = Number(s, "mean_error");
    html += fmt::format(
        "<tr class=\"suggestion\" data-name=\"{0}\" data-unobserved-area=\"{1}\" "
        "data-mean-error=\"{2}\"><td class=\"text\">{0}</td><td class=\"text\">{3}</td><td "
        "class=\"text\">centre {4}<br>qvec {5}<br>tvec {6}</td><td>{7} ({8})</td><td>{9}</td>"
        "<td>{10}</td></tr>\n",
        HtmlEscape(name), DataNumber(area), DataNumber(mean_error), image, Vector(s, "center"),
        Vector(s, "qvec"), Vector(s, "tvec"), DisplayNumber(area), Percent(area, unobserved),
        std::isfinite(Number(s, "visible_vertices"))
            ? fmt::format("{:.0f}", Number(s, "visible_vertices"))
            : "\u2013",
        DisplayNumber(mean_error));
  }
  html += "</tbody></table></section>\n";
  return html;
}

void WriteSuggestionsReport(const fs::path& dir, const fs::path& out_html, int thumbnail_width) {
  const std::string title = "rephoto suggest: the next photos to take";
  const std::string html = internal::PageStart(title) +
                           fmt::format("<header><h1>{}</h1></header>\n", HtmlEscape(title)) +
                           SuggestionsSectionHtml(dir, thumbnail_width, 2) + internal::PageEnd();
  WriteTextFileAtomically(out_html, html);
}

}  // namespace rephoto::suggest
