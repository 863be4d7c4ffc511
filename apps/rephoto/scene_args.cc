#include "scene_args.h"

#include "rephoto/core/error.h"

namespace rephoto::cli {

void AddSceneOptions(CLI::App& app, SceneArguments* args) {
  app.add_option("--format", args->format,
                 "Scene format instead of detection: " + scene::SceneFormatList());
  app.add_option("--image-root", args->image_root,
                 "Folder the image names are relative to (default: the format's)");
}

scene::ReadSceneOptions MakeReadSceneOptions(const SceneArguments& args, bool check_image_sizes) {
  scene::ReadSceneOptions options;
  if (!args.format.empty()) {
    options.format = scene::ParseSceneFormat(args.format);
    REPHOTO_CHECK(options.format.has_value(), "--format '{}': unknown format (supported: {})",
                  args.format, scene::SceneFormatList());
  }
  if (!args.image_root.empty()) options.image_root = args.image_root;
  options.check_image_sizes = check_image_sizes;
  return options;
}

}  // namespace rephoto::cli
