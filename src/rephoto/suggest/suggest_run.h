// `rephoto suggest` as a library call (the CLI and the demo's acquisition step use it):
// camera poses for the next photos (suggest/next_views.h) and every output a user looks at.
//
// RunSuggest reads nothing itself but the projected errors: the caller gives the scene (the
// photos taken so far) and the model. It writes into options.out (created if needed; each file
// atomically):
//   sparse/                COLMAP text: the suggested cameras (views suggest_XX.png)
//   transforms.json        the same cameras for nerfstudio-style tools
//   suggestions.json       "schema": "rephoto.suggest/1" (kSuggestionsSchema; files written
//                          before it have "version": 1 instead, which readers accept); per
//                          suggestion: name, center (camera centre), look_at (the point it
//                          looks at, the model's bounding-box centre), qvec, tvec (COLMAP
//                          world-to-camera), score, unobserved_area (model units², newly seen
//                          surface no photo sees), visible_vertices, mean_error (null = none);
//                          totals total_area, unobserved_area, unobserved_area_covered (model
//                          units²); target, distance; the scene, model and run labels. All
//                          coordinates in the scene's (= model's) world units.
//   renders/suggest_XX.png the model rendered from each suggestion: what to photograph
//   report.html            suggest/suggest_page.h
// Failure behaviour: Error (one line naming the file) for projected errors that are missing or
// do not match the model, or an output that cannot be written; UsageError for a camera id the
// scene does not have or invalid options. Thread safety: reentrant (one call per out folder).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/suggest/next_views.h"
#include "rephoto/render/render_model.h"
#include "rephoto/scene/scene.h"

namespace rephoto::suggest {

inline constexpr const char* kSuggestionsSchema = "rephoto.suggest/1";

struct SuggestRunOptions {
  std::filesystem::path out;
  std::string scene_label;  // how suggestions.json and the report name the scene
  std::string model_label;  // ... and the model
  // Projected per-vertex errors: a run folder with projected/<metric>.ply (rephoto evaluate
  // with a fixed --model, or rephoto project's output) or that PLY; empty = none (only the
  // surface no photo sees counts).
  std::filesystem::path run;
  std::string metric = "1-ncc";
  int camera_id = -1;  // scene camera whose intrinsics the suggestions use (-1: the first view's)
  suggest::SuggestOptions suggest;
};

// Per-vertex errors of `run` (see SuggestRunOptions::run) for a model of `vertex_count`
// vertices. Throws Error naming the file when it is missing, has no "error" property or
// another vertex count.
std::vector<float> ReadProjectedErrors(const std::filesystem::path& run, const std::string& metric,
                                       size_t vertex_count);

// See the file comment. Returns what SuggestViews found.
suggest::SuggestResult RunSuggest(const scene::Scene& scene, const render::RenderModel& model,
                                   const SuggestRunOptions& options);

// The one-line summary the CLI prints and the demo logs ("x % of the model's surface is seen
// by no photo ... together: y % of the unseen surface").
std::string SuggestSummary(const suggest::SuggestResult& result, const SuggestRunOptions& options);

}  // namespace rephoto::suggest
