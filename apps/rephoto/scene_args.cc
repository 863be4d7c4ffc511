#include "scene_args.h"

#include <filesystem>

#include "rephoto/core/error.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/split/split.h"

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

std::vector<size_t> PhotoViews(const scene::Scene& scene, const std::string& images,
                               const std::string& scene_name) {
  if (!images.empty()) return scene::ViewIndices(scene, split::ReadImageList(images), images);
  std::vector<size_t> views;
  for (size_t v = 0; v < scene.views.size(); ++v) {
    if (std::filesystem::exists(scene.views[v].image_path)) views.push_back(v);
  }
  REPHOTO_CHECK(!views.empty(), "{}: none of the scene's photos exists on disk", scene_name);
  return views;
}

}  // namespace rephoto::cli
