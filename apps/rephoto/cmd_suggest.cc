// rephoto suggest --scene S --model M [--run RUN] --count K --out DIR [--camera ID]
//                 [--candidates N] [--elevation-margin DEG]
// Proposes K camera poses for the next photos: views of the model's surface that no photo sees
// yet and of the regions with the highest projected error (src/rephoto/geometry/suggest.h).
// Writes DIR/sparse/ (COLMAP text: the suggested cameras), DIR/transforms.json,
// DIR/suggestions.json, DIR/renders/suggest_XX.png (the model rendered at each suggestion) and
// DIR/report.html (report/suggest_report.h: the suggested views with their rephotos, poses,
// newly covered surface and mean error).
#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/geometry/suggest.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/render/render.h"
#include "rephoto/report/suggest_report.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/scene/transforms_json.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

namespace fs = std::filesystem;

struct SuggestArguments {
  std::string scene;
  SceneArguments scene_args;
  std::string model;
  std::string run;
  std::string metric = "1-ncc";
  std::string out;
  int camera_id = -1;
  geometry::SuggestOptions options;
};

// The projected per-vertex error: RUN may be the PLY itself or a run folder holding
// projected/<metric>.ply (rephoto evaluate with a fixed --model, or rephoto project's output).
std::vector<float> ReadProjectedErrors(const std::string& run, const std::string& metric,
                                       size_t vertex_count) {
  fs::path path = run;
  if (fs::is_directory(path)) path = path / "projected" / (metric + ".ply");
  REPHOTO_CHECK(fs::is_regular_file(path), "{}: no projected errors (expected {})", run,
                path.string());
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

CommandRunner SetupSuggest(CLI::App& app) {
  auto args = std::make_shared<SuggestArguments>();
  geometry::SuggestOptions& o = args->options;
  app.add_option("--scene", args->scene, "Scene with the photos taken so far")->required();
  AddSceneOptions(app, &args->scene_args);
  app.add_option("--model", args->model, "The reconstruction (.ply, .obj)")->required();
  app.add_option("--run", args->run,
                 "Projected errors: a run folder with projected/<metric>.ply or that PLY")
      ->check(CLI::ExistingPath);
  app.add_option("--metric", args->metric, "Metric of the projected errors in --run")
      ->capture_default_str();
  app.add_option("--count", o.count, "Number of poses to suggest")->capture_default_str();
  app.add_option("--out", args->out, "Output folder")->required();
  app.add_option("--camera", args->camera_id,
                 "Scene camera id whose intrinsics the suggestions use (default: the first "
                 "view's)");
  app.add_option("--candidates", o.candidate_count, "Candidate poses on the sphere of directions")
      ->capture_default_str();
  app.add_option("--elevation-margin", o.elevation_margin_degrees,
                 "Candidates' elevations may exceed the photos' range by this many degrees")
      ->capture_default_str();
  return [args]() {
    args->options.Check();
    const scene::Scene scene =
        scene::ReadScene(args->scene, MakeReadSceneOptions(args->scene_args, false));
    REPHOTO_CHECK(!scene.views.empty(), "{}: the scene has no views", args->scene);
    const int camera_id = args->camera_id >= 0 ? args->camera_id : scene.views[0].camera_id;
    REPHOTO_CHECK_USAGE(scene.cameras.count(camera_id) == 1, "--camera {}: no such camera in {}",
                        camera_id, args->scene);
    const camera::Camera camera = scene.cameras.at(camera_id);
    const render::RenderModel model(mesh::ReadMesh(args->model), {}, args->model);
    const std::vector<float> errors =
        args->run.empty()
            ? std::vector<float>{}
            : ReadProjectedErrors(args->run, args->metric, model.mesh().vertex_count());
    const geometry::SuggestResult result =
        geometry::SuggestViews(model, scene, camera, errors, args->options);

    const fs::path out = args->out;
    scene::Scene suggested;
    suggested.cameras[camera_id] = camera;
    suggested.image_root = out / "renders";
    nlohmann::ordered_json json;
    json["version"] = 1;
    json["scene"] = args->scene;
    json["model"] = args->model;
    json["run"] =
        args->run.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(args->run);
    json["total_area"] = result.total_area;
    json["unobserved_area"] = result.unobserved_area;
    json["unobserved_area_covered"] = result.unobserved_area_covered;
    json["target"] = {result.target.x(), result.target.y(), result.target.z()};
    json["distance"] = result.distance;
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (size_t k = 0; k < result.suggestions.size(); ++k) {
      const geometry::Suggestion& s = result.suggestions[k];
      scene::View view;
      view.name = fmt::format("suggest_{:02d}.png", k);
      view.image_path = out / "renders" / view.name;
      view.camera_id = camera_id;
      view.cam_from_world = s.cam_from_world;
      suggested.views.push_back(view);
      const Eigen::Vector3d c = s.cam_from_world.Center();
      const Eigen::Vector4d q = s.cam_from_world.Quaternion();
      list.push_back(
          {{"name", view.name},
           {"center", {c.x(), c.y(), c.z()}},
           {"qvec", {q[0], q[1], q[2], q[3]}},
           {"tvec",
            {s.cam_from_world.translation.x(), s.cam_from_world.translation.y(),
             s.cam_from_world.translation.z()}},
           {"score", s.score},
           {"unobserved_area", s.unobserved_area},
           {"visible_vertices", s.visible_vertices},
           {"mean_error", std::isfinite(s.mean_error) ? nlohmann::ordered_json(s.mean_error)
                                                      : nlohmann::ordered_json(nullptr)}});
      const render::Rephoto rephoto = render::RenderRephoto(model, camera, s.cam_from_world);
      io::WritePng(view.image_path, rephoto.color);
    }
    json["suggestions"] = list;
    fs::create_directories(out / "sparse");
    scene::WriteColmap(suggested, out / "sparse", scene::ColmapFormat::kText);
    scene::WriteTransformsJson(suggested, out / "transforms.json");
    WriteTextFileAtomically(out / "suggestions.json", json.dump(2) + "\n");
    report::WriteSuggestionsReport(out, out / "report.html");

    const double unobserved = result.unobserved_area;
    fmt::print("{}: {:.1f} % of the model's surface is seen by no photo of {}\n", args->model,
               result.total_area > 0 ? 100 * unobserved / result.total_area : 0.0, args->scene);
    for (size_t k = 0; k < result.suggestions.size(); ++k) {
      const Eigen::Vector3d c = result.suggestions[k].cam_from_world.Center();
      fmt::print(
          "suggest_{:02d}: centre ({:.4g}, {:.4g}, {:.4g}), sees {:.1f} % of the unseen "
          "surface\n",
          k, c.x(), c.y(), c.z(),
          unobserved > 0 ? 100 * result.suggestions[k].unobserved_area / unobserved : 0.0);
    }
    fmt::print("together: {:.1f} % of the unseen surface; wrote {}\n",
               unobserved > 0 ? 100 * result.unobserved_area_covered / unobserved : 0.0,
               (out / "suggestions.json").string());
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(56, "suggest",
                "Suggest camera poses for the next photos (unseen or high-error surface)",
                SetupSuggest);

}  // namespace rephoto::cli
