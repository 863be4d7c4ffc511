#include "rephoto/suggest/suggest_run.h"

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/stats.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/render/render.h"
#include "rephoto/report/view3d.h"
#include "rephoto/suggest/suggest_page.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/transforms_json.h"

namespace rephoto::suggest {
namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

namespace {

Json NumberOrNull(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

double Percent(double part, double whole) { return whole > 0 ? 100 * part / whole : 0.0; }

// The 3D view of the suggest page: the model coloured by its projected errors (when given)
// or by what no photo sees, the photos so far and the suggested views.
report::View3dData SuggestView3d(const scene::Scene& scene, const render::RenderModel& model,
                                 const std::vector<float>& errors, const SuggestResult& result,
                                 const scene::Scene& suggested, const SuggestRunOptions& options) {
  const mesh::Mesh& mesh = model.mesh();
  report::View3dModel m;
  m.label = options.model_label;
  m.metric = errors.empty() ? "" : options.metric;
  m.positions = mesh.positions;
  m.faces.assign(mesh.faces.begin(), mesh.faces.end());
  if (!errors.empty()) {
    m.error = errors;
    std::vector<double> finite;
    for (float e : errors) {
      if (std::isfinite(e)) finite.push_back(e);
    }
    if (!finite.empty()) {
      m.low = static_cast<float>(Quantile(finite, 0.025));
      m.high = static_cast<float>(Quantile(finite, 0.975));
    }
  }
  if (mesh.colors.size() == mesh.vertex_count()) {
    m.colors.resize(mesh.colors.size());
    for (size_t i = 0; i < mesh.colors.size(); ++i) {
      for (int c = 0; c < 3; ++c) {
        m.colors[i][c] =
            static_cast<uint8_t>(std::lround(255.f * std::clamp(mesh.colors[i][c], 0.f, 1.f)));
      }
    }
  }
  m.unseen.resize(result.observed.size());
  for (size_t i = 0; i < result.observed.size(); ++i) m.unseen[i] = result.observed[i] ? 0 : 1;
  report::DecimateForBrowser(m);
  auto camera_of = [](const camera::Camera& cam, const scene::View& view, const char* role) {
    return report::MakeView3dCamera(cam, view.cam_from_world.rotation,
                                    view.cam_from_world.translation, view.name, role);
  };
  for (const scene::View& view : scene.views) {
    m.cameras.push_back(camera_of(scene.CameraOf(view), view, "photo"));
  }
  report::View3dData data;
  data.mode = "unseen";  // what the suggestions are about
  data.models.push_back(std::move(m));
  for (size_t k = 0; k < suggested.views.size(); ++k) {
    report::View3dCamera c =
        camera_of(suggested.CameraOf(suggested.views[k]), suggested.views[k], "suggested");
    if (result.unobserved_area > 0) {
      c.note = fmt::format("sees {:.1f} % of the surface no photo sees",
                           100 * result.suggestions[k].unobserved_area / result.unobserved_area);
    }
    c.error = result.suggestions[k].mean_error;
    data.suggested.push_back(std::move(c));
  }
  return data;
}

}  // namespace

std::vector<float> ReadProjectedErrors(const fs::path& run, const std::string& metric,
                                       size_t vertex_count) {
  fs::path path = run;
  std::error_code ec;
  if (fs::is_directory(path, ec)) path = path / "projected" / (metric + ".ply");
  REPHOTO_CHECK(fs::is_regular_file(path, ec), "{}: no projected errors (expected {})",
                run.string(), path.string());
  const mesh::Mesh projected = mesh::ReadMesh(path);
  for (const mesh::VertexScalar& scalar : projected.scalars) {
    if (scalar.name != "error") continue;
    REPHOTO_CHECK(scalar.values.size() == vertex_count,
                  "{}: {} projected vertices but the model has {}", path.string(),
                  scalar.values.size(), vertex_count);
    return scalar.values;
  }
  ThrowError("{}: no vertex property 'error' (write it with rephoto project)", path.string());
}

suggest::SuggestResult RunSuggest(const scene::Scene& scene, const render::RenderModel& model,
                                   const SuggestRunOptions& options) {
  options.suggest.Check();
  REPHOTO_CHECK(!scene.views.empty(), "{}: the scene has no views", options.scene_label);
  const int camera_id = options.camera_id >= 0 ? options.camera_id : scene.views[0].camera_id;
  REPHOTO_CHECK_USAGE(scene.cameras.count(camera_id) == 1, "--camera {}: no such camera in {}",
                      camera_id, options.scene_label);
  const camera::Camera camera = scene.cameras.at(camera_id);
  const std::vector<float> errors =
      options.run.empty()
          ? std::vector<float>{}
          : ReadProjectedErrors(options.run, options.metric, model.mesh().vertex_count());
  const suggest::SuggestResult result =
      suggest::SuggestViews(model, scene, camera, errors, options.suggest);

  const fs::path& out = options.out;
  fs::create_directories(out / "renders");
  scene::Scene suggested;
  suggested.cameras[camera_id] = camera;
  suggested.image_root = out / "renders";
  Json json;
  json["schema"] = kSuggestionsSchema;
  json["scene"] = options.scene_label;
  json["model"] = options.model_label;
  json["run"] = options.run.empty() ? Json(nullptr) : Json(options.run.string());
  json["total_area"] = result.total_area;
  json["unobserved_area"] = result.unobserved_area;
  json["unobserved_area_covered"] = result.unobserved_area_covered;
  json["target"] = {result.target.x(), result.target.y(), result.target.z()};
  json["distance"] = result.distance;
  Json list = Json::array();
  for (size_t k = 0; k < result.suggestions.size(); ++k) {
    const suggest::Suggestion& s = result.suggestions[k];
    scene::View view;
    view.name = fmt::format("suggest_{:02d}.png", k);
    view.image_path = out / "renders" / view.name;
    view.camera_id = camera_id;
    view.cam_from_world = s.cam_from_world;
    suggested.views.push_back(view);
    const Eigen::Vector3d c = s.cam_from_world.Center();
    const Eigen::Vector4d q = s.cam_from_world.Quaternion();
    const Eigen::Vector3d& t = s.cam_from_world.translation;
    list.push_back({{"name", view.name},
                    {"center", {c.x(), c.y(), c.z()}},
                    {"look_at", {result.target.x(), result.target.y(), result.target.z()}},
                    {"qvec", {q[0], q[1], q[2], q[3]}},
                    {"tvec", {t.x(), t.y(), t.z()}},
                    {"score", s.score},
                    {"unobserved_area", s.unobserved_area},
                    {"visible_vertices", s.visible_vertices},
                    {"mean_error", NumberOrNull(s.mean_error)}});
    const render::Rephoto rephoto = render::RenderRephoto(model, camera, s.cam_from_world);
    io::WritePng(view.image_path, rephoto.color);
  }
  json["suggestions"] = list;
  fs::create_directories(out / "sparse");
  scene::WriteColmap(suggested, out / "sparse", scene::ColmapFormat::kText);
  scene::WriteTransformsJson(suggested, out / "transforms.json");
  WriteTextFileAtomically(out / "suggestions.json", json.dump(2) + "\n");
  const report::View3dData view = SuggestView3d(scene, model, errors, result, suggested, options);
  suggest::WriteSuggestionsReport(out, out / "report.html", 480, &view);
  return result;
}

std::string SuggestSummary(const suggest::SuggestResult& result,
                           const SuggestRunOptions& options) {
  const double unobserved = result.unobserved_area;
  std::string text =
      fmt::format("{}: {:.1f} % of the model's surface is seen by no photo of {}\n",
                  options.model_label, Percent(unobserved, result.total_area), options.scene_label);
  for (size_t k = 0; k < result.suggestions.size(); ++k) {
    const Eigen::Vector3d c = result.suggestions[k].cam_from_world.Center();
    text += fmt::format(
        "suggest_{:02d}: centre ({:.4g}, {:.4g}, {:.4g}), sees {:.1f} % of the unseen surface\n", k,
        c.x(), c.y(), c.z(), Percent(result.suggestions[k].unobserved_area, unobserved));
  }
  text += fmt::format("together: {:.1f} % of the unseen surface; wrote {}\n",
                      Percent(result.unobserved_area_covered, unobserved),
                      (options.out / "suggestions.json").string());
  return text;
}

}  // namespace rephoto::suggest
