// `rephoto demo`: the built-in example, needing no data files.
//
// 1. Generates the procedural demo scene (synth/demo_scene.h): a ground-truth mesh and a ring
//    of calibrated cameras, and "photographs" it: each photo is the ground truth rendered with
//    16 samples per pixel, then given a small exposure difference (gain in 1 +- 8 %) and sensor
//    noise (sigma 0.01), quantized to 8 bits.
// 2. Produces several reconstructions of it, each a model file a user could open in MeshLab:
//    the ground truth itself, texture noise, geometry noise, a simplified mesh and a coloured
//    point cloud (degrade/degrade.h).
// 3. Rephotographs every reconstruction at every camera with the built-in renderer
//    (render/render.h) and compares the rephotos with the photos (compare/compare.h), then
//    ranks the reconstructions by their median 1-NCC error, completeness next to it.
//
// Output folder layout (all files written atomically):
//   scene/images/view_XXX.png     the photos
//   scene/sparse/                 their cameras (COLMAP text)
//   scene/ground_truth.ply        the ground-truth mesh
//   models/<reconstruction>.ply   the reconstructions
//   renders/<reconstruction>/     rephotos (RGBA PNG, alpha = coverage)
//   results/<reconstruction>/     `rephoto compare` run directories (per_image.csv, ...)
//   ranking.csv, demo.json        the reconstructions ranked by median 1-NCC
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/compare/compare.h"
#include "rephoto/synth/demo_scene.h"

namespace rephoto::demo {

struct DemoOptions {
  std::filesystem::path out;
  synth::DemoSceneOptions scene;
  int photo_samples_per_pixel = 16;
  int render_samples_per_pixel = 4;
  double noise_sigma = 0.01;
  double max_exposure_change = 0.08;
  std::vector<metrics::Metric> metrics = metrics::AllMetrics();
};

struct DemoReconstruction {
  std::string name;         // e.g. "texture_noise"
  std::string description;  // what was done to the ground truth
  std::filesystem::path model;
  compare::CompareResult result;
};

struct DemoResult {
  std::vector<DemoReconstruction> ranking;  // by median 1-NCC over images, best first
};

DemoResult RunDemo(const DemoOptions& options);

}  // namespace rephoto::demo
