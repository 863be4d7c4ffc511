// Command-line options every command that reads a scene shares: --format and --image-root.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

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

}  // namespace rephoto::cli
