// rephoto suggest --scene S --model M [--run RUN] --count K --out DIR [--camera ID]
//                 [--candidates N] [--elevation-margin DEG]
// Proposes K camera poses for the next photos: views of the model's surface that no photo sees
// yet and of the regions with the highest projected error (src/rephoto/suggest/next_views.h).
// Writes DIR/sparse/ (COLMAP text: the suggested cameras), DIR/transforms.json,
// DIR/suggestions.json, DIR/renders/suggest_XX.png (the model rendered at each suggestion) and
// DIR/report.html (suggest/suggest_page.h: the suggested views with their rephotos, poses,
// newly covered surface and mean error).
#include <fmt/format.h>

#include <memory>
#include <string>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/suggest/suggest_run.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

struct SuggestArguments {
  std::string scene;
  SceneArguments scene_args;
  std::string model;
  std::string run;
  std::string out;
  suggest::SuggestRunOptions options;
};

CommandRunner SetupSuggest(CLI::App& app) {
  auto args = std::make_shared<SuggestArguments>();
  suggest::SuggestOptions& o = args->options.suggest;
  app.add_option("--scene", args->scene, "Scene with the photos taken so far")->required();
  AddSceneOptions(app, &args->scene_args);
  app.add_option("--model", args->model, "The reconstruction (.ply, .obj)")->required();
  app.add_option("--run", args->run,
                 "Projected errors: a run folder with projected/<metric>.ply or that PLY")
      ->check(CLI::ExistingPath);
  app.add_option("--metric", args->options.metric, "Metric of the projected errors in --run")
      ->capture_default_str();
  app.add_option("--count", o.count, "Number of poses to suggest")->capture_default_str();
  app.add_option("--out", args->out, "Output folder")->required();
  app.add_option("--camera", args->options.camera_id,
                 "Scene camera id whose intrinsics the suggestions use (default: the first "
                 "view's)");
  app.add_option("--candidates", o.candidate_count, "Candidate poses on the sphere of directions")
      ->capture_default_str();
  app.add_option("--elevation-margin", o.elevation_margin_degrees,
                 "Candidates' elevations may exceed the photos' range by this many degrees")
      ->capture_default_str();
  return [args]() {
    args->options.suggest.Check();
    const scene::Scene scene =
        scene::ReadScene(args->scene, MakeReadSceneOptions(args->scene_args, false));
    const render::RenderModel model(mesh::ReadMesh(args->model), {}, args->model);
    suggest::SuggestRunOptions options = args->options;
    options.out = args->out;
    options.scene_label = args->scene;
    options.model_label = args->model;
    options.run = args->run;
    const suggest::SuggestResult result = suggest::RunSuggest(scene, model, options);
    fmt::print("{}", suggest::SuggestSummary(result, options));
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(56, "suggest",
                "Suggest camera poses for the next photos (unseen or high-error surface)",
                SetupSuggest);

}  // namespace rephoto::cli
