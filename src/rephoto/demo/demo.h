// `rephoto demo`: the built-in example, needing no data files.
//
// 1. Generates the procedural demo scene (synth/demo_scene.h): a ground-truth mesh and a ring
//    of calibrated cameras, and "photographs" it: each photo is the ground truth rendered with
//    16 samples per pixel, then given a small exposure difference (gain in 1 +- 8 %) and sensor
//    noise (sigma 0.01), quantized to 8 bits.
// 2. Produces several reconstructions of it, each a model file a user could open in MeshLab:
//    the ground truth itself, texture noise, geometry noise, a simplified mesh and a coloured
//    point cloud (degrade/degrade.h), and view-dependent texturing of the simplified mesh from
//    each fold's training photos (ibr/image_based_renderer.h; no model file of its own).
// 3. Evaluates each reconstruction with `rephoto evaluate` (eval/evaluate.h: the model as a
//    global reconstruction, k-fold test views so that every photo is a test photo exactly
//    once and the folds give the boxplots, error projected onto the model, a report per run),
//    then ranks the reconstructions by their median 1-NCC across folds (completeness next to
//    it) and writes one report that compares them (report/report.h).
// 4. Where to photograph next (paper Sections 5.2 and 6.2): as if only the photos from one
//    half of the ring had been taken (camera centres with x above the model's bounding-box
//    centre), `rephoto suggest` (suggest/suggest_run.h) proposes `suggestions` new views of the
//    ground-truth model, standing in for a reconstruction, that see the surface those photos
//    miss, weighing the seen surface by the ground truth's projected 1-NCC of step 3
//    (runs/ground_truth/projected/1-ncc.ply: the suggestions' "mean error"); the comparison
//    report shows them ("Where to photograph next", and as magenta frusta in its 3D view).
//
// Output folder layout (all files written atomically):
//   scene/images/view_XXX.png     the photos
//   scene/masks/view_XXX.png      their masks: 0 where the photo shows no scene (the empty
//                                 sky), as users mask the background of real photos
//   scene/sparse/                 their cameras (COLMAP text)
//   scene/ground_truth.ply        the ground-truth mesh
//   models/<reconstruction>.ply   the reconstructions
//   runs/<reconstruction>/        `rephoto evaluate` run directories (per_image.csv,
//                                 per_fold.csv, summary.json, projected/1-ncc.ply, report.html;
//                                 error images of 1-NCC only, what the reports show)
//   next_photos/photos_so_far/sparse/  the one-sided photos' cameras (COLMAP text)
//   next_photos/                  `rephoto suggest`'s outputs for them: sparse/,
//                                 transforms.json, suggestions.json, renders/, report.html
//   ranking.csv, demo.json        the reconstructions ranked by median 1-NCC (demo.json also
//                                 the acquisition step's coverage: "next_photos")
//   report.html                   the comparison of all reconstructions and the suggestions
// Rerunning into the same folder reuses every evaluation whose inputs did not change (the
// scene and photos are deterministic for the seed).
//
// Thread safety: RunDemo is a whole run writing the folder it is given (and the process's progress
// log); run at most one per folder.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "rephoto/eval/evaluate.h"
#include "rephoto/synth/demo_scene.h"

namespace rephoto::demo {

struct DemoOptions {
  std::filesystem::path out;
  synth::DemoSceneOptions scene;
  int photo_samples_per_pixel = 16;
  int render_samples_per_pixel = 4;
  double noise_sigma = 0.01;
  double max_exposure_change = 0.08;
  std::string scheme = "kfold:4";
  std::vector<metrics::Metric> metrics = metrics::AllMetrics();
  bool report = true;   // report.html per run and for the comparison
  int suggestions = 3;  // views the acquisition step suggests (0: no acquisition step)
};

// The acquisition step's outcome.
struct DemoSuggestions {
  size_t photos_so_far = 0;      // the one-sided photos
  double unseen_fraction = 0;    // of the model's surface, seen by none of them
  double covered_fraction = 0;   // of that unseen surface, seen by the suggestions together
  std::filesystem::path folder;  // next_photos/
};

struct DemoReconstruction {
  std::string name;         // e.g. "texture_noise"
  std::string description;  // what was done to the ground truth
  std::filesystem::path model;
  std::filesystem::path run_dir;
  eval::EvaluateResult result;

  // Median across folds of a metric's fold means (NaN if the metric was not computed).
  double Median(metrics::Metric metric) const;
};

struct DemoResult {
  std::vector<DemoReconstruction> ranking;     // by median 1-NCC across folds, best first
  std::optional<DemoSuggestions> suggestions;  // when DemoOptions::suggestions > 0
  double seconds = 0;
};

DemoResult RunDemo(const DemoOptions& options);

}  // namespace rephoto::demo
