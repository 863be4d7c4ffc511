// rephoto render MODEL --scene SCENE [--images LIST] [--spp N] [--no-backfaces]
//                [--point-radius R] [--format F] [--image-root DIR] --out DIR
// Rephotographs a mesh or point cloud (PLY, OBJ) at every selected camera of a scene with the
// built-in Embree renderer (rephoto/render/render.h), at each camera's own resolution and
// distortion. Writes DIR/<image name without extension>.png (RGBA 8-bit; alpha = coverage, the
// completeness mask) and DIR/<...>.depth.exr (camera-frame z, NaN where empty), atomically.
#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/render/render.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/split/split.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

struct RenderArguments {
  std::string model;
  std::string scene;
  std::string images;
  SceneArguments scene_args;
  std::string out;
  int spp = 4;
  bool no_backfaces = false;
  float point_radius = 0;
  int point_neighbors = 6;
};

// Indices of the views named in the list file (all views without one); throws Error naming an
// unknown image.
std::vector<size_t> SelectViews(const scene::Scene& scene, const std::string& list) {
  std::vector<size_t> selected;
  if (list.empty()) {
    for (size_t v = 0; v < scene.views.size(); ++v) selected.push_back(v);
    return selected;
  }
  std::map<std::string, size_t> by_name;
  for (size_t v = 0; v < scene.views.size(); ++v) by_name[scene.views[v].name] = v;
  for (const std::string& name : split::ReadImageList(list)) {
    const auto it = by_name.find(name);
    REPHOTO_CHECK(it != by_name.end(), "{}: image '{}' is not in the scene", list, name);
    selected.push_back(it->second);
  }
  return selected;
}

CommandRunner SetupRender(CLI::App& app) {
  auto args = std::make_shared<RenderArguments>();
  app.add_option("model", args->model, "Mesh or point cloud (.ply, .obj)")->required();
  app.add_option("--scene", args->scene, "Scene file or folder with the cameras")->required();
  app.add_option("--images", args->images,
                 "List file of the image names to render (one per line; default: all views)");
  app.add_option("--spp", args->spp, "Samples per pixel (stratified, jittered, deterministic)")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  app.add_flag("--no-backfaces", args->no_backfaces, "Do not render the back sides of triangles");
  app.add_option("--point-radius", args->point_radius,
                 "Splat radius of point clouds in model units (default: the file's radius, else "
                 "the distance to the k-th nearest neighbour)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--point-neighbors", args->point_neighbors,
                 "k of the k-th nearest neighbour radius")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  AddSceneOptions(app, &args->scene_args);
  app.add_option("--out", args->out, "Output folder for <name>.png and <name>.depth.exr")
      ->required();
  return [args]() {
    const scene::ReadSceneOptions scene_options = MakeReadSceneOptions(args->scene_args);
    const scene::Scene scene = scene::ReadScene(args->scene, scene_options);
    const std::vector<size_t> views = SelectViews(scene, args->images);

    const auto start = std::chrono::steady_clock::now();
    render::ModelOptions model_options;
    model_options.point_radius = args->point_radius;
    model_options.point_radius_neighbors = args->point_neighbors;
    const render::RenderModel model(mesh::ReadMesh(args->model), model_options, args->model);
    LogInfo(
        fmt::format("{}: {} vertices, {} triangles, prepared in {:.2f} s (BVH {:.2f} s)",
                    args->model, model.mesh().vertex_count(), model.mesh().face_count(),
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                    model.build_seconds()));

    render::RenderOptions options;
    options.samples_per_pixel = args->spp;
    options.backfaces = !args->no_backfaces;
    const std::filesystem::path out(args->out);
    std::set<std::filesystem::path> written;
    render::Rephoto rephoto;
    Progress progress("render", views.size());
    for (size_t v : views) {
      const scene::View& view = scene.views[v];
      const std::filesystem::path stem = std::filesystem::path(view.name).replace_extension("");
      REPHOTO_CHECK(written.insert(stem).second,
                    "{}: two selected images map to the same output name '{}'", args->scene,
                    stem.string());
      const auto rays = model.RaysFor(scene.CameraOf(view));
      render::RenderRephoto(model, *rays, view.cam_from_world, options, &rephoto);
      io::WritePng(out / (stem.string() + ".png"), rephoto.color);
      io::WriteExr(out / (stem.string() + ".depth.exr"), rephoto.depth);
      progress.Advance(view.name);
    }
    progress.Finish();
    LogInfo(fmt::format("rendered {} views -> {}", views.size(), args->out));
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(30, "render", "Rephotograph a mesh or point cloud at a scene's cameras",
                SetupRender);

}  // namespace rephoto::cli
