// Building ImageBasedRenderer inputs from a calibrated scene (for `rephoto render`,
// `rephoto depth` and the evaluation's folds).
//
// Thread safety: reentrant (reads the scene and files; no shared state).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <vector>

#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/scene/scene.h"

namespace rephoto::ibr {

// Training views for scene.views[i], i in `indices` (in that order). With a non-empty
// `depth_maps_dir`, each view's depth map is the first existing file among
//   <dir>/<name>.geometric.bin, <dir>/<name>.photometric.bin (COLMAP's stereo/depth_maps
//   naming, <name> = the image name), <dir>/<name>.bin, <dir>/<stem>.pfm, <dir>/<stem>.exr,
//   <dir>/<stem>.depth.exr (<stem> = the image name without extension),
// and empty (estimated by plane sweep) when none exists. Throws Error for an index out of range.
std::vector<TrainingView> TrainingViewsFromScene(const scene::Scene& scene,
                                                 const std::vector<size_t>& indices,
                                                 const std::filesystem::path& depth_maps_dir = {});

// The scene's sparse points (world coordinates), for ImageBasedOptions::scene_points.
std::vector<Eigen::Vector3d> ScenePoints(const scene::Scene& scene);

}  // namespace rephoto::ibr
