// `rephoto suggest`'s outputs as a user reads them (issue 32): suggestions.json says "schema"
// like every other file (an old file's "version": 1 still reads), the page gives each view as
// "camera at (x, y, z) looking at (x, y, z)" in the scene's units and the unseen area in model
// units² and % of the surface, and the mean error column has values when projected errors are
// given (a constant error of 0.5 on every vertex: every suggestion's area-weighted mean is
// 0.5).
#include "rephoto/suggest/suggest_page.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/project/project.h"
#include "rephoto/suggest/suggest_run.h"
#include "rephoto/synth/demo_scene.h"
#include "rephoto/testing/testing.h"

namespace rephoto::suggest {
namespace {
namespace fs = std::filesystem;

TEST(SuggestPage, SchemaWhereToStandAreasAndMeanErrors) {
  const fs::path root = testing::MakeTempDir();
  synth::DemoSceneOptions demo;
  demo.image_width = 160;
  demo.image_height = 120;
  demo.camera_count = 8;
  demo.ground_cells = 30;
  demo.object_bands = 30;
  const mesh::Mesh truth = synth::MakeDemoMesh(demo);
  scene::Scene scene = synth::MakeDemoScene(demo, root / "images");
  std::vector<scene::View> one_side;
  for (const scene::View& view : scene.views) {
    if (view.cam_from_world.Center().x() > 0) one_side.push_back(view);
  }
  scene.views = one_side;
  // Projected errors: 0.5 on every vertex.
  project::ProjectResult projected;
  projected.vertex_error.assign(truth.vertex_count(), 0.5f);
  projected.view_count.assign(truth.vertex_count(), 1);
  projected.low = 0;
  projected.high = 1;
  project::WriteProjectedPly(truth, projected, root / "run" / "projected" / "1-ncc.ply");
  SuggestRunOptions options;
  options.out = root / "next";
  options.scene_label = "scene";
  options.model_label = "truth.ply";
  options.run = root / "run";
  options.suggest.count = 2;
  const render::RenderModel model(truth);
  const SuggestResult result = RunSuggest(scene, model, options);
  ASSERT_EQ(result.suggestions.size(), 2u);

  const nlohmann::json json =
      nlohmann::json::parse(ReadFileToString(options.out / "suggestions.json"));
  EXPECT_EQ(json["schema"], "rephoto.suggest/1");
  EXPECT_FALSE(json.contains("version"));
  const std::string html = ReadFileToString(options.out / "report.html");
  for (size_t k = 0; k < 2; ++k) {
    const nlohmann::json& s = json["suggestions"][k];
    EXPECT_NEAR(s["mean_error"].get<double>(), 0.5, 1e-6);
    // The camera centre of the pose (C = -R^T t) and the point it looks at (the target).
    const Eigen::Vector3d c = result.suggestions[k].cam_from_world.Center();
    EXPECT_NEAR(s["center"][0].get<double>(), c.x(), 1e-9);
    const std::string where = fmt::format(
        "camera at ({:.4g}, {:.4g}, {:.4g}) looking at ({:.4g}, {:.4g}, {:.4g})", c.x(), c.y(),
        c.z(), result.target.x(), result.target.y(), result.target.z());
    EXPECT_NE(html.find("<span class=\"where\">" + where + "</span>"), std::string::npos) << where;
    // It looks at the target: the viewing direction points from C to it.
    const Eigen::Vector3d to_target = (result.target - c).normalized();
    EXPECT_NEAR(result.suggestions[k].cam_from_world.ViewDirection().dot(to_target), 1, 1e-6);
    EXPECT_NE(html.find(fmt::format("data-mean-error=\"{}\"", 0.5)), std::string::npos);
  }
  // The mean error column: no "–".
  EXPECT_EQ(html.find("<td>\u2013</td></tr>"), std::string::npos);
  // Areas in model units² and as shares of the unseen and the whole surface.
  const double area0 = result.suggestions[0].unobserved_area;
  EXPECT_NE(html.find(fmt::format("{:.1f} % of the unseen surface, {:.1f} % of the whole",
                                  100 * area0 / result.unobserved_area,
                                  100 * area0 / result.total_area)),
            std::string::npos);
  EXPECT_NE(html.find("units\u00b2"), std::string::npos);
  // The 3D view with the photos so far and the suggested views.
  EXPECT_NE(html.find("<div class=\"view3d\" id=\"view3d\">"), std::string::npos);

  // Files written before the rename ("version": 1) still read; other versions do not.
  std::string text = ReadFileToString(options.out / "suggestions.json");
  const size_t at = text.find("\"schema\": \"rephoto.suggest/1\"");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, std::string("\"schema\": \"rephoto.suggest/1\"").size(), "\"version\": 1");
  WriteTextFileAtomically(options.out / "suggestions.json", text);
  EXPECT_NO_THROW(WriteSuggestionsReport(options.out, root / "old.html"));
  EXPECT_NE(ReadFileToString(root / "old.html").find("camera at ("), std::string::npos);
  text.replace(text.find("\"version\": 1"), 12, "\"version\": 2");
  WriteTextFileAtomically(options.out / "suggestions.json", text);
  EXPECT_THROW(WriteSuggestionsReport(options.out, root / "new.html"), Error);
}

}  // namespace
}  // namespace rephoto::suggest
