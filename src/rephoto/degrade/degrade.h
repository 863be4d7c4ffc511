// Synthetic defects on a model (paper Section 4.1, Fig. 5/6): texture noise, geometry noise and
// mesh simplification, deterministic for a seed and composable in one call (applied in the order
// simplification, geometry noise, texture noise).
#pragma once

#include <cstdint>

#include "rephoto/mesh/mesh.h"

namespace rephoto::degrade {

struct DegradeOptions {
  // Maximum offset per RGB channel, in colour units ([0,1] = full range): each channel is
  // offset by texture_noise * SimplexNoise(p), independently per channel, then clamped to
  // [0,1]. Needs vertex colours (texel noise on textured meshes is not implemented).
  float texture_noise = 0;
  // Maximum displacement along the vertex normal, as a fraction of the scene extent (the
  // diagonal of the model's bounding box). Normals come from the file, else from the faces.
  float geometry_noise = 0;
  // Fraction of vertices to remove by edge collapse (meshoptimizer's meshopt_simplify), in
  // [0,1). Colours, normals, radii and per-vertex texture coordinates carry over.
  float simplify = 0;
  // Noise features per scene extent (the noise is evaluated at p * frequency / extent).
  float noise_frequency = 40;
  uint64_t seed = 0;
};

struct DegradeReport {
  size_t vertices_before = 0;
  size_t vertices_after = 0;
  double removed_fraction = 0;  // achieved by simplification
  double extent = 0;            // bounding-box diagonal used for geometry noise
};

// Returns the degraded copy. Throws Error when a requested defect cannot be applied (texture
// noise without vertex colours, geometry noise on a point cloud without normals, simplification
// of a point cloud, parameters out of range).
mesh::Mesh Degrade(const mesh::Mesh& model, const DegradeOptions& options,
                   DegradeReport* report = nullptr);

}  // namespace rephoto::degrade
