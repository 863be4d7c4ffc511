// Per-face view selection (Waechter, Moehrle and Goesele 2014, "Let there be color!", Sec. 4),
// internal to texture/.
//
// Candidates. View v is a candidate of face f when
//   - f faces the camera: n_f . (C - c_f) / |C - c_f| > min_facing_cosine (n_f the unit face
//     normal from the winding, c_f the centroid, C the camera centre);
//   - its three corners project (with the camera's distortion) inside the photo, at least half
//     a pixel from the border;
//   - Embree occlusion rays from C to the centroid and to a barycentric grid of points on the
//     face (the corners for faces up to 24 pixels long in the photo; one more row of points
//     per 24 pixels of the longest projected edge, up to 13 per edge; each point moved 1 % of
//     the way towards the centroid, so that the neighbouring faces sharing a corner or an edge
//     do not count) meet no surface before (1 - occlusion_epsilon) of their length: a large
//     face is not visible when something hides its middle but not its corners.
//   Faces that no photo sees whole this way may use photos that see part of them (an
//   extension for coarse meshes, whose large faces are often cut by the image border or
//   partly hidden in every photo): "partial" candidates, where at least
//   `partial_min_fraction` of the sample points project inside the photo and are unoccluded;
//   their quality is multiplied by that fraction and by `partial_weight`. They are dropped
//   for every face that has a whole view (0 = no partial candidates).
// Quality (the data term's input): the gradient magnitude integral over the face's projection
// (GMI, as the paper), plus `gradient_floor` per covered pixel: sum over the pixel centres
// inside the projected triangle (straight edges between the distorted corners) of
// (|Sobel gradient of luma| + gradient_floor). The floor keeps untextured surfaces from
// getting quality 0 in every view: there the term falls back to the projected area in pixels,
// i.e. it favours close and frontal views. A projection covering no pixel centre counts its
// area times the value at the centroid. The face's mean colour in the view (over the same
// pixels, or the centroid sample) is kept for the photo-consistency check.
// Deterministic for any thread count (per-view lists in face order, views in list order).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <utility>
#include <vector>

#include "rephoto/render/render_model.h"
#include "rephoto/scene/scene.h"
#include "rephoto/texture/mrf.h"

namespace rephoto::texture {

struct FaceCandidate {
  uint32_t view = 0;      // position in the `views` list given to ComputeCandidates
  float quality = 0;      // see above, >= 0
  Eigen::Vector3f color;  // mean RGB of the face in that photo
  bool partial = false;   // the photo sees only part of the face
};

// Candidates of every face: items[offsets[f] .. offsets[f + 1]), in increasing view order.
struct Candidates {
  std::vector<uint32_t> offsets;
  std::vector<FaceCandidate> items;
  size_t face_count() const { return offsets.empty() ? 0 : offsets.size() - 1; }
};

struct CandidateOptions {
  double min_facing_cosine = 0.05;
  double occlusion_epsilon = 1e-3;
  double gradient_floor = 0.02;
  double partial_min_fraction = 0.5;
  double partial_weight = 0.1;
  bool show_progress = false;
};

// Reads each view's photo once. model: the mesh's geometry with its BVH. Throws Error naming a
// photo that cannot be read.
Candidates ComputeCandidates(const render::RenderModel& model, const scene::Scene& scene,
                             const std::vector<size_t>& views, const CandidateOptions& options);

// Photo-consistency check (the paper's outlier removal, simplified): for a face with at least
// three candidates, the mode of the candidates' mean colours is found by mean shift (Gaussian
// kernel of `bandwidth` in RGB, started at the per-channel median, 20 iterations); candidates
// farther than max(threshold_sigmas * s, min_threshold) from it are dropped, s = 1.4826 x the
// median distance of all candidates to the mode. A view that sees an occluder in front of the
// face (an object the mesh lacks) sees a different colour than the others and is dropped.
// Returns how many candidates were removed.
struct ConsistencyOptions {
  double bandwidth = 0.1;
  double threshold_sigmas = 3.0;
  double min_threshold = 0.1;
};
size_t RemoveInconsistentCandidates(Candidates* candidates, const ConsistencyOptions& options);

// The labelling problem: node = face, label = view position, cost = 1 - min(1, quality /
// q_max) with q_max the 99th percentile of all candidates' qualities (so the sharpest, closest
// views cost about 0 and the labelling is independent of the scene's scale); edges = faces
// sharing an edge; Potts weight `smoothness`.
PottsProblem MakeViewSelectionProblem(const Candidates& candidates,
                                      const std::vector<std::pair<uint32_t, uint32_t>>& face_pairs,
                                      float smoothness);

}  // namespace rephoto::texture
