// rephoto render [MODEL] --scene SCENE [--images LIST] [--spp N] [--no-backfaces]
//                [--point-radius R] [--format F] [--image-root DIR] --out DIR
//                [--representation auto|vdt|ibr|gaussians] [--training LIST] [--depth-maps DIR]
//                [--k-best K] [--depth-tolerance T] [--sweep-width W] [--sweep-planes N]
//                [--gaussian-mode classic|antialiased] [--background R,G,B] [--no-depth]
// Rephotographs a reconstruction at every selected camera of a scene, at each camera's own
// resolution and distortion:
// - auto (default): MODEL (mesh or point cloud, PLY/OBJ) with the built-in Embree renderer
//   (rephoto/render/render.h): vertex colours, textures or splats, from what the file holds; a
//   3D Gaussian splatting model (a PLY with Gaussian properties, a compressed PLY or a .splat
//   file, rephoto/splat/gaussians.h) is detected and rendered as with `gaussians`.
// - gaussians: MODEL as 3D Gaussians with the CPU rasterizer (rephoto/splat/rasterize.h: the
//   reference CUDA rasterizer's forward pass; --gaussian-mode antialiased as gsplat's; RGB over
//   --background, default black; one sample at each pixel centre, --spp does not apply).
// - vdt: view-dependent texturing of the training photos on MODEL as geometry proxy
//   (rephoto/ibr/image_based_renderer.h).
// - ibr: image-based rendering of the training photos with per-view depth maps (--depth-maps:
//   COLMAP stereo/depth_maps/*.bin, PFM or EXR, see ibr/training_views.h; views without one get
//   a plane-sweep estimate from their training neighbours). MODEL is not used.
// Training photos for vdt/ibr: --training (a list file, or comma-separated image names); without
// it each view is rendered from all other views of the scene (leave-one-out: one renderer per
// rendered view). A rendered view that is also a training view is reported: the renderer then
// reproduces its own photo and the error is meaningless (paper Section 4.4).
// Writes DIR/<image name without extension>.png (RGBA 8-bit; alpha = coverage, the
// completeness mask) and DIR/<...>.depth.exr (camera-frame z, NaN where empty; not with
// --no-depth, which also removes an earlier run's depth map of each rendered view, so that
// `tar cf renders.tar -C DIR .` holds only the PNGs), atomically.
// Which renderer renders what is decided in the library (rephoto/representation/make_renderer.h,
// shared with `rephoto evaluate`); this file parses the flags and reads the scene.
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <set>
#include <string>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/render/view_renderer.h"
#include "rephoto/representation/make_renderer.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/splat/rasterize.h"
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
  std::string representation = "auto";
  std::string training;
  std::string depth_maps;
  ibr::ImageBasedOptions ibr_options;
  std::string gaussian_mode = "classic";
  std::string background = "0,0,0";
  bool no_depth = false;
};

// Scene view indices of a --training value: a list file when such a file exists, else
// comma-separated image names. Throws Error naming an unknown image.
std::vector<size_t> TrainingIndices(const scene::Scene& scene, const std::string& value) {
  std::vector<std::string> names;
  if (std::filesystem::is_regular_file(value)) {
    names = split::ReadImageList(value);
  } else {
    size_t begin = 0;
    while (begin <= value.size()) {
      const size_t end = std::min(value.find(',', begin), value.size());
      if (end > begin) names.push_back(value.substr(begin, end - begin));
      begin = end + 1;
    }
  }
  const std::vector<size_t> indices = scene::ViewIndices(scene, names, "--training " + value);
  REPHOTO_CHECK(!indices.empty(), "--training {}: no images", value);
  return indices;
}

// Indices of the views named in the list file (all views without one); throws Error naming an
// unknown image.
std::vector<size_t> SelectViews(const scene::Scene& scene, const std::string& list) {
  std::vector<size_t> selected;
  if (list.empty()) {
    for (size_t v = 0; v < scene.views.size(); ++v) selected.push_back(v);
    return selected;
  }
  return scene::ViewIndices(scene, split::ReadImageList(list), list);
}

// Output names, one per view; throws Error when two views map to the same name.
std::vector<std::string> OutputStems(const RenderArguments& args, const scene::Scene& scene,
                                     const std::vector<size_t>& views) {
  std::set<std::filesystem::path> seen;
  std::vector<std::string> stems;
  for (size_t v : views) {
    const std::filesystem::path stem =
        std::filesystem::path(scene.views[v].name).replace_extension("");
    REPHOTO_CHECK(seen.insert(stem).second,
                  "{}: two selected images map to the same output name '{}'", args.scene,
                  stem.string());
    stems.push_back(stem.string());
  }
  return stems;
}

// The flags as the renderers' settings (enums parsed here, once).
representation::RendererSettings Settings(const RenderArguments& args) {
  representation::RendererSettings settings;
  settings.render.samples_per_pixel = args.spp;
  settings.render.backfaces = !args.no_backfaces;
  settings.model.point_radius = args.point_radius;
  settings.model.point_radius_neighbors = args.point_neighbors;
  settings.gaussians.mode =
      representation::GaussianModeFromName(args.gaussian_mode, "--gaussian-mode");
  settings.gaussians.background = splat::ParseBackground(args.background, "--background");
  settings.image_based = args.ibr_options;
  settings.image_based.show_progress = true;
  return settings;
}

CommandRunner SetupRender(CLI::App& app) {
  auto args = std::make_shared<RenderArguments>();
  app.add_option("model", args->model,
                 "Mesh or point cloud (.ply, .obj); the geometry proxy for vdt; unused by ibr");
  app.add_option("--scene", args->scene, "Scene file or folder with the cameras")->required();
  app.add_option("--images", args->images,
                 "List file of the image names to render (one per line; default: all views)");
  CLI::Option* spp_option =
      app.add_option("--spp", args->spp,
                     "Samples per pixel (stratified, jittered, deterministic; not for Gaussians)")
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
  app.add_option("--representation", args->representation,
                 "auto: render MODEL as it is (Gaussian splatting files detected); vdt: "
                 "view-dependent texturing of the training photos on MODEL; ibr: image-based "
                 "rendering with per-view depth maps; gaussians: MODEL as 3D Gaussians")
      ->check(CLI::IsMember({"auto", "vdt", "ibr", "gaussians"}))
      ->capture_default_str();
  app.add_option("--gaussian-mode", args->gaussian_mode,
                 "Gaussians: classic (graphdeco's rasterizer) or antialiased (gsplat's "
                 "rasterize_mode=antialiased: opacity scaled by sqrt(det cov / det(cov + 0.3 I)))")
      ->check(CLI::IsMember({"classic", "antialiased"}))
      ->capture_default_str();
  app.add_option("--background", args->background,
                 "Gaussians: background colour R,G,B in [0, 1], black or white (the colour "
                 "the model was trained against)")
      ->capture_default_str();
  app.add_option("--training", args->training,
                 "vdt/ibr training photos: a list file (e.g. a split's train.txt) or "
                 "comma-separated image names (default: all other views, leave-one-out)");
  app.add_option("--depth-maps", args->depth_maps,
                 "ibr: folder of per-view depth maps (<name>.geometric.bin as COLMAP's "
                 "stereo/depth_maps, <stem>.pfm, <stem>.exr); missing ones are estimated");
  app.add_option("--k-best", args->ibr_options.k_best, "vdt/ibr: views fused per pixel")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  app.add_option("--depth-tolerance", args->ibr_options.depth_tolerance,
                 "vdt/ibr: relative depth agreement of the visibility test")
      ->check(CLI::Range(1e-6, 0.5))
      ->capture_default_str();
  app.add_option("--sweep-width", args->ibr_options.plane_sweep.max_width,
                 "ibr plane sweep: working width in pixels (0 = full)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--sweep-planes", args->ibr_options.plane_sweep.num_planes,
                 "ibr plane sweep: depth hypotheses")
      ->check(CLI::Range(2, 4096))
      ->capture_default_str();
  AddSceneOptions(app, &args->scene_args);
  app.add_flag("--no-depth", args->no_depth,
               "Write only the PNGs, no <name>.depth.exr (removes those of an earlier run)");
  app.add_option("--out", args->out, "Output folder for <name>.png and <name>.depth.exr")
      ->required();
  return [args, spp_option]() {
    const representation::RendererSettings settings = Settings(*args);
    const render::ViewRepresentation requested =
        representation::RepresentationFromName(args->representation, "--representation");
    const scene::ReadSceneOptions scene_options = MakeReadSceneOptions(args->scene_args);
    const scene::Scene scene = scene::ReadScene(args->scene, scene_options);
    const std::vector<size_t> views = SelectViews(scene, args->images);
    const std::vector<std::string> stems = OutputStems(*args, scene, views);

    const render::ViewRepresentation resolved =
        representation::ResolveRepresentation(requested, args->model);
    if (resolved == render::ViewRepresentation::kGaussians && spp_option->count() > 0) {
      LogWarning("--spp does not apply to Gaussians (one sample at each pixel centre, as 3DGS)");
    }
    const representation::Models models =
        representation::LoadModels(resolved, args->model, settings);
    if (render::IsImageBased(resolved) && args->training.empty()) {
      representation::RenderLeaveOneOut(resolved, models, scene, views, stems, args->depth_maps,
                                        settings, args->out, !args->no_depth);
    } else {
      representation::TrainingPhotos training{&scene, {}, args->depth_maps};
      if (render::IsImageBased(resolved)) {
        training.views = TrainingIndices(scene, args->training);
        representation::WarnRenderedTrainingPhotos(scene, training.views, views);
      }
      const std::unique_ptr<render::ViewRenderer> renderer =
          representation::MakeRenderer(resolved, models, training, settings);
      Progress progress("render", views.size());
      render::RenderViews(*renderer, scene, views, stems, args->out, &progress, !args->no_depth);
      progress.Finish();
    }
    LogInfo(fmt::format("rendered {} views -> {}", views.size(), args->out));
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(
    30, "render",
    "Rephotograph a mesh, point cloud, Gaussian splatting model or image-based representation "
    "at a scene's cameras",
    SetupRender);

}  // namespace rephoto::cli
