// rephoto colorize MESH --scene SCENE [--images LIST] [--format F] [--image-root DIR]
//                  [--ascii] --out MESH.ply
// Colours a mesh's vertices from the photos of a scene (rephoto/render/colorize.h): per vertex
// a robust weighted mean over the photos that see it. Writes a PLY with uchar colours and a
// float "view_count" per vertex (0 = seen by no photo, colour black), atomically.
#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/render/colorize.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/split/split.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

struct ColorizeArguments {
  std::string mesh;
  std::string scene;
  std::string images;
  SceneArguments scene_args;
  std::string out;
  bool ascii = false;
  double min_cosine = render::VisibilityRule{}.min_facing_cosine;  // render/visibility.h
};

CommandRunner SetupColorize(CLI::App& app) {
  auto args = std::make_shared<ColorizeArguments>();
  app.add_option("mesh", args->mesh, "Mesh (.ply, .obj)")->required();
  app.add_option("--scene", args->scene, "Scene file or folder with cameras and photos")
      ->required();
  app.add_option("--images", args->images,
                 "List file of the photos to use, e.g. a fold's training list (default: every "
                 "view whose photo exists)");
  app.add_option("--min-cosine", args->min_cosine,
                 "A photo sees a vertex only if cos(normal, direction to camera) exceeds this")
      ->check(CLI::Range(-1.0, 1.0))
      ->capture_default_str();
  app.add_flag("--ascii", args->ascii, "Write an ASCII PLY (default: binary little endian)");
  AddSceneOptions(app, &args->scene_args);
  app.add_option("--out", args->out, "Output PLY")->required();
  return [args]() {
    const scene::ReadSceneOptions scene_options = MakeReadSceneOptions(args->scene_args);
    const scene::Scene scene = scene::ReadScene(args->scene, scene_options);
    const std::vector<size_t> views = PhotoViews(scene, args->images, args->scene);
    const mesh::Mesh mesh = mesh::ReadMesh(args->mesh);
    const auto start = std::chrono::steady_clock::now();
    render::ColorizeOptions options;
    options.min_facing_cosine = args->min_cosine;
    options.show_progress = true;
    render::ColorizeReport report;
    const mesh::Mesh colored = render::ColorizeMesh(mesh, scene, views, options, &report);
    mesh::WritePly(
        args->out, colored,
        args->ascii ? mesh::PlyEncoding::kAscii : mesh::PlyEncoding::kBinaryLittleEndian);
    LogInfo(fmt::format(
        "{}: coloured {} of {} vertices from {} photos ({} observations) in {:.1f} s -> {}",
        args->mesh, report.colored_vertices, report.vertices, views.size(), report.observations,
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
        args->out));
    if (report.colored_vertices < report.vertices) {
      LogWarning(fmt::format("{} vertices are seen by no photo (black, view_count 0)",
                             report.vertices - report.colored_vertices));
    }
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(31, "colorize", "Colour a mesh's vertices from calibrated photos", SetupColorize);

}  // namespace rephoto::cli
