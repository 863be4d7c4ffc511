// Colouring a mesh's vertices from calibrated photos: turns an uncoloured reconstruction into
// the "mesh with vertex colours" representation.
//
// For every vertex V and every selected view (camera centre C, intrinsics, photo):
//   visible  <=> the view sees V by render/visibility.h's rule (in the usable field, projected
//                at least half a pixel inside the photo so that bilinear sampling stays inside,
//                facing: n . (C - V) / |C - V| > min_facing_cosine with n = the mesh's vertex
//                normal, or the area-weighted face normal average when the mesh has none, and
//                no surface before (1 - occlusion_epsilon) * |V - C|);
//   sample   =  the photo bilinearly interpolated at the projection (pixel-corner convention),
//               RGB as stored in the file, in [0,1];
//   weight   =  cos * (f / |V - C|)^2 with cos the facing cosine above and f the camera's mean
//               focal length in pixels: the photo's pixel density on the surface, favouring
//               frontal and close views.
// The colour is a robust weighted mean of the samples: start at the per-channel weighted
// median, then `irls_iterations` steps of iteratively reweighted least squares with Cauchy
// weights w_i / (1 + (r_i / (2.385 s))^2), r_i = |sample_i - estimate| (RGB Euclidean),
// s = max(1.4826 * weighted median of r, 1/255). Vertices seen by no view get colour 0.
// Deterministic: independent of the thread count.
#pragma once

#include <cstddef>
#include <vector>

#include "rephoto/mesh/mesh.h"
#include "rephoto/render/render_model.h"
#include "rephoto/render/visibility.h"
#include "rephoto/scene/scene.h"

namespace rephoto::render {

struct ColorizeOptions {
  double min_facing_cosine = VisibilityRule{}.min_facing_cosine;
  double occlusion_epsilon = VisibilityRule{}.occlusion_epsilon;
  int irls_iterations = 5;
  bool show_progress = false;  // a Progress line per photo
};

struct ColorizeReport {
  size_t vertices = 0;
  size_t colored_vertices = 0;  // seen by at least one view
  size_t observations = 0;      // visible (vertex, view) pairs
};

// Returns a copy of `mesh` with `colors` set and a per-vertex scalar "view_count" (how many
// views saw the vertex). `views` are indices into scene.views. Photos are read with
// io::ReadImage (1, 3 or 4 channels; grey is replicated, alpha ignored); a photo whose size
// differs from its camera's is used with the camera scaled to it (Camera::Scaled). Throws Error
// naming the file for an unreadable photo, an invalid mesh (Mesh::Validate, context "mesh") or
// a view index out of range.
mesh::Mesh ColorizeMesh(const mesh::Mesh& mesh, const scene::Scene& scene,
                        const std::vector<size_t>& views, const ColorizeOptions& options = {},
                        ColorizeReport* report = nullptr);

// The same colours for the mesh of a model whose BVH is already built (the occlusion tests use
// it), so that one BVH serves colouring, rendering (RenderModel::SetVertexColors) and error
// projection. The model's existing colours are ignored.
struct VertexColors {
  std::vector<Eigen::Vector3f> colors;  // one per vertex, 0 where no view sees it
  mesh::VertexScalar view_count;        // "view_count": how many views saw each vertex
};
VertexColors ColorizeVertices(const RenderModel& model, const scene::Scene& scene,
                              const std::vector<size_t>& views, const ColorizeOptions& options = {},
                              ColorizeReport* report = nullptr);

}  // namespace rephoto::render
