// Acquisition guidance: camera poses for the next photos to take, chosen to see the parts of a
// model that no photo observes yet and the parts with the highest projected error.
//
// Surface elements are the model's vertices, each weighing its area (a third of the area of the
// faces around it; 1 per point for point clouds). A vertex is seen from a camera by the rule
// of render/visibility.h with its defaults (in the camera's usable field, projected inside the
// image, facing it with cosine > 0.05 for the area-weighted vertex normal, or the file's normals
// for point clouds, and unoccluded in the RenderModel's BVH up to 0.1 % of the distance short of
// it): the rule colorize, texturing and error projection use.
// Need of a vertex: 1 if no scene photo sees it, else its projected error mapped to [0, 1]
// between the 2.5 and 97.5 % percentiles of the finite errors (0 without errors). Its weight is
// area * need.
// Candidates: `candidate_count` directions on a Fibonacci sphere around the centre of the
// model's bounding box, at the median distance of the scene's cameras from that centre, whose
// elevation (angle to the scene's up direction: the direction most nearly
// orthogonal to the cameras' x axes, signed like their mean -y axis) lies within
// `elevation_margin_degrees` of the range of the photos' elevations, and not below the centre's
// horizon when every photo was taken from above it (the photographer stands on the ground the
// photos show, and cannot stand under it); each looks at the centre
// with the photos' mean up direction (no roll). A candidate's score is the sum of the weights of
// the vertices it sees. Greedy choice: the best candidate is taken, the weights of the vertices
// it sees become 0, and so on K times, so the suggestions cover different parts.
// Units: the model's and scene's world frame (they must agree). Thread safety: reentrant;
// parallel inside (core/parallel.h), deterministic for any thread count.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/render/render_model.h"
#include "rephoto/scene/scene.h"

namespace rephoto::suggest {

struct SuggestOptions {
  int count = 3;                         // K >= 1 poses to suggest
  int candidate_count = 400;             // >= K
  double elevation_margin_degrees = 20;  // >= 0
  void Check() const;
};

struct Suggestion {
  camera::Pose cam_from_world;
  double score = 0;             // summed weight it added when chosen (area units)
  double unobserved_area = 0;   // area of so-far-unobserved surface it newly sees
  size_t visible_vertices = 0;  // vertices it sees
  // Area-weighted mean projected error (vertex_error) of the vertices it sees that have a
  // finite error; NaN without errors or when it sees none with an error.
  double mean_error = 0;
};

struct SuggestResult {
  std::vector<Suggestion> suggestions;               // in the order chosen (best first)
  double total_area = 0;                             // sum of vertex areas
  double unobserved_area = 0;                        // area no scene photo sees
  double unobserved_area_covered = 0;                // of which the suggestions see, together
  Eigen::Vector3d target = Eigen::Vector3d::Zero();  // where the candidates look (bbox centre)
  double distance = 0;                               // candidates' distance from the target
  std::vector<uint8_t> observed;                     // per vertex: 1 when some scene photo sees it
};

// Per vertex, whether `camera` at `cam_from_world` sees it (render/visibility.h). `field` is
// camera::UsableField(camera) when the caller has it (it is the same for every pose), else null.
std::vector<uint8_t> VisibleVertices(const render::RenderModel& model,
                                     const std::vector<Eigen::Vector3f>& normals,
                                     const camera::Camera& camera,
                                     const camera::Pose& cam_from_world,
                                     const camera::UsableField* field = nullptr);

// See the file comment. `vertex_error` is empty or one value per model vertex (NaN = none).
// `camera` gives the suggested views' intrinsics. Throws Error when the scene has no views,
// vertex_error has the wrong size, or the options are invalid (UsageError).
SuggestResult SuggestViews(const render::RenderModel& model, const scene::Scene& scene,
                           const camera::Camera& camera, const std::vector<float>& vertex_error,
                           const SuggestOptions& options);

}  // namespace rephoto::suggest
