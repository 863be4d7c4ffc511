#include "rephoto/report/report.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <regex>

#include "rephoto/core/colormap.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/stats.h"
#include "rephoto/io/csv.h"
#include "rephoto/io/image_io.h"
#include "rephoto/report/html.h"
#include "rephoto/report/report_fixture.h"
#include "rephoto/report/thumbnails.h"
#include "rephoto/run/run_data.h"
#include "rephoto/testing/testing.h"

namespace rephoto::report {
namespace {
namespace fs = std::filesystem;
using Attributes = std::map<std::string, std::string>;

std::vector<Attributes> Elements(const std::string& html, const std::string& start) {
  std::vector<Attributes> out;
  const std::regex attribute("([\\w-]+)=\"([^\"]*)\"");
  for (size_t pos = html.find(start); pos != std::string::npos; pos = html.find(start, pos + 1)) {
    const std::string tag = html.substr(pos, html.find('>', pos) - pos);
    Attributes a;
    for (std::sregex_iterator it(tag.begin(), tag.end(), attribute), end; it != end; ++it) {
      a[(*it)[1]] = (*it)[2];
    }
    out.push_back(std::move(a));
  }
  return out;
}

// Boxes of the SVG plots by series (run reports: the metric) or category.
std::vector<Attributes> Boxes(const std::string& html, const std::string& key,
                              const std::string& value) {
  std::vector<Attributes> out;
  for (Attributes& a : Elements(html, "<g class=\"box\"")) {
    if (a[key] == value) out.push_back(a);
  }
  return out;
}

// Linear-interpolation quantile (numpy default), written out independently of core/stats.
double HandQuantile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const double position = p * (v.size() - 1);
  const size_t i = static_cast<size_t>(position);
  if (i + 1 >= v.size()) return v.back();
  return v[i] + (position - i) * (v[i + 1] - v[i]);
}

void ExpectSelfContained(const std::string& html) {
  EXPECT_EQ(html.find("<link"), std::string::npos);
  EXPECT_EQ(html.find("@import"), std::string::npos);
  EXPECT_EQ(html.find("<iframe"), std::string::npos);
  for (const char* scheme : {"http://", "https://", "//cdn", "ftp://"}) {
    for (size_t p = html.find(scheme); p != std::string::npos; p = html.find(scheme, p + 1)) {
      EXPECT_EQ(html.compare(p, 26, "http://www.w3.org/2000/svg"), 0)
          << "external reference: " << html.substr(p, 60);
    }
  }
  for (size_t p = html.find("src=\""); p != std::string::npos; p = html.find("src=\"", p + 1)) {
    EXPECT_EQ(html.compare(p + 5, 5, "data:"), 0) << html.substr(p, 60);
  }
  for (size_t p = html.find("url("); p != std::string::npos; p = html.find("url(", p + 1)) {
    EXPECT_EQ(html[p + 4], '#') << html.substr(p, 60);
  }
}

double Num(const std::string& text) {
  if (text == "Infinity") return INFINITY;
  return std::stod(text);
}

TEST(HtmlHelpers, EscapeAndBase64) {
  EXPECT_EQ(HtmlEscape("<a href='x'>&\"</a>"), "&lt;a href=&#39;x&#39;&gt;&amp;&quot;&lt;/a&gt;");
  const auto b64 = [](const std::string& s) {
    return Base64(std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(s.data()), s.size()));
  };
  // RFC 4648 test vectors.
  EXPECT_EQ(b64(""), "");
  EXPECT_EQ(b64("f"), "Zg==");
  EXPECT_EQ(b64("fo"), "Zm8=");
  EXPECT_EQ(b64("foo"), "Zm9v");
  EXPECT_EQ(b64("foob"), "Zm9vYg==");
  EXPECT_EQ(b64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(b64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(DataNumber(NAN), "");
  EXPECT_EQ(DataNumber(INFINITY), "Infinity");
  EXPECT_EQ(DataNumber(0.1), "0.1");
  EXPECT_EQ(DisplayNumber(0.123456), "0.1235");
}

TEST(RunReport, CompareRunRowsBoxesExamplesAndEscaping) {
  const fs::path root = rephoto::testing::MakeTempDir();
  const compare::CompareResult result = testing::MakeCompareRun(root, 5, 0.02, 7);
  ASSERT_EQ(result.images.size(), 6u);
  ASSERT_EQ(result.missing.size(), 1u);
  ReportOptions options;
  options.example_images = 2;
  options.thumbnail_width = 24;
  // The photos and renderings lie outside the run folder: they are shown from the folders the
  // caller names only. Without them, no file the run's CSV names outside the run is read.
  WriteRunReport(root / "run", root / "unnamed.html", options);
  EXPECT_EQ(Elements(ReadFileToString(root / "unnamed.html"), "<img ").size(), 4u);  // errors
  options.image_folders = {root / "photos", root / "renders"};
  WriteRunReport(root / "run", root / "report.html", options);
  const std::string html = ReadFileToString(root / "report.html");
  ExpectSelfContained(html);

  // Every per_image.csv row, the missing one marked.
  const std::vector<Attributes> rows = Elements(html, "<tr data-name=");
  ASSERT_EQ(rows.size(), 7u);
  for (const compare::ImageResult& image : result.images) {
    EXPECT_NE(html.find("<tr data-name=\"" + HtmlEscape(image.name) + "\""), std::string::npos)
        << image.name;
  }
  EXPECT_NE(html.find("<tr data-name=\"zz_missing\" class=\"bad\">"), std::string::npos);
  EXPECT_NE(html.find(">missing_render<"), std::string::npos);
  // The hostile name only escaped.
  EXPECT_EQ(html.find(testing::kEvilName), std::string::npos);
  EXPECT_EQ(html.find("<b>&"), std::string::npos);
  EXPECT_NE(html.find("v&lt;b&gt;&amp;&#39;q&quot;"), std::string::npos);

  // The 1-ncc box equals hand-computed quartiles of the per-image means.
  std::vector<double> ncc;
  for (const compare::ImageResult& image : result.images) ncc.push_back(image.metrics[0].mean);
  const std::vector<Attributes> box = Boxes(html, "data-series", "1-ncc");
  ASSERT_EQ(box.size(), 1u);
  EXPECT_EQ(box[0].at("data-count"), "6");
  EXPECT_DOUBLE_EQ(Num(box[0].at("data-min")), *std::min_element(ncc.begin(), ncc.end()));
  EXPECT_DOUBLE_EQ(Num(box[0].at("data-max")), *std::max_element(ncc.begin(), ncc.end()));
  EXPECT_NEAR(Num(box[0].at("data-q1")), HandQuantile(ncc, 0.25), 1e-15);
  EXPECT_NEAR(Num(box[0].at("data-median")), HandQuantile(ncc, 0.5), 1e-15);
  EXPECT_NEAR(Num(box[0].at("data-q3")), HandQuantile(ncc, 0.75), 1e-15);
  double sum = 0;
  for (double v : ncc) sum += v;
  EXPECT_NEAR(Num(box[0].at("data-mean")), sum / ncc.size(), 1e-15);
  // One plot per metric plus completeness.
  EXPECT_EQ(Elements(html, "<svg class=\"boxplot\"").size(), 4u);

  // Examples: 2 worst and 2 best by 1-ncc (noise grows with the image index).
  const std::vector<Attributes> examples = Elements(html, "<div class=\"example\"");
  ASSERT_EQ(examples.size(), 4u);
  const auto worst = std::max_element(
      result.images.begin(), result.images.end(),
      [](const auto& a, const auto& b) { return a.metrics[0].mean < b.metrics[0].mean; });
  const auto best = std::min_element(
      result.images.begin(), result.images.end(),
      [](const auto& a, const auto& b) { return a.metrics[0].mean < b.metrics[0].mean; });
  EXPECT_EQ(examples[0].at("data-rank"), "worst #1");
  EXPECT_EQ(examples[0].at("data-name"), HtmlEscape(worst->name));
  EXPECT_EQ(examples[2].at("data-rank"), "best #1");
  EXPECT_EQ(examples[2].at("data-name"), HtmlEscape(best->name));
  EXPECT_EQ(best->name, "v00");
  EXPECT_EQ(worst->name, testing::kEvilName);  // the last, noisiest image
  // 4 images per example, all embedded and decodable at the thumbnail size.
  const std::vector<Attributes> images = Elements(html, "<img ");
  ASSERT_EQ(images.size(), 16u);
  const std::string& uri = images[0].at("src");
  const std::string prefix = "data:image/jpeg;base64,";
  ASSERT_EQ(uri.compare(0, prefix.size(), prefix), 0);
  EXPECT_EQ(images[0].at("width"), "24");
  EXPECT_EQ(images[0].at("height"), "19");  // 32 * 24 / 40 = 19.2
  EXPECT_EQ(html.find("not available"), std::string::npos);
  // Colour bar with the 1-ncc range [0, 1].
  EXPECT_NE(html.find("1-ncc error, range 0 to 1"), std::string::npos);
}

TEST(RunReport, EvaluateRunAcrossFoldsFailedFoldsAndSettings) {
  const fs::path dir = rephoto::testing::MakeTempDir() / "run";
  testing::WriteEvaluateRun(dir);
  WriteRunReport(dir, dir / "report.html");
  const std::string html = ReadFileToString(dir / "report.html");
  ExpectSelfContained(html);

  // Across folds: 1-ncc of the ok folds 0.1, 0.4, 0.2, 0.3 -> sorted 0.1 0.2 0.3 0.4:
  // Q1 at position 0.75 = 0.175, median 0.25, Q3 at 2.25 = 0.325 (by hand).
  const std::vector<Attributes> ncc = Boxes(html, "data-series", "1-ncc");
  ASSERT_EQ(ncc.size(), 1u);
  EXPECT_EQ(ncc[0].at("data-count"), "4");
  EXPECT_NEAR(Num(ncc[0].at("data-min")), 0.1, 1e-15);
  EXPECT_NEAR(Num(ncc[0].at("data-q1")), 0.175, 1e-15);
  EXPECT_NEAR(Num(ncc[0].at("data-median")), 0.25, 1e-15);
  EXPECT_NEAR(Num(ncc[0].at("data-q3")), 0.325, 1e-15);
  EXPECT_NEAR(Num(ncc[0].at("data-max")), 0.4, 1e-15);
  EXPECT_NEAR(Num(ncc[0].at("data-mean")), 0.25, 1e-15);
  // Completeness 0.9 0.8 1.0 0.7 -> 0.7 0.8 0.9 1.0: Q1 0.775, median 0.85, Q3 0.925.
  const std::vector<Attributes> completeness = Boxes(html, "data-series", "completeness");
  ASSERT_EQ(completeness.size(), 1u);
  EXPECT_NEAR(Num(completeness[0].at("data-q1")), 0.775, 1e-15);
  EXPECT_NEAR(Num(completeness[0].at("data-median")), 0.85, 1e-15);
  EXPECT_NEAR(Num(completeness[0].at("data-q3")), 0.925, 1e-15);
  // psnr 21 15 inf 17 -> median (17 + 21) / 2 = 19, max infinity.
  const std::vector<Attributes> psnr = Boxes(html, "data-series", "psnr");
  ASSERT_EQ(psnr.size(), 1u);
  EXPECT_NEAR(Num(psnr[0].at("data-median")), 19, 1e-12);
  EXPECT_EQ(psnr[0].at("data-max"), "Infinity");

  // Both summary tables; the 1-ncc row across folds has completeness mean 0.85 next to it.
  EXPECT_NE(html.find("data-unit=\"folds\""), std::string::npos);
  EXPECT_NE(html.find("data-unit=\"images\""), std::string::npos);
  const size_t folds_table = html.find("data-unit=\"folds\"");
  const size_t row = html.find("<tr data-metric=\"1-ncc\">", folds_table);
  ASSERT_NE(row, std::string::npos);
  const std::string row_html = html.substr(row, html.find("</tr>", row) - row);
  // Cells: mean min Q1 median Q3 max count completeness-mean.
  std::vector<std::string> cells;
  const std::regex cell("<td(?: data-v=\"([^\"]*)\")?>");
  for (std::sregex_iterator it(row_html.begin(), row_html.end(), cell), end; it != end; ++it) {
    cells.push_back((*it)[1]);
  }
  ASSERT_EQ(cells.size(), 8u) << row_html;
  EXPECT_NEAR(Num(cells[7]), 0.85, 1e-12) << row_html;
  // Over images: 1-ncc 0.12 0.08 0.4 0.2 0.3 -> median 0.2.
  const size_t images_table = html.find("data-unit=\"images\"");
  const size_t image_row = html.find("<tr data-metric=\"1-ncc\">", images_table);
  const std::string image_row_html =
      html.substr(image_row, html.find("</tr>", image_row) - image_row);
  EXPECT_NE(image_row_html.find("<td data-v=\"0.2\">0.2</td>"), std::string::npos)
      << image_row_html;

  // Failed fold with its (escaped) message; its image marked failed; settings escaped.
  EXPECT_NE(html.find("<b>fold_04</b>: reconstruct exited with 1: "
                      "&lt;script&gt;alert(1)&lt;/script&gt;"),
            std::string::npos);
  EXPECT_EQ(html.find("<script>alert"), std::string::npos);
  EXPECT_NE(html.find("<tr data-name=\"f\" class=\"bad\"><td class=\"text\">fold_04</td>"),
            std::string::npos);
  EXPECT_NE(html.find("run.json.settings.representation"), std::string::npos);
  EXPECT_NE(html.find("&#39;echo &lt;b&gt;hi&lt;/b&gt;&#39;"), std::string::npos);
  EXPECT_NE(html.find("scene /data/scene&lt;x&gt;"), std::string::npos);
  // Photos that do not exist: examples say so instead of failing.
  EXPECT_NE(html.find("not available"), std::string::npos);
  EXPECT_EQ(Elements(html, "<tr data-name=").size(), 6u);
  // The per-fold table: 5 folds, the failed one marked.
  EXPECT_EQ(Elements(html, "<tr data-fold=").size(), 5u);
  EXPECT_NE(html.find("<tr data-fold=\"fold_04\" class=\"bad\">"), std::string::npos);
}

TEST(RunReport, HundredsOfImagesStayTextWithThumbnailsOnlyForExamples) {
  // 400 compared images (compare layout written by hand, no image files): every row is in the
  // table, the only images are the examples' (here unavailable, so none), and the file grows by
  // well under 1 KB per image.
  const fs::path dir = rephoto::testing::MakeTempDir() / "run";
  std::string csv = "name,status,photo,render,width,height,resized,completeness,1-ncc,psnr\n";
  for (int i = 0; i < 400; ++i) {
    csv += fmt::format("img_{:04d},ok,p/{:04d}.png,r/{:04d}.png,640,480,0,{},{},{}\n", i, i, i,
                       0.5 + i / 1000.0, (i * 37 % 400) / 400.0, 20 + i % 7);
  }
  WriteTextFileAtomically(dir / "per_image.csv", csv);
  WriteRunReport(dir, dir / "report.html", {.example_images = 2});
  const std::string html = ReadFileToString(dir / "report.html");
  EXPECT_EQ(Elements(html, "<tr data-name=").size(), 400u);
  EXPECT_EQ(Elements(html, "<div class=\"example\"").size(), 4u);
  EXPECT_EQ(Elements(html, "<img ").size(), 0u);
  EXPECT_LT(html.size(), 400u * 1024u);
  // The worst image by 1-ncc: (i * 37) % 400 is largest (399) for i = 227.
  EXPECT_EQ(Elements(html, "<div class=\"example\"")[0].at("data-name"), "img_0227");
}

TEST(RunData, FailedFoldMessageFromPerFoldCsvWithoutSummary) {
  const fs::path dir = rephoto::testing::MakeTempDir() / "run";
  testing::WriteEvaluateRun(dir);
  fs::remove(dir / "summary.json");
  WriteTextFileAtomically(dir / "per_fold.csv",
                          "fold,status,test_images,evaluated_images,seconds,completeness,1-ncc,"
                          "psnr,message\n"
                          "fold_00,ok,2,2,1.5,0.9,0.1,21,\n"
                          "fold_04,failed,1,0,0.5,,,,\"render: exit 2, see logs\"\n");
  const run::RunData run = run::LoadRun(dir);
  EXPECT_EQ(run.layout, run::RunLayout::kEvaluate);  // by the fold column
  ASSERT_EQ(run.failed_folds.size(), 1u);
  EXPECT_EQ(run.failed_folds[0].fold, "fold_04");
  EXPECT_EQ(run.failed_folds[0].message, "render: exit 2, see logs");
  EXPECT_FALSE(run.AcrossFolds() && run.FoldValues(0).size() != 1u);
  EXPECT_EQ(run.metrics, (std::vector<std::string>{"1-ncc", "psnr"}));
  EXPECT_EQ(run.ImageDir(run.images[0]), dir / "folds" / "fold_00");
  EXPECT_EQ(run.images.back().status, "failed");
  EXPECT_TRUE(std::isnan(run.images.back().completeness));
}

TEST(CollectionReport, RanksEntriesAndBoxesPerEntry) {
  const fs::path root = rephoto::testing::MakeTempDir();
  const compare::CompareResult noisy = testing::MakeCompareRun(root / "noisy", 4, 0.08, 1, false);
  const compare::CompareResult clean = testing::MakeCompareRun(root / "clean", 4, 0.01, 2, false);
  testing::WriteEvaluateRun(root / "eval");
  std::vector<CollectionEntry> entries = {
      {.label = "noisy <n>", .description = "more noise", .run_dir = root / "noisy" / "run"},
      {.label = "clean", .description = "less noise", .run_dir = root / "clean" / "run"},
      {.label = "", .description = "hand-written", .run_dir = root / "eval"}};
  WriteCollectionReport(entries, root / "report.html");
  const std::string html = ReadFileToString(root / "report.html");
  ExpectSelfContained(html);
  // Ranked by median 1-ncc, best first; the eval run (0.25 across folds) ranks by its value.
  std::vector<double> clean_ncc, noisy_ncc;
  for (const auto& i : clean.images) clean_ncc.push_back(i.metrics[0].mean);
  for (const auto& i : noisy.images) noisy_ncc.push_back(i.metrics[0].mean);
  std::vector<std::pair<double, std::string>> expected = {
      {HandQuantile(clean_ncc, 0.5), "clean"},
      {HandQuantile(noisy_ncc, 0.5), "noisy &lt;n&gt;"},
      {0.25, "eval"}};
  std::sort(expected.begin(), expected.end());
  const std::vector<Attributes> ranking = Elements(html, "<tr data-label=");
  ASSERT_EQ(ranking.size(), 3u);
  for (size_t i = 0; i < 3; ++i) EXPECT_EQ(ranking[i].at("data-label"), expected[i].second);
  // One 1-ncc box per entry with that entry's statistics.
  const std::vector<Attributes> clean_boxes = Boxes(html, "data-category", "clean");
  ASSERT_EQ(clean_boxes.size(), 4u);  // 1-ncc, completeness, cb+cr, psnr
  EXPECT_NEAR(Num(clean_boxes[0].at("data-median")), HandQuantile(clean_ncc, 0.5), 1e-15);
  EXPECT_NEAR(Num(clean_boxes[0].at("data-q3")), HandQuantile(clean_ncc, 0.75), 1e-15);
  const std::vector<Attributes> eval_boxes = Boxes(html, "data-category", "eval");
  ASSERT_EQ(eval_boxes.size(), 3u);  // the eval run has no cb+cr
  EXPECT_NEAR(Num(eval_boxes[0].at("data-median")), 0.25, 1e-15);
  EXPECT_EQ(Elements(html, "<svg class=\"boxplot\"").size(), 4u);
  // One worst and one best image per compare run; per-image tables of all runs.
  EXPECT_EQ(Elements(html, "<div class=\"example\"").size(), 2u + 2u + 2u);
  EXPECT_EQ(Elements(html, "<table class=\"sortable per-image\"").size(), 3u);

  // psnr: higher is better, so the best is the highest median (eval: 19 dB across folds).
  std::vector<double> clean_psnr, noisy_psnr;
  for (const auto& i : clean.images) clean_psnr.push_back(i.metrics[2].mean);
  for (const auto& i : noisy.images) noisy_psnr.push_back(i.metrics[2].mean);
  std::vector<std::pair<double, std::string>> expected_psnr = {
      {HandQuantile(clean_psnr, 0.5), "clean"},
      {HandQuantile(noisy_psnr, 0.5), "noisy &lt;n&gt;"},
      {19.0, "eval"}};
  std::sort(expected_psnr.rbegin(), expected_psnr.rend());
  CollectionOptions options;
  options.primary_metric = "psnr";
  WriteCollectionReport(entries, root / "psnr.html", options);
  const std::vector<Attributes> by_psnr =
      Elements(ReadFileToString(root / "psnr.html"), "<tr data-label=");
  ASSERT_EQ(by_psnr.size(), 3u);
  for (size_t i = 0; i < 3; ++i) EXPECT_EQ(by_psnr[i].at("data-label"), expected_psnr[i].second);
  // rank = false keeps the given order.
  options.rank = false;
  WriteCollectionReport(entries, root / "unranked.html", options);
  const std::vector<Attributes> unranked =
      Elements(ReadFileToString(root / "unranked.html"), "<tr data-label=");
  ASSERT_EQ(unranked.size(), 3u);
  EXPECT_EQ(unranked[0].at("data-label"), "noisy &lt;n&gt;");
  EXPECT_EQ(unranked[2].at("data-label"), "eval");
}

// issue 14: accuracy is meaningless without completeness. Runs that are much less complete
// than the most complete one, or not cross-validated, are marked in the ranking and its CSV.
TEST(CollectionReport, MarksRunsThatDoNotCompareByAccuracyAlone) {
  const fs::path root = rephoto::testing::MakeTempDir();
  testing::MakeCompareRun(root / "clean", 4, 0.01, 2, false);
  testing::WriteEvaluateRun(root / "eval");  // completeness across folds: median 0.85
  fs::copy(root / "eval", root / "fixed", fs::copy_options::recursive);
  std::string summary = ReadFileToString(root / "fixed" / "summary.json");
  summary.replace(summary.find("\"folds\": 5,"), 11, "\"folds\": 5, \"cross_validated\": false,");
  WriteTextFileAtomically(root / "fixed" / "summary.json", summary);
  const double clean_completeness =
      Summarize(run::LoadRun(root / "clean" / "run").Values(-1)).median;
  ASSERT_GT(clean_completeness, 0.9);
  const std::vector<CollectionEntry> entries = {
      {.label = "clean", .run_dir = root / "clean" / "run"},
      {.label = "eval", .run_dir = root / "eval"},
      {.label = "fixed", .run_dir = root / "fixed"}};
  CollectionOptions options;
  options.ranking_csv = root / "ranking.csv";
  WriteCollectionReport(entries, root / "report.html", options);
  const auto rows = io::ParseCsv(ReadFileToString(root / "ranking.csv"), "ranking.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[0][0], "rank");
  EXPECT_EQ(rows[0][3], "1-ncc_median");
  EXPECT_EQ(rows[0][4], "completeness_median");
  EXPECT_EQ(rows[0].back(), "note");
  std::map<std::string, std::vector<std::string>> by_label;
  for (size_t r = 1; r < rows.size(); ++r) by_label[rows[r][1]] = rows[r];
  EXPECT_EQ(by_label["clean"].back(), "");
  EXPECT_EQ(by_label["clean"][rows[0].size() - 2], "true");
  const std::string low = fmt::format(
      "completeness 0.850 is more than 0.05 below the most complete run's {:.3f}: its accuracy "
      "covers fewer pixels and does not compare",
      clean_completeness);
  EXPECT_EQ(by_label["eval"].back(), low);
  EXPECT_EQ(by_label["fixed"].back(),
            low + "; not cross-validated: the model may have seen the test photos");
  EXPECT_EQ(by_label["fixed"][rows[0].size() - 2], "false");
  const std::string html = ReadFileToString(root / "report.html");
  EXPECT_NE(html.find("<th class=\"text\" data-col=\"note\">note</th>"), std::string::npos);
  EXPECT_NE(html.find("\u26a0"), std::string::npos);
  // A wider margin accepts the evaluate runs' completeness; the fixed model stays marked.
  options.completeness_margin = 0.2;
  WriteCollectionReport(entries, root / "report.html", options);
  const auto wide = io::ParseCsv(ReadFileToString(root / "ranking.csv"), "ranking.csv");
  for (size_t r = 1; r < wide.size(); ++r) {
    EXPECT_EQ(wide[r].back(), wide[r][1] == "fixed"
                                  ? "not cross-validated: the model may have seen the test photos"
                                  : "");
  }
}

TEST(CollectionReport, SweepBoxesPerSettingAndSeries) {
  const fs::path root = rephoto::testing::MakeTempDir();
  std::vector<CollectionEntry> entries;
  std::map<std::pair<std::string, double>, double> medians;
  int seed = 10;
  for (const std::string series : {"texture", "geometry"}) {
    for (double setting : {0.5, 1.0, 2.0}) {
      const fs::path dir = root / (series + std::to_string(seed));
      const double noise = (series == "texture" ? 0.01 : 0.02) * setting;
      const compare::CompareResult r = testing::MakeCompareRun(dir, 3, noise, seed++, false);
      std::vector<double> v;
      for (const auto& i : r.images) v.push_back(i.metrics[0].mean);
      medians[{series, setting}] = HandQuantile(v, 0.5);
      entries.push_back({.label = series + " " + std::to_string(setting),
                         .run_dir = dir / "run",
                         .series = series,
                         .setting = setting});
    }
  }
  CollectionOptions options;
  options.setting_name = "noise strength";
  WriteCollectionReport(entries, root / "sweep.html", options);
  const std::string html = ReadFileToString(root / "sweep.html");
  ExpectSelfContained(html);
  // Boxes at categories "0.5", "1", "2" per series; their medians are the runs' medians.
  for (const auto& [key, median] : medians) {
    const std::string category = key.second == 0.5 ? "0.5" : key.second == 1.0 ? "1" : "2";
    std::vector<Attributes> boxes;
    for (const Attributes& a : Boxes(html, "data-category", category)) {
      if (a.at("data-series") == key.first) boxes.push_back(a);
    }
    ASSERT_EQ(boxes.size(), 4u) << key.first << " " << category;  // 3 metrics + completeness
    EXPECT_NEAR(Num(boxes[0].at("data-median")), median, 1e-15);
  }
  // Medians connected per series in every plot; axis label.
  EXPECT_EQ(Elements(html, "<path class=\"median-line\"").size(), 2u * 4u);
  EXPECT_NE(html.find(">noise strength</text>"), std::string::npos);

  // Entries must all have a setting or none.
  entries.back().setting.reset();
  EXPECT_THROW(WriteCollectionReport(entries, root / "bad.html", options), Error);
}

TEST(Report, BadInputThrowsNamingTheFile) {
  const fs::path root = rephoto::testing::MakeTempDir();
  fs::create_directories(root / "empty");
  try {
    WriteRunReport(root / "empty", root / "out.html");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("per_image.csv"), std::string::npos) << e.what();
  }
  testing::WriteEvaluateRun(root / "eval");
  fs::remove(root / "eval" / "per_fold.csv");
  EXPECT_THROW(WriteRunReport(root / "eval", root / "out.html"), Error);
  fs::create_directories(root / "bad");
  WriteTextFileAtomically(root / "bad" / "per_image.csv",
                          "name,status,completeness,1-ncc\na,ok,0.5,zero\n");
  try {
    run::LoadRun(root / "bad");
    FAIL();
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("per_image.csv: line 2: column \"1-ncc\""), std::string::npos)
        << message;
  }
  WriteTextFileAtomically(root / "bad" / "per_image.csv", "name,status,completeness,1-ncc\n");
  WriteTextFileAtomically(root / "bad" / "summary.json", "{not json");
  EXPECT_THROW(run::LoadRun(root / "bad"), Error);
  EXPECT_THROW(WriteCollectionReport({}, root / "out.html"), Error);
  fs::remove(root / "bad" / "summary.json");
  EXPECT_THROW(WriteCollectionReport({{.run_dir = root / "bad"}}, root / "out.html",
                                     {.primary_metric = "ssim"}),
               Error);
  EXPECT_FALSE(fs::exists(root / "out.html"));
}

// The image of a thumbnail's data URI (base64 decoded by hand: the inverse of Base64).
Image DecodeThumbnail(const Thumbnail& t) {
  const std::string b64 = t.data_uri.substr(t.data_uri.find(',') + 1);
  std::vector<uint8_t> bytes;
  uint32_t buffer = 0;
  int bits = 0;
  for (char c : b64) {
    if (c == '=') break;
    const int v = std::isupper(c)   ? c - 'A'
                  : std::islower(c) ? c - 'a' + 26
                  : std::isdigit(c) ? c - '0' + 52
                  : c == '+'        ? 62
                                    : 63;
    buffer = (buffer << 6) | v;
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      bytes.push_back(static_cast<uint8_t>(buffer >> bits));
    }
  }
  Image image;
  io::DecodeImage(bytes, "thumbnail", &image);
  return image;
}

TEST(Thumbnails, MaskFromAlphaAndNanAwareErrorShrinking) {
  const fs::path root = rephoto::testing::MakeTempDir();
  testing::MakeCompareRun(root, 2, 0.01, 3, false);
  // v01 has a transparent block x 5..14, y 4..11: black in the rephoto, 0 in the mask.
  Thumbnail rephoto, mask;
  RenderThumbnails(root / "renders" / "v01.png", 100, &rephoto, &mask);
  ASSERT_TRUE(rephoto.error.empty()) << rephoto.error;
  EXPECT_EQ(mask.width, 40);  // never enlarged
  Image decoded;
  decoded = DecodeThumbnail(mask);
  ASSERT_EQ(decoded.channels(), 1);
  EXPECT_EQ(decoded.at(7, 6), 0.f);
  EXPECT_EQ(decoded.at(30, 20), 1.f);
  decoded = DecodeThumbnail(rephoto);
  // Black (texture values are 0.15-0.85); JPEG chroma subsampling of the small block blurs a
  // few levels in.
  float sum = 0;
  for (int c = 0; c < 3; ++c) {
    EXPECT_LT(decoded.at(9, 7, c), 0.12f);
    sum += decoded.at(9, 7, c);
  }
  EXPECT_LT(sum / 3, 0.06f);

  // Error image 64x48: left half NaN, right half 0.25 at even columns and NaN at odd ones.
  // Shrunk to 32 wide, each right-half thumbnail pixel averages one value and one NaN: it must
  // show 0.25 (jet (0, 0.5, 1)), not 0.125 and not "not evaluated"; the left half shows the
  // grey checkerboard (150 / 200 in 8-pixel squares).
  Image error(64, 48, 1, NAN);
  for (int y = 0; y < 48; ++y) {
    for (int x = 32; x < 64; x += 2) error.at(x, y) = 0.25f;
  }
  io::WriteExr(root / "e.exr", error);
  const Thumbnail t = ErrorThumbnail(root / "e.exr", {}, metrics::Metric::kOneMinusNcc, 32);
  ASSERT_TRUE(t.error.empty()) << t.error;
  EXPECT_EQ(t.width, 32);
  EXPECT_EQ(t.height, 24);
  decoded = DecodeThumbnail(t);
  const std::array<float, 3> jet = JetColor(0.25f);  // range [0, 1] for 1-ncc
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(decoded.at(24, 12, c), jet[c], 6 / 255.f) << c;
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(decoded.at(3, 3, c), 150 / 255.f, 6 / 255.f);
    EXPECT_NEAR(decoded.at(11, 3, c), 200 / 255.f, 6 / 255.f);
  }
  // Missing files are reported, not thrown.
  EXPECT_FALSE(ErrorThumbnail(root / "none.exr", root / "none.png", metrics::Metric::kCbCr, 32)
                   .error.empty());
  EXPECT_FALSE(PhotoThumbnail(root / "none.png", 32).error.empty());
}

// The process-wide cache (thumbnails.h): the same file gives the same thumbnail, also named
// by another path; a file rewritten in place (same size, same modification time set back) or
// replaced by a rename gives the thumbnail of its new content; a missing file is not kept.
TEST(Thumbnails, CacheFollowsTheFilesContent) {
  const fs::path root = rephoto::testing::MakeTempDir();
  const auto Uniform = [&](const fs::path& path, float value) {
    io::WriteExr(path, Image(64, 48, 1, value));
  };
  const auto Centre = [](const Thumbnail& t) {
    const Image image = DecodeThumbnail(t);
    return std::array<float, 3>{image.at(16, 12, 0), image.at(16, 12, 1), image.at(16, 12, 2)};
  };
  const auto ExpectJet = [&](const Thumbnail& t, float value) {
    ASSERT_TRUE(t.error.empty()) << t.error;
    const std::array<float, 3> got = Centre(t), jet = JetColor(value);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], jet[c], 6 / 255.f) << value << " " << c;
  };
  const metrics::Metric m = metrics::Metric::kOneMinusNcc;  // jet over [0, 1]
  const fs::path e = root / "e.exr";
  Uniform(e, 0.25f);
  const Thumbnail first = ErrorThumbnail(e, {}, m, 32);
  ExpectJet(first, 0.25f);
  EXPECT_EQ(ErrorThumbnail(root / "." / "e.exr", {}, m, 32).data_uri, first.data_uri);

  // Rewritten in place (the same inode and size) with its old modification time put back: the
  // status-change time still tells.
  const fs::file_time_type written = fs::last_write_time(e);
  {
    Image other(64, 48, 1, 0.75f);
    const fs::path tmp = root / "other.exr";
    io::WriteExr(tmp, other);
    ASSERT_EQ(fs::file_size(tmp), fs::file_size(e));
    fs::copy_file(tmp, e, fs::copy_options::overwrite_existing);
    fs::last_write_time(e, written);
  }
  ExpectJet(ErrorThumbnail(e, {}, m, 32), 0.75f);

  // Replaced by a rename (a new inode), as rephoto writes its outputs.
  Uniform(root / "next.exr", 0.5f);
  fs::rename(root / "next.exr", e);
  ExpectJet(ErrorThumbnail(e, {}, m, 32), 0.5f);

  // A failure is not kept: the file appearing later gives its thumbnail.
  const fs::path late = root / "late.exr";
  EXPECT_FALSE(ErrorThumbnail(late, {}, m, 32).error.empty());
  Uniform(late, 0.25f);
  ExpectJet(ErrorThumbnail(late, {}, m, 32), 0.25f);
}

}  // namespace
}  // namespace rephoto::report
