// rephoto project MODEL --scene SCENE [--format F] [--image-root R] --errors RUN_DIR
//                 [--metric 1-ncc] --out OUT.ply [--low-percentile P] [--high-percentile P]
//                 [--range LOW HIGH] [--depth-tolerance T] [--footprint-tolerance K]
//                 [--scale-cameras] [--no-backfaces] [--point-radius R] [--point-neighbors K]
// Projects the per-pixel error images of a `rephoto evaluate` or `rephoto compare` run onto a
// mesh or point cloud: per-vertex mean over the views that see the vertex (depth-tested against
// the model's rendered depth), written as a PLY with jet colours between two percentiles, a
// float "error" and a uint "views" property (src/rephoto/project/project.h).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "command.h"
#include "rephoto/compare/compare.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/project/project.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"
#include "rephoto/splat/scalar_ply.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

struct ProjectArguments {
  std::string model;
  std::string scene;
  SceneArguments scene_args;
  std::string errors;
  std::string metric = "1-ncc";
  std::string out;
  project::ProjectOptions options;
  std::vector<float> range;
  bool no_backfaces = false;
  std::string gaussian_mode = "classic";
  std::string background = "black";
};

CommandRunner SetupProject(CLI::App& app) {
  auto args = std::make_shared<ProjectArguments>();
  project::ProjectOptions& o = args->options;
  app.add_option("model", args->model,
                 "Mesh, point cloud or 3D Gaussian splatting model (.ply, .obj, .splat) the errors "
                 "belong to")
      ->required();
  app.add_option("--scene", args->scene, "Scene file or folder with the evaluation cameras")
      ->required();
  AddSceneOptions(app, &args->scene_args);
  app.add_option("--errors", args->errors,
                 "Run directory of rephoto evaluate (folds/*/errors/) or rephoto compare "
                 "(errors/)")
      ->required();
  app.add_option("--metric", args->metric, "Metric whose error images are projected")
      ->capture_default_str();
  app.add_option("--out", args->out, "Output PLY (colours, float error, uint views)")->required();
  app.add_option("--low-percentile", o.low_percentile,
                 "Percentile of the vertex errors mapped to dark blue")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_option("--high-percentile", o.high_percentile,
                 "Percentile of the vertex errors mapped to dark red")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_option("--range", args->range,
                 "Fixed colour range LOW HIGH in error units instead of the percentiles")
      ->expected(2);
  app.add_option("--depth-tolerance", o.depth_tolerance,
                 "Depth test: allowed |vertex depth - rendered depth| relative to the depth")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--footprint-tolerance", o.footprint_tolerance,
                 "Depth test: plus this many pixel footprints (depth / focal length)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_flag("--scale-cameras", o.scale_cameras,
               "Scale a camera to its error image when only the resolution differs (an "
               "evaluation at reduced resolution); otherwise a size mismatch is an error");
  app.add_flag("--no-backfaces", args->no_backfaces,
               "The errors were rendered without the back sides of triangles");
  app.add_option("--gaussian-mode", args->gaussian_mode,
                 "Gaussian splatting models: classic or antialiased, as they were rendered")
      ->check(CLI::IsMember({"classic", "antialiased"}))
      ->capture_default_str();
  app.add_option("--background", args->background,
                 "Gaussian splatting models: the background R,G,B, black or white they were "
                 "rendered over")
      ->capture_default_str();
  app.add_option("--point-radius", o.model_options.point_radius,
                 "Splat radius of point clouds in model units, as rendered (default: the file's "
                 "radius, else the distance to the k-th nearest neighbour)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--point-neighbors", o.model_options.point_radius_neighbors,
                 "k of the k-th nearest neighbour radius, as rendered")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  return [args]() {
    project::ProjectOptions options = args->options;
    options.backfaces = !args->no_backfaces;
    options.show_progress = true;
    REPHOTO_CHECK(options.low_percentile <= options.high_percentile,
                  "--low-percentile {} is above --high-percentile {}", options.low_percentile,
                  options.high_percentile);
    if (!args->range.empty()) {
      options.fixed_range = std::make_pair(args->range[0], args->range[1]);
    }
    if (const auto metric = metrics::ParseMetric(args->metric)) {
      options.higher_is_better = metrics::ErrorImageHigherIsBetter(*metric);
    }

    const auto start = std::chrono::steady_clock::now();
    const scene::Scene scene =
        scene::ReadScene(args->scene, MakeReadSceneOptions(args->scene_args, false));
    size_t without = 0, unmatched = 0;
    const std::vector<project::ProjectView> views =
        project::FindErrorImages(scene, args->errors, args->metric, &without, &unmatched);
    if (views.empty()) {
      const std::vector<std::string> available = project::ListErrorMetrics(args->errors);
      if (unmatched > 0) {
        ThrowError(
            "{}: none of its {} error images for '{}' belongs to a view of {} (a run of another "
            "scene?)",
            args->errors, unmatched, args->metric, args->scene);
      }
      ThrowError("{}: no error images for metric '{}' (available: {})", args->errors, args->metric,
                 available.empty() ? "none" : fmt::format("{}", fmt::join(available, ", ")));
    }
    if (without > 0) {
      LogWarning(fmt::format("{} of {} views of {} have no '{}' error image in {} (skipped)",
                             without, scene.views.size(), args->scene, args->metric, args->errors));
    }
    if (unmatched > 0) {
      LogWarning(fmt::format("{} '{}' error images in {} belong to no view of {} (ignored)",
                             unmatched, args->metric, args->errors, args->scene));
    }

    if (splat::IsGaussianFile(args->model)) {
      // 3D Gaussians: the mean error per Gaussian, weighted by its blending weights, added to
      // the model's own file as a float "error" (project.h, splat/scalar_ply.h).
      splat::GaussianRenderOptions gaussian_options;
      gaussian_options.mode = *splat::ParseGaussianMode(args->gaussian_mode);
      gaussian_options.background = splat::ParseBackground(args->background, "--background");
      const splat::GaussianModel gaussians = splat::ReadGaussians(args->model);
      size_t seen = 0;
      const std::vector<float> error =
          project::ProjectErrorsOntoGaussians(gaussians, views, gaussian_options, options, &seen);
      splat::WriteGaussiansWithScalar(args->model, gaussians, "error", error, args->out);
      fmt::print("{}: projected {} error images of '{}' onto {} Gaussians: {} seen ({:.1f} %)\n",
                 args->model, views.size(), args->metric, gaussians.size(), seen,
                 100.0 * static_cast<double>(seen) / static_cast<double>(gaussians.size()));
      fmt::print("wrote {} ({:.2f} s)\n", args->out,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      return static_cast<int>(ExitCode::kOk);
    }
    const mesh::Mesh model = mesh::ReadMesh(args->model);
    REPHOTO_CHECK(model.vertex_count() > 0, "{}: the model has no vertices", args->model);
    const project::ProjectResult result = project::ProjectErrors(model, views, options);
    project::WriteProjectedPly(model, result, args->out);

    const size_t n = model.vertex_count();
    fmt::print(
        "{}: projected {} error images of '{}' onto {} {}: {} seen ({:.1f} %), {} more "
        "visible without a finite error\n",
        args->model, views.size(), args->metric, n, model.is_point_cloud() ? "points" : "vertices",
        result.seen_vertices,
        100.0 * static_cast<double>(result.seen_vertices) / static_cast<double>(n),
        result.visible_vertices - std::min(result.visible_vertices, result.seen_vertices));
    if (result.seen_vertices > 0) {
      if (options.fixed_range) {
        fmt::print("colour range [{:.4g}, {:.4g}] (fixed)\n", result.low, result.high);
      } else {
        fmt::print("colour range [{:.4g}, {:.4g}] ({:g} and {:g} percentiles{})\n", result.low,
                   result.high, options.low_percentile, options.high_percentile,
                   options.higher_is_better ? ", reversed: higher is better" : "");
      }
    }
    fmt::print("wrote {} ({:.2f} s: depth rendering {:.2f} s, projection {:.2f} s)\n", args->out,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
               result.render_seconds, result.project_seconds);
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(50, "project",
                "Project per-pixel error images onto the model (per-vertex mean, jet-coloured "
                "PLY)",
                SetupProject);

}  // namespace rephoto::cli
