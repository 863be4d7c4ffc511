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
#include "rephoto/report/view3d.h"

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

// "(x, y, z)" of a 3-vector entry, 4 significant digits; "" when absent or malformed.
std::string Point(const Json& j, const char* key) {
  const Json v = j.value(key, Json());
  if (!v.is_array() || v.size() != 3) return "";
  for (const Json& x : v) {
    if (!x.is_number()) return "";
  }
  return Vector(j, key);
}

// An area in model units² with 4 significant digits.
std::string Area(double area) { return std::isfinite(area) ? DisplayNumber(area) + " units\u00b2" : "\u2013"; }

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
  // "schema": "rephoto.suggest/1"; files of earlier versions say "version": 1.
  const Json schema = json.value("schema", Json());
  const Json version = json.value("version", Json());
  REPHOTO_CHECK((schema.is_string() && schema.get<std::string>() == "rephoto.suggest/1") ||
                    (schema.is_null() && version.is_number() && version.get<double>() == 1),
                "{}: not a suggestions file of this version (expected \"schema\": "
                "\"rephoto.suggest/1\")",
                file.string());
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
      "<section id=\"suggest-summary\"><{0}>Coverage</{0}><p>{1} of the model's surface ({4} of "
      "{5}) is seen by no photo; the {2} suggested views see <strong>{3}</strong> of it "
      "together.</p><p "
      "class=\"muted\">Each suggestion is a pose at the photos' distance from the model, "
      "chosen greedily to see the most unseen or high-error surface not seen by the earlier "
      "suggestions. The rephoto shows what to photograph.</p></section>\n",
      h, Percent(unobserved, total), json["suggestions"].size(), Percent(covered, unobserved),
      Area(unobserved), Area(total));
  html += fmt::format(
      "<section id=\"suggestions\"><{0}>Suggested views</{0}>\n<table "
      "id=\"suggestions-table\"><thead><tr><th class=\"text\">view</th><th "
      "class=\"text\">rephoto</th><th class=\"text\">where to stand (scene units)</th><th>unseen "
      "surface it covers</th><th>vertices seen</th><th>mean error</th></tr></thead><tbody>\n",
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
    std::string look_at = Point(s, "look_at");
    if (look_at.empty()) look_at = Point(json, "target");  // files without look_at
    const std::string where =
        fmt::format("camera at {}{}", Vector(s, "center"),
                    look_at.empty() ? "" : " looking at " + look_at);
    html += fmt::format(
        "<tr class=\"suggestion\" data-name=\"{0}\" data-unobserved-area=\"{1}\" "
        "data-mean-error=\"{2}\"><td class=\"text\">{0}</td><td class=\"text\">{3}</td><td "
        "class=\"text\"><span class=\"where\">{4}</span><br><span class=\"muted\">COLMAP qvec "
        "{5}, tvec {6}</span></td><td class=\"text\">{7}<br>{8} of the unseen surface, {11} of "
        "the whole</td><td>{9}</td><td>{10}</td></tr>\n",
        HtmlEscape(name), DataNumber(area), DataNumber(mean_error), image, where,
        Vector(s, "qvec"), Vector(s, "tvec"), Area(area), Percent(area, unobserved),
        std::isfinite(Number(s, "visible_vertices"))
            ? fmt::format("{:.0f}", Number(s, "visible_vertices"))
            : "\u2013",
        DisplayNumber(mean_error), Percent(area, total));
  }
  html += "</tbody></table></section>\n";
  return html;
}

void WriteSuggestionsReport(const fs::path& dir, const fs::path& out_html, int thumbnail_width,
                            const report::View3dData* view) {
  const std::string title = "rephoto suggest: the next photos to take";
  std::string html = internal::PageStart(title) +
                     fmt::format("<header><h1>{}</h1></header>\n", HtmlEscape(title)) +
                     SuggestionsSectionHtml(dir, thumbnail_width, 2);
  if (view != nullptr) {
    html +=
        "<section id=\"view3d-section\"><h2>The model, the photos and the suggested "
        "views</h2><p class=\"muted\">Magenta frusta: the suggested views; \u201cseen by no "
        "photo\u201d shows the surface they are meant to cover.</p>\n" +
        report::View3dHtml(*view, "view3d") + "</section>\n" + report::View3dScripts();
  }
  html += internal::PageEnd();
  WriteTextFileAtomically(out_html, html);
}

}  // namespace rephoto::suggest
