// rephoto depth SCENE --out DIR [--images LIST] [--neighbors-from LIST] [--sweep-width W]
//                [--sweep-planes N] [--sweep-neighbors K] [--min-consistent M]
//                [--depth-tolerance T] [--format F] [--image-root DIR]
// Plane-sweep stereo depth maps for the selected views (rephoto/ibr/plane_sweep.h): each view
// is matched against its nearest converging views among --neighbors-from (default: all views;
// give a fold's train.txt so that no evaluation photo is used), then depths that no neighbour's
// depth map confirms are dropped. Writes DIR/<image name>.geometric.bin in COLMAP's depth-map
// format (0 = unknown), which `rephoto render --representation ibr --depth-maps DIR` reads.
#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/ibr/depth_map_io.h"
#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/ibr/training_views.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/split/split.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

struct DepthArguments {
  std::string scene;
  std::string images;
  std::string neighbors_from;
  SceneArguments scene_args;
  std::string out;
  ibr::ImageBasedOptions options;
};

// Indices of the views named in a list file (all views for an empty path).
std::vector<size_t> ViewsOf(const scene::Scene& scene, const std::string& list) {
  std::vector<size_t> out;
  if (list.empty()) {
    for (size_t v = 0; v < scene.views.size(); ++v) out.push_back(v);
    return out;
  }
  return scene::ViewIndices(scene, split::ReadImageList(list), list);
}

CommandRunner SetupDepth(CLI::App& app) {
  auto args = std::make_shared<DepthArguments>();
  app.add_option("scene", args->scene, "Scene file or folder with the cameras")->required();
  app.add_option("--images", args->images,
                 "List file of the views to compute depth for (default: all)");
  app.add_option("--neighbors-from", args->neighbors_from,
                 "List file of the views that may serve as matching neighbours (default: all)");
  app.add_option("--sweep-width", args->options.plane_sweep.max_width,
                 "Working width in pixels (0 = the photo's)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--sweep-planes", args->options.plane_sweep.num_planes, "Depth hypotheses")
      ->check(CLI::Range(2, 4096))
      ->capture_default_str();
  app.add_option("--sweep-neighbors", args->options.sweep_neighbors, "Neighbours per view")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  app.add_option("--min-consistent", args->options.sweep_min_consistent,
                 "Neighbour depth maps that must confirm a depth (0 = no filter)")
      ->check(CLI::Range(0, 16))
      ->capture_default_str();
  app.add_option("--depth-tolerance", args->options.depth_tolerance,
                 "Relative depth agreement of the consistency filter")
      ->check(CLI::Range(1e-6, 0.5))
      ->capture_default_str();
  AddSceneOptions(app, &args->scene_args);
  app.add_option("--out", args->out, "Output folder for <image name>.geometric.bin")->required();
  return [args]() {
    const scene::Scene scene =
        scene::ReadScene(args->scene, MakeReadSceneOptions(args->scene_args));
    const std::vector<size_t> targets = ViewsOf(scene, args->images);
    std::vector<size_t> pool = ViewsOf(scene, args->neighbors_from);
    // The views to estimate take part even when not in the neighbour pool (as references).
    std::vector<bool> estimate(pool.size(), false);
    std::map<size_t, size_t> position;
    for (size_t i = 0; i < pool.size(); ++i) position[pool[i]] = i;
    for (size_t t : targets) {
      if (!position.count(t)) {
        position[t] = pool.size();
        pool.push_back(t);
        estimate.push_back(false);
      }
      estimate[position[t]] = true;
    }
    ibr::ImageBasedOptions options = args->options;
    options.scene_points = ibr::ScenePoints(scene);
    options.show_progress = true;
    const std::vector<ibr::TrainingView> views = ibr::TrainingViewsFromScene(scene, pool);
    const std::vector<Image> depths = ibr::EstimateDepthMaps(views, estimate, options);
    size_t valid = 0, pixels = 0;
    for (size_t i = 0; i < pool.size(); ++i) {
      if (!estimate[i]) continue;
      ibr::WriteColmapDepthMap(
          std::filesystem::path(args->out) / (views[i].name + ".geometric.bin"), depths[i]);
      for (size_t p = 0; p < depths[i].pixel_count(); ++p)
        valid += std::isfinite(depths[i].data()[p]);
      pixels += depths[i].pixel_count();
    }
    LogInfo(fmt::format("{} depth maps -> {} ({:.1f} % of the pixels have a depth)", targets.size(),
                        args->out, pixels ? 100.0 * valid / pixels : 0.0));
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(32, "depth", "Plane-sweep depth maps of a scene's views (for --representation ibr)",
                SetupDepth);

}  // namespace rephoto::cli
