// Command-line options every command that reads a scene shares: --format and --image-root.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "rephoto/scene/read_scene.h"

namespace rephoto::cli {

struct SceneArguments {
  std::string format;      // empty = detect from the path
  std::string image_root;  // empty = the format's default
};

// Declares --format and --image-root on `app`, storing into `args` (which must outlive parsing).
void AddSceneOptions(CLI::App& app, SceneArguments* args);

// The ReadSceneOptions the arguments ask for; throws Error naming an unknown --format.
scene::ReadSceneOptions MakeReadSceneOptions(const SceneArguments& args,
                                             bool check_image_sizes = true);

// The photos a command uses: the views named in the list file `images`, or, when it is empty,
// every view whose photo exists (Error when none does). `scene_name` names the scene in messages.
std::vector<size_t> PhotoViews(const scene::Scene& scene, const std::string& images,
                               const std::string& scene_name);

}  // namespace rephoto::cli
