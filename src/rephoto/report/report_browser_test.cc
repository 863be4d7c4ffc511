// Opens generated reports in headless Chromium (Debian `chromium`) and checks the DOM after the
// scripts ran: no console messages or uncaught exceptions, the table rows and SVG plots are
// there, and sorting by a column works (through the "#sort=" hook, which clicks the header).
// Chromium is required: when it is missing the test fails and says how to install it.
//
// Chromium's startup dominates (about 2 s on an idle 2-core machine, 6-7 s under a load of 10),
// so the browser is started once: a harness page loads the three pages in iframes
// (--allow-file-access-from-files lets it read their DOM after their scripts ran) and copies
// each DOM into a <script type="text/plain"> element, which --dump-dom serialises verbatim.
// Console messages of all frames go to the log with their source file.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <regex>
#include <sstream>

#include "rephoto/core/file.h"
#include "rephoto/report/html.h"
#include "rephoto/report/report.h"
#include "rephoto/report/report_fixture.h"
#include "rephoto/testing/testing.h"

namespace rephoto::report {
namespace {
namespace fs = std::filesystem;

std::string FindChromium() {
  const char* path = std::getenv("PATH");
  std::stringstream folders(path ? path : "/usr/bin:/bin");
  std::string folder;
  while (std::getline(folders, folder, ':')) {
    for (const char* name : {"chromium", "chromium-browser"}) {
      const fs::path candidate = fs::path(folder) / name;
      std::error_code ec;
      if (fs::is_regular_file(candidate, ec)) return candidate.string();
    }
  }
  return "";
}

struct BrowserResult {
  int status = -1;
  std::string dom;  // --dump-dom of the harness: the DOM after the scripts ran
  std::string log;  // stderr with --enable-logging=stderr --v=0
};

// Loads `url` in a fresh headless Chromium with a private profile in `work`.
BrowserResult DumpDom(const std::string& chromium, const std::string& url, const fs::path& work) {
  const fs::path profile = work / "chromium-profile";
  const fs::path dom = work / "dom.html";
  const fs::path log = work / "chromium.log";
  fs::create_directories(profile);
  const std::string command =
      "timeout 120 '" + chromium +
      "' --headless --no-sandbox --disable-gpu --no-first-run --no-default-browser-check "
      "--disable-extensions --disable-background-networking --disable-component-update "
      "--disable-sync --mute-audio --allow-file-access-from-files --user-data-dir='" +
      profile.string() + "' --enable-logging=stderr --v=0 --dump-dom '" + url + "' > '" +
      dom.string() + "' 2> '" + log.string() + "'";
  BrowserResult result;
  result.status = std::system(command.c_str());
  result.dom = fs::exists(dom) ? ReadFileToString(dom) : "";
  result.log = fs::exists(log) ? ReadFileToString(log) : "";
  return result;
}

// The console lines of the log ("...:CONSOLE...] "message", source: file:///... (line)") whose
// source is `file` (all sources when empty).
std::string ConsoleLines(const std::string& log, const std::string& file) {
  std::string lines;
  std::stringstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    if (line.find(":CONSOLE") == std::string::npos) continue;
    if (!file.empty() && line.find("source: file://" + file) == std::string::npos) continue;
    lines += line + "\n";
  }
  return lines;
}

// The harness: loads each (name, url) in an iframe and, on load, copies the iframe's DOM into
// <script type="text/plain" id="dom-NAME"> followed by an end marker.
std::string HarnessHtml(const std::vector<std::pair<std::string, std::string>>& pages) {
  std::string html = "<!DOCTYPE html><html><head><meta charset=\"utf-8\"></head><body>\n";
  std::string names;
  for (const auto& [name, url] : pages) {
    html += "<iframe id=\"f-" + name + "\" src=\"" + url + "\"></iframe>\n";
    names += (names.empty() ? "'" : ",'") + name + "'";
  }
  html += "<script>window.addEventListener('load', function () {[" + names +
          "].forEach(function (name) {var out = document.createElement('script');"
          "out.type = 'text/plain'; out.id = 'dom-' + name; var text;"
          "try { text = document.getElementById('f-' + name).contentDocument.documentElement"
          ".outerHTML; } catch (e) { text = 'HARNESS-ERROR ' + e; }"
          "out.textContent = text + '\\n<!--END-dom-' + name + '-->';"
          "document.body.appendChild(out);});});</script></body></html>\n";
  return html;
}

// The DOM of one page from the harness dump ("" when absent).
std::string PageDom(const std::string& dump, const std::string& name) {
  const std::string begin = "id=\"dom-" + name + "\">";
  const std::string end = "<!--END-dom-" + name + "-->";
  const size_t a = dump.find(begin);
  if (a == std::string::npos) return "";
  const size_t b = dump.find(end, a);
  if (b == std::string::npos) return "";
  return dump.substr(a + begin.size(), b - a - begin.size());
}

std::string FileUrl(const fs::path& path, const std::string& fragment) {
  return "file://" + fs::absolute(path).string() + fragment;
}

// data-name of the rows of the table with id `id`, in DOM order.
std::vector<std::string> RowNames(const std::string& dom, const std::string& id) {
  const size_t start = dom.find("id=\"" + id + "\"");
  if (start == std::string::npos) return {};
  const size_t end = dom.find("</table>", start);
  const std::string table = dom.substr(start, end - start);
  std::vector<std::string> names;
  const std::regex row("<tr data-name=\"([^\"]*)\"");
  for (std::sregex_iterator it(table.begin(), table.end(), row), e; it != e; ++it) {
    names.push_back((*it)[1]);
  }
  return names;
}

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

TEST(ReportBrowser, ChromiumRunsTheScriptsWithoutErrorsAndSorts) {
  const std::string chromium = FindChromium();
  if (chromium.empty()) {
    FAIL() << "chromium not found on PATH: the report's browser test needs Debian's chromium; "
              "run scripts/install-deps.sh (CI installs it)";
  }
  const fs::path root = rephoto::testing::MakeTempDir();
  // A compare run (7 rows: 6 compared incl. a hostile name, 1 missing) and its report.
  const compare::CompareResult result = testing::MakeCompareRun(root / "a", 5, 0.02, 11);
  WriteRunReport(root / "a" / "run", root / "run.html",
                 {.thumbnail_width = 40, .image_folders = {root / "a"}});
  // A collection of it and an evaluate-layout run.
  testing::WriteEvaluateRun(root / "eval");
  WriteCollectionReport({{.label = "compare", .run_dir = root / "a" / "run"},
                         {.label = "evaluate", .run_dir = root / "eval"}},
                        root / "collection.html", {.image_folders = {root / "a"}});
  // Negative control: the same report with a console message and an uncaught exception, to
  // show that such problems are detected.
  std::string broken = ReadFileToString(root / "run.html");
  broken.replace(broken.rfind("</body>"), 7,
                 "<script>console.error('console says no'); throw new Error('boom');</script>"
                 "</body>");
  WriteTextFileAtomically(root / "broken.html", broken);

  WriteTextFileAtomically(root / "harness.html",
                          HarnessHtml({{"run", "run.html#sort=-1-ncc"},
                                       {"collection", "collection.html#sort=completeness"},
                                       {"broken", "broken.html"}}));

  const auto start = std::chrono::steady_clock::now();
  const BrowserResult browser = DumpDom(chromium, FileUrl(root / "harness.html", ""), root);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("headless chromium (3 pages): %.2f s\n", seconds);
  RecordProperty("chromium_seconds", std::to_string(seconds));
  ASSERT_EQ(browser.status, 0) << browser.log;
  const std::string run_file = fs::absolute(root / "run.html").string();
  const std::string collection_file = fs::absolute(root / "collection.html").string();
  const std::string broken_file = fs::absolute(root / "broken.html").string();
  struct Page {
    std::string dom, console;
  };
  const Page r{PageDom(browser.dom, "run"), ConsoleLines(browser.log, run_file)};
  const Page c{PageDom(browser.dom, "collection"), ConsoleLines(browser.log, collection_file)};
  const Page b{PageDom(browser.dom, "broken"), ConsoleLines(browser.log, broken_file)};
  ASSERT_EQ(browser.dom.find("\">HARNESS-ERROR"), std::string::npos) << browser.dom;
  // No console output but the control's.
  std::string others;
  std::stringstream all(ConsoleLines(browser.log, ""));
  for (std::string line; std::getline(all, line);) {
    if (line.find(broken_file) == std::string::npos) others += line + "\n";
  }
  EXPECT_EQ(others, "") << "console output of the reports or the harness";

  // The run report: scripts ran to the end, nothing on the console.
  ASSERT_FALSE(r.dom.empty()) << browser.dom;
  EXPECT_NE(r.dom.find("data-ready=\"1\""), std::string::npos) << browser.log;
  EXPECT_EQ(r.dom.find("data-js-error=\""), std::string::npos);
  EXPECT_EQ(r.console, "") << "console output of the report";
  // Table rows and plots in the DOM.
  EXPECT_EQ(Count(r.dom, "<svg class=\"boxplot\""), 4u);  // completeness + 3 metrics
  EXPECT_EQ(Count(r.dom, "<g class=\"box\""), 4u);
  EXPECT_EQ(Count(r.dom, "<div class=\"example\""), 6u);  // 3 worst + 3 best
  // Sorted by 1-ncc descending (two clicks on the header), the missing row last.
  std::vector<std::pair<double, std::string>> expected;
  for (const compare::ImageResult& image : result.images) {
    // The DOM serialiser escapes & < > " in attributes, not '.
    const std::string escaped = HtmlEscape(image.name);
    std::string name;
    for (size_t i = 0; i < escaped.size(); ++i) {
      if (escaped.compare(i, 5, "&#39;") == 0) {
        name += '\'';
        i += 4;
      } else {
        name += escaped[i];
      }
    }
    expected.push_back({image.metrics[0].mean, name});
  }
  std::sort(expected.rbegin(), expected.rend());
  std::vector<std::string> expected_names;
  for (const auto& e : expected) expected_names.push_back(e.second);
  expected_names.push_back("zz_missing");
  EXPECT_EQ(RowNames(r.dom, "per-image"), expected_names);
  EXPECT_NE(r.dom.find("data-col=\"1-ncc\" tabindex=\"0\" title=\"Sort by 1-ncc\" "
                       "aria-sort=\"descending\""),
            std::string::npos);

  // The collection report: ranking table sorted by completeness (ascending: evaluate's median
  // fold completeness 0.85 before the compare run's ~1).
  ASSERT_FALSE(c.dom.empty()) << browser.dom;
  EXPECT_NE(c.dom.find("data-ready=\"1\""), std::string::npos) << browser.log;
  EXPECT_EQ(c.dom.find("data-js-error=\""), std::string::npos);
  EXPECT_EQ(c.console, "");
  const size_t evaluate_row = c.dom.find("<tr data-label=\"evaluate\"");
  const size_t compare_row = c.dom.find("<tr data-label=\"compare\"");
  ASSERT_NE(evaluate_row, std::string::npos);
  ASSERT_NE(compare_row, std::string::npos);
  EXPECT_LT(evaluate_row, compare_row);
  EXPECT_EQ(Count(c.dom, "<svg class=\"boxplot\""), 4u);  // 1-ncc, completeness, cb+cr, psnr
  EXPECT_EQ(RowNames(c.dom, "per-image-0").size() + RowNames(c.dom, "per-image-1").size(), 7u + 6u);

  // The control: both problems detected.
  EXPECT_NE(b.console.find("console says no"), std::string::npos) << browser.log;
  EXPECT_NE(b.console.find("Uncaught Error: boom"), std::string::npos) << browser.log;
  EXPECT_NE(b.dom.find("data-js-error=\""), std::string::npos);
}

}  // namespace
}  // namespace rephoto::report
