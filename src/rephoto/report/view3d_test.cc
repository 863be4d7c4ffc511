// The 3D view's data (view3d.h) and the run report's papercuts (issue 32): what the loaders
// read from a run folder written by the fixture, the browser decimation, the HTML data block,
// and the Settings section's values.
#include "rephoto/report/view3d.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <cstring>
#include <limits>
#include <map>
#include <regex>

#include "rephoto/core/file.h"
#include "rephoto/report/html.h"
#include "rephoto/report/report.h"
#include "rephoto/report/report_fixture.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/testing/testing.h"

namespace rephoto::report {
namespace {
namespace fs = std::filesystem;

// Base64 decoding written here from RFC 4648 (the reference for html.h's encoder).
std::vector<uint8_t> FromBase64(const std::string& text) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::vector<uint8_t> out;
  uint32_t buffer = 0;
  int bits = 0;
  for (char c : text) {
    const int v = value(c);
    if (v < 0) continue;
    buffer = (buffer << 6) | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<uint8_t>((buffer >> bits) & 0xFF));
    }
  }
  return out;
}

template <typename T>
std::vector<T> Decode(const std::string& text) {
  const std::vector<uint8_t> bytes = FromBase64(text);
  std::vector<T> values(bytes.size() / sizeof(T));
  std::memcpy(values.data(), bytes.data(), values.size() * sizeof(T));
  return values;
}

// The JSON of the first view in a page.
nlohmann::json ViewData(const std::string& html) {
  const std::string open = "<script type=\"application/json\" class=\"v3-data\">";
  const size_t a = html.find(open);
  EXPECT_NE(a, std::string::npos);
  const size_t b = html.find("</script>", a);
  std::string text = html.substr(a + open.size(), b - a - open.size());
  return nlohmann::json::parse(text);
}

TEST(View3d, LoadsTheProjectedModelCamerasAndColoursOfARun) {
  const fs::path dir = rephoto::testing::MakeTempDir() / "run";
  testing::WriteView3dRun(dir);
  const run::RunData run = run::LoadRun(dir);
  const std::optional<View3dModel> model = LoadRunView3d(run, "1-ncc", 0);
  ASSERT_TRUE(model.has_value());
  EXPECT_EQ(model->positions.size(), 41u * 41u);
  EXPECT_EQ(model->faces.size(), 3200u);
  EXPECT_EQ(model->original_faces, 3200u);
  EXPECT_FLOAT_EQ(model->low, 1.f);
  EXPECT_FLOAT_EQ(model->high, 3.f);
  ASSERT_EQ(model->error.size(), model->positions.size());
  size_t unseen = 0;
  for (size_t i = 0; i < model->positions.size(); ++i) {
    const double expected = testing::View3dRunError(model->positions[i].x(), model->positions[i].y());
    if (std::isnan(expected)) {
      EXPECT_TRUE(std::isnan(model->error[i])) << i;
      ++unseen;
    } else {
      EXPECT_NEAR(model->error[i], expected, 1e-6) << i;
    }
  }
  EXPECT_EQ(unseen, 6u * 6u);  // x, y = -1 + i / 20 > 0.72 for i = 35 .. 40
  // Model colours from run.json inputs.model.path (inside the run folder): r = (x + 1) / 2.
  ASSERT_EQ(model->colors.size(), model->positions.size());
  EXPECT_EQ(model->colors[0][0], 0);
  EXPECT_EQ(model->colors[40][0], 255);
  EXPECT_EQ(model->colors[40][2], 64);  // 0.25 * 255 rounded
  ASSERT_EQ(model->folds, (std::vector<std::string>{"fold_00", "fold_01"}));
  ASSERT_EQ(model->cameras.size(), 4u);
  std::map<std::string, const View3dCamera*> by_name;
  for (const View3dCamera& c : model->cameras) by_name[c.name] = &c;
  ASSERT_EQ(by_name.count("cam_a.png"), 1u);
  EXPECT_EQ(by_name["cam_a.png"]->test_fold, 0);
  EXPECT_EQ(by_name["cam_a.png"]->train_folds, std::vector<int>{1});
  EXPECT_EQ(by_name["cam_d.png"]->test_fold, 1);
  EXPECT_DOUBLE_EQ(by_name["cam_b.png"]->error, 0.2);
  EXPECT_DOUBLE_EQ(by_name["cam_d.png"]->error, 0.4);
  EXPECT_DOUBLE_EQ(by_name["cam_a.png"]->fx, 1000);
  // Its centre: -R^T t = (1.5, 1.5, 3).
  const Eigen::Vector3d centre =
      -by_name["cam_a.png"]->rotation.transpose() * by_name["cam_a.png"]->translation;
  EXPECT_NEAR((centre - Eigen::Vector3d(1.5, 1.5, 3)).norm(), 0, 1e-9);
  // No projected errors of another metric: nothing to show.
  EXPECT_FALSE(LoadRunView3d(run, "psnr", 0).has_value());
}

TEST(View3d, DecimationCarriesTheMeanErrorOfTheVerticesEachKeptOneStandsFor) {
  const fs::path dir = rephoto::testing::MakeTempDir() / "run";
  testing::WriteView3dRun(dir);
  const run::RunData run = run::LoadRun(dir);
  const std::optional<View3dModel> full = LoadRunView3d(run, "1-ncc", 0);
  std::optional<View3dModel> model = LoadRunView3d(run, "1-ncc", 0, {.max_faces = 400});
  ASSERT_TRUE(full.has_value() && model.has_value());
  EXPECT_LE(model->faces.size(), 400u);
  EXPECT_GT(model->faces.size(), 50u);
  EXPECT_EQ(model->original_faces, 3200u);
  EXPECT_LT(model->positions.size(), 41u * 41u);
  ASSERT_EQ(model->error.size(), model->positions.size());
  ASSERT_EQ(model->colors.size(), model->positions.size());
  // Reference by brute force: each original vertex goes to its nearest kept vertex (the lowest
  // kept index on ties); a kept vertex's error is the mean of its members' finite errors.
  const size_t k = model->positions.size();
  std::vector<double> sum(k, 0);
  std::vector<int> count(k, 0);
  for (size_t v = 0; v < full->positions.size(); ++v) {
    size_t best = 0;
    float best_d = std::numeric_limits<float>::infinity();
    for (size_t i = 0; i < k; ++i) {
      const float d = (model->positions[i] - full->positions[v]).squaredNorm();
      if (d < best_d) {
        best_d = d;
        best = i;
      }
    }
    if (std::isfinite(full->error[v])) {
      sum[best] += full->error[v];
      ++count[best];
    }
  }
  size_t unseen = 0;
  for (size_t i = 0; i < k; ++i) {
    const Eigen::Vector3f& p = model->positions[i];
    if (count[i] == 0) {
      EXPECT_TRUE(std::isnan(model->error[i])) << i;
      ++unseen;
    } else {
      EXPECT_NEAR(model->error[i], sum[i] / count[i], 1e-5) << i;
      // The field is 2 + x: a cluster's mean stays within its extent (< 0.3) of 2 + x.
      EXPECT_NEAR(model->error[i], 2 + p.x(), 0.3) << i;
    }
    EXPECT_NEAR(model->colors[i][0], std::lround(255 * (p.x() + 1) / 2), 1);
  }
  EXPECT_GT(unseen, 0u);  // the unseen corner survives
  for (const auto& face : model->faces) {
    for (uint32_t index : face) EXPECT_LT(index, model->positions.size());
  }
  // Point clouds: every k-th point.
  View3dModel points;
  for (int i = 0; i < 1000; ++i) {
    points.positions.push_back({static_cast<float>(i), 0, 0});
    points.error.push_back(static_cast<float>(i));
  }
  DecimateForBrowser(points, {.max_points = 300});
  ASSERT_EQ(points.positions.size(), 250u);  // step ceil(1000 / 300) = 4
  EXPECT_EQ(points.original_vertices, 1000u);
  for (size_t i = 0; i < points.positions.size(); ++i) {
    EXPECT_EQ(points.positions[i].x(), 4.f * i);
    EXPECT_EQ(points.error[i], 4.f * i);
  }
}

TEST(View3d, HtmlCarriesTheArraysAndEscapesTheJson) {
  View3dModel m;
  m.label = "</script><b>x</b>";
  m.metric = "1-ncc";
  m.low = 0.25f;
  m.high = 0.75f;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 2}};
  m.error = {0.25f, std::nanf(""), 0.5f};
  View3dData data;
  data.models.push_back(m);
  const std::string html = View3dHtml(data, "v");
  EXPECT_EQ(html.find("</script><b>"), std::string::npos);
  EXPECT_NE(html.find("<\\/script><b>x<\\/b>"), std::string::npos);
  const nlohmann::json j = ViewData(html);
  ASSERT_EQ(j["models"].size(), 1u);
  const nlohmann::json& model = j["models"][0];
  EXPECT_EQ(model["label"], m.label);
  EXPECT_EQ(model["kind"], "mesh");
  EXPECT_DOUBLE_EQ(model["low"].get<double>(), 0.25);
  const std::vector<float> positions = Decode<float>(model["positions"]);
  EXPECT_EQ(positions, (std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}));
  EXPECT_EQ(Decode<uint32_t>(model["indices"]), (std::vector<uint32_t>{0, 1, 2}));
  const std::vector<float> error = Decode<float>(model["error"]);
  ASSERT_EQ(error.size(), 3u);
  EXPECT_EQ(error[0], 0.25f);
  EXPECT_TRUE(std::isnan(error[1]));
  EXPECT_THROW(View3dHtml(data, "bad id\""), Error);
  EXPECT_THROW(View3dHtml({}, "v"), Error);
  // The scripts: three.js and OrbitControls inlined, nothing that closes the element early.
  const std::string scripts = View3dScripts();
  EXPECT_NE(scripts.find("REVISION=\"111\""), std::string::npos);
  EXPECT_NE(scripts.find("THREE.OrbitControls"), std::string::npos);
  EXPECT_EQ(scripts.find("src=\"http"), std::string::npos);
  size_t closes = 0;
  for (size_t p = scripts.find("</script"); p != std::string::npos; p = scripts.find("</script", p + 1)) {
    ++closes;
  }
  EXPECT_EQ(closes, 3u);  // one per <script> element
}

TEST(View3d, SuggestedCamerasFromASuggestFolder) {
  const fs::path dir = rephoto::testing::MakeTempDir() / "next";
  scene::Scene s;
  camera::Camera camera;
  camera.model = camera::CameraModel::kPinhole;
  camera.width = 320;
  camera.height = 240;
  camera.params = {250, 250, 160, 120};
  s.cameras[1] = camera;
  scene::View view;
  view.name = "suggest_00.png";
  view.camera_id = 1;
  view.cam_from_world.translation = {0, 0, 5};
  s.views.push_back(view);
  scene::WriteColmap(s, dir / "sparse", scene::ColmapFormat::kText);
  WriteTextFileAtomically(dir / "suggestions.json", R"({"schema": "rephoto.suggest/1",
    "unobserved_area": 2.0, "suggestions": [{"name": "suggest_00.png", "unobserved_area": 0.5,
    "mean_error": 0.125}]})");
  const std::vector<View3dCamera> cameras = LoadSuggestedCameras(dir);
  ASSERT_EQ(cameras.size(), 1u);
  EXPECT_EQ(cameras[0].role, "suggested");
  EXPECT_EQ(cameras[0].note, "sees 25.0 % of the surface no photo sees");
  EXPECT_DOUBLE_EQ(cameras[0].error, 0.125);
  EXPECT_DOUBLE_EQ(cameras[0].translation.z(), 5);
  EXPECT_DOUBLE_EQ(cameras[0].cx, 160);
  WriteTextFileAtomically(dir / "suggestions.json",
                          R"({"suggestions": [{"name": "../elsewhere.png"}]})");
  EXPECT_THROW(LoadSuggestedCameras(dir), Error);
  EXPECT_TRUE(LoadSuggestedCameras(dir / "nothing").empty());
}

// Issue 32 papercut: the run report's Settings showed run.json's values of the moment before
// the projection ("outputs.projected (none)", "counters.projections 0") and
// split.cross_validated true for a fixed model whose summary.json says false.
TEST(RunReportSettings, ShowTheFolderAndSummaryNotStaleRunJsonValues) {
  const fs::path dir = rephoto::testing::MakeTempDir() / "run";
  testing::WriteView3dRun(dir);
  WriteRunReport(dir, dir / "report.html");
  const std::string html = ReadFileToString(dir / "report.html");
  EXPECT_NE(html.find("<tr><td>outputs.projected (in the run folder)</td><td "
                      "class=\"path\">projected/1-ncc.ply</td></tr>"),
            std::string::npos);
  EXPECT_EQ(html.find("run.json.outputs"), std::string::npos);
  EXPECT_EQ(html.find("run.json.counters.projections"), std::string::npos);
  EXPECT_EQ(html.find("run.json.status"), std::string::npos);
  EXPECT_NE(html.find("<tr><td>run.json.split.cross_validated</td><td class=\"path\">false "
                      "(summary.json; the split holds test photos out, but the model was given"),
            std::string::npos);
  EXPECT_NE(html.find("not cross-validated (a given model)"), std::string::npos);
  // And the 3D view with the three.js it needs.
  EXPECT_NE(html.find("<div class=\"view3d\" id=\"view3d\">"), std::string::npos);
  EXPECT_NE(html.find("REVISION=\"111\""), std::string::npos);
  const nlohmann::json data = ViewData(html);
  EXPECT_EQ(data["models"][0]["cameras"].size(), 4u);
  // Without projected errors: no view, no three.js.
  fs::remove(dir / "projected" / "1-ncc.ply");
  WriteRunReport(dir, dir / "report2.html");
  const std::string plain = ReadFileToString(dir / "report2.html");
  EXPECT_EQ(plain.find("class=\"view3d\""), std::string::npos);
  EXPECT_EQ(plain.find("REVISION"), std::string::npos);
  EXPECT_NE(plain.find("outputs.projected (in the run folder)</td><td class=\"path\">(none)"),
            std::string::npos);
  // A projected PLY that cannot be read costs the view (with the reason), not the report.
  WriteTextFileAtomically(dir / "projected" / "1-ncc.ply", "ply\nformat ascii 1.0\nbroken\n");
  WriteRunReport(dir, dir / "report3.html");
  const std::string broken = ReadFileToString(dir / "report3.html");
  EXPECT_NE(broken.find("<p class=\"problems\">No 3D view: "), std::string::npos);
  EXPECT_NE(broken.find("1-ncc.ply"), std::string::npos);
}

// A Gaussian splatting run: projected/1-ncc.ply is the Gaussians' PLY with an "error"
// property (graphdeco's layout); the view shows the Gaussians as points at their means.
TEST(View3d, GaussiansAsPoints) {
  const fs::path dir = rephoto::testing::MakeTempDir() / "run";
  testing::WriteView3dRun(dir);
  std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
      "property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n"
      "property float opacity\nproperty float scale_0\nproperty float scale_1\n"
      "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\n"
      "property float rot_3\nproperty float error\nend_header\n";
  for (int i = 0; i < 3; ++i) {
    ply += fmt::format("{} 0 0 0 0 1 0.5 0.5 0.5 2 -3 -3 -3 1 0 0 0 {}\n", i, i == 1 ? "nan" : "0.25");
  }
  WriteTextFileAtomically(dir / "projected" / "1-ncc.ply", ply);
  const std::optional<View3dModel> model = LoadRunView3d(run::LoadRun(dir), "1-ncc", 0);
  ASSERT_TRUE(model.has_value());
  EXPECT_TRUE(model->faces.empty());
  ASSERT_EQ(model->positions.size(), 3u);
  EXPECT_EQ(model->positions[2].x(), 2.f);
  EXPECT_EQ(model->error[0], 0.25f);
  EXPECT_TRUE(std::isnan(model->error[1]));
  // No "colour range" comment: the 2.5 / 97.5 % percentiles of the errors (all 0.25).
  EXPECT_EQ(model->low, 0.25f);
  EXPECT_EQ(model->high, 0.25f);
}

// Runs with --reconstruct project onto each fold's model: one entry per fold.
TEST(View3d, PerFoldModelsOfReconstructRuns) {
  const fs::path dir = rephoto::testing::MakeTempDir() / "run";
  testing::WriteView3dRun(dir);
  fs::rename(dir / "projected" / "1-ncc.ply", dir / "projected" / "fold_01.1-ncc.ply");
  fs::copy_file(dir / "projected" / "fold_01.1-ncc.ply", dir / "projected" / "fold_00.1-ncc.ply");
  fs::copy_file(dir / "projected" / "fold_01.1-ncc.ply", dir / "projected" / "fold_00.psnr.ply");
  const run::RunData run = run::LoadRun(dir);
  EXPECT_FALSE(LoadRunView3d(run, "1-ncc", 0).has_value());
  const std::vector<View3dModel> models = LoadRunView3dModels(run, "1-ncc", 0);
  ASSERT_EQ(models.size(), 2u);
  EXPECT_EQ(models[0].label, "fold_00");
  EXPECT_EQ(models[1].label, "fold_01");
  EXPECT_EQ(models[1].faces.size(), 3200u);
  EXPECT_TRUE(models[0].colors.empty());
  EXPECT_EQ(models[0].cameras.size(), 4u);
  WriteRunReport(dir, dir / "report.html");
  const nlohmann::json data = ViewData(ReadFileToString(dir / "report.html"));
  ASSERT_EQ(data["models"].size(), 2u);
  EXPECT_EQ(data["models"][1]["label"], "run fold_01");
  EXPECT_EQ(data["models"][1]["positions_of"], 0);
}

// Issue 32: the comparison report's side-by-side strip (the photos on which the runs disagree
// most, one row per photo with every run) and its one 3D view over the runs, sharing the arrays
// of identical meshes and showing the suggested views.
TEST(CollectionReport, SideBySideStripAnd3dView) {
  const fs::path root = rephoto::testing::MakeTempDir();
  testing::WriteView3dRun(root / "a");
  testing::WriteView3dRun(root / "b");
  // Run b's 1-ncc: a 0.1, b 0.5, c 0.3, d 0.9 against a's 0.1, 0.2, 0.3, 0.4: spreads 0, 0.3,
  // 0, 0.5, so the strip shows cam_d, cam_b, then cam_a (a tie at 0 with cam_c, by name).
  WriteTextFileAtomically(root / "b" / "per_image.csv",
                          "fold,name,status,photo,render,width,height,resized,completeness,"
                          "valid_photo_windows,valid_both_windows,1-ncc,1-ncc_evaluated\n"
                          "fold_00,cam_a,ok,,,640,480,0,1,1,1,0.1,100\n"
                          "fold_00,cam_b,ok,,,640,480,0,1,1,1,0.5,100\n"
                          "fold_01,cam_c,ok,,,640,480,0,1,1,1,0.3,100\n"
                          "fold_01,cam_d,ok,,,640,480,0,1,1,1,0.9,100\n");
  WriteCollectionReport({{.label = "A", .run_dir = root / "a"}, {.label = "B", .run_dir = root / "b"}},
                        root / "c.html");
  const std::string html = ReadFileToString(root / "c.html");
  std::vector<std::string> rows;
  const std::regex row("<tr class=\"strip-row\" data-name=\"([^\"]*)\">");
  for (std::sregex_iterator it(html.begin(), html.end(), row), e; it != e; ++it) rows.push_back((*it)[1]);
  EXPECT_EQ(rows, (std::vector<std::string>{"cam_d", "cam_b", "cam_a"}));
  const size_t d = html.find("data-name=\"cam_d\">");
  const size_t end = html.find("</tr>", d);
  const std::string d_row = html.substr(d, end - d);
  EXPECT_NE(d_row.find("data-run=\"A\">1-ncc 0.4"), std::string::npos) << d_row;
  EXPECT_NE(d_row.find("data-run=\"B\">1-ncc 0.9"), std::string::npos) << d_row;
  // Chosen photos instead.
  WriteCollectionReport({{.label = "A", .run_dir = root / "a"}, {.label = "B", .run_dir = root / "b"}},
                        root / "c2.html", {.side_by_side = {"cam_c"}});
  const std::string chosen = ReadFileToString(root / "c2.html");
  rows.clear();
  for (std::sregex_iterator it(chosen.begin(), chosen.end(), row), e; it != e; ++it) rows.push_back((*it)[1]);
  EXPECT_EQ(rows, std::vector<std::string>{"cam_c"});
  // One 3D view with both runs; b's positions, faces and colours refer to a's.
  const nlohmann::json data = ViewData(html);
  ASSERT_EQ(data["models"].size(), 2u);
  EXPECT_EQ(data["models"][1]["label"], "B");
  EXPECT_EQ(data["models"][1]["positions_of"], 0);
  EXPECT_EQ(data["models"][1]["indices_of"], 0);
  EXPECT_EQ(data["models"][1]["colors_of"], 0);
  EXPECT_TRUE(data["models"][1].contains("error"));
  EXPECT_FALSE(data["models"][1].contains("positions"));
}

}  // namespace
}  // namespace rephoto::report
