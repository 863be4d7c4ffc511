// rephoto scene info SCENE [--format F] [--image-root DIR] [--json]
// Reads a scene of any supported format (rephoto/scene/read_scene.h) and prints a summary
// (rephoto/scene/scene_info.h): images, cameras per model, resolution range, bounding boxes of
// the camera centres and points, where the optical axes meet, images missing on disk.
// --json prints the same as one JSON object on stdout for scripts.
#include <fmt/format.h>

#include <memory>
#include <string>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/scene/scene_info.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

struct SceneInfoArguments {
  std::string scene;
  SceneArguments scene_args;
  bool json = false;
  bool no_size_check = false;
};

CommandRunner SetupScene(CLI::App& app) {
  app.require_subcommand(1);
  CLI::App* info = app.add_subcommand("info", "Summarize a scene (images, cameras, extent)");
  auto args = std::make_shared<SceneInfoArguments>();
  info->add_option("scene", args->scene, "Scene file or folder (format detected)")->required();
  AddSceneOptions(*info, &args->scene_args);
  info->add_flag("--json", args->json, "Print one JSON object instead of text");
  info->add_flag("--no-size-check", args->no_size_check,
                 "Do not check image sizes on disk against the cameras");
  return [args]() {
    scene::SceneSource source;
    const scene::Scene scene = scene::ReadScene(
        args->scene, MakeReadSceneOptions(args->scene_args, !args->no_size_check), &source);
    const scene::SceneInfo info = scene::ComputeSceneInfo(
        scene, source.path.string(), std::string(scene::SceneFormatName(source.format)));
    if (args->json) {
      fmt::print("{}\n", scene::SceneInfoToJson(info).dump(2));
    } else {
      fmt::print("{}", scene::FormatSceneInfo(info));
    }
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(10, "scene", "Inspect a calibrated scene (info)", SetupScene);

}  // namespace rephoto::cli
