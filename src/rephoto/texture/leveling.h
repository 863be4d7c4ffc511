// Global colour adjustment across seams (Waechter, Moehrle and Goesele 2014, Sec. 5.1, after
// Lempitsky and Ivanov 2007), internal to texture/.
//
// Every vertex v gets one additive RGB offset g(v, l) per label l (view) of the faces around
// it; a texel of a face labelled l is its photo colour plus the barycentric interpolation of
// g(., l) at the face's corners. The offsets minimize
//   sum over seam vertices v, label pairs l < m at v:  (f(v, l) + g(v, l) - f(v, m) - g(v, m))^2
//   + smoothness * sum over faces labelled l, edges (a, b) of the face: (g(a, l) - g(b, l))^2
//   + regularization * sum g^2
// so that both sides of a seam meet in colour while each patch's offsets vary smoothly (a
// patch-wide exposure difference becomes a constant offset at no smoothness cost).
// f(v, l): the mean colour in photo l of the points v and v + 0.25 (w - v) for every
// neighbour w of v (the same 3D points in every photo, so f(v, l) - f(v, m) measures the
// photos' colour difference there, not texture detail; simplification of the paper's samples
// along the seam edges). Points that do not project inside photo l are left out.
// Solved per channel by conjugate gradients (Eigen, diagonal preconditioner) on the normal
// equations. Deterministic.
//
// Thread safety: a function of its arguments; parallel inside, deterministic.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "rephoto/mesh/mesh.h"
#include "rephoto/scene/scene.h"
#include "rephoto/texture/topology.h"

namespace rephoto::texture {

// g(v, l) for the labels around each vertex: entries [offsets[v], offsets[v + 1]).
struct ColorAdjustment {
  std::vector<uint32_t> offsets;
  std::vector<int> labels;
  std::vector<Eigen::Vector3f> values;
  // g(vertex, label); zero when absent (or no adjustment was computed).
  Eigen::Vector3f At(uint32_t vertex, int label) const {
    if (offsets.empty()) return Eigen::Vector3f::Zero();
    for (uint32_t i = offsets[vertex]; i < offsets[vertex + 1]; ++i) {
      if (labels[i] == label) return values[i];
    }
    return Eigen::Vector3f::Zero();
  }
};

struct LevelingOptions {
  double smoothness = 1.0;
  double regularization = 1e-3;
  int max_iterations = 1000;
  // Relative residual of the conjugate gradients: 1e-4 of the seam differences is far below
  // an 8-bit step.
  double tolerance = 1e-4;
};

struct LevelingReport {
  size_t variables = 0;
  size_t seam_vertices = 0;
  size_t seam_terms = 0;
  int iterations = 0;  // most conjugate-gradient iterations of the three channels
};

// face_labels: position in `views` per face, -1 = none. Reads the photos of the labels that
// meet at seams (once each). Throws Error naming a photo that cannot be read.
ColorAdjustment LevelSeams(const mesh::Mesh& mesh, const VertexFaces& vertex_faces,
                           const std::vector<int>& face_labels, const scene::Scene& scene,
                           const std::vector<size_t>& views, const LevelingOptions& options,
                           LevelingReport* report);

}  // namespace rephoto::texture
