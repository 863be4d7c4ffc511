// Synthetic defects on a model (paper Section 4.1, Fig. 5/6): texture noise, geometry noise and
// mesh simplification, deterministic for a seed and composable in one call (applied in the order
// simplification, geometry noise, texture noise).
//
// Thread safety: reentrant (no shared state); Degrade reads its input mesh and parallelizes inside
// (core/parallel.h), so concurrent calls may share one const input.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "rephoto/mesh/mesh.h"

namespace rephoto::degrade {

struct DegradeOptions {
  // Maximum offset per RGB channel, in colour units ([0,1] = full range): each channel is
  // offset by texture_noise * SimplexNoise(p), independently per channel, then clamped to
  // [0,1], where p is the surface point (before geometry noise) the colour belongs to.
  // The noise goes where the renderer takes colours from (render/render_model.h): the texels
  // of a textured mesh (every texel a face covers, p from the face's barycentric coordinates;
  // texels within one texel of a face too, so bilinear filtering at chart borders sees noisy
  // values; other texels are unchanged), else the vertex colours.
  float texture_noise = 0;
  // Texel noise writes each modified texture as 8-bit PNG "<texture_prefix>_<material>.png"
  // into this folder (created if needed) and points the material at it (absolute path).
  // Required when texel noise is applied.
  std::filesystem::path texture_dir;
  std::string texture_prefix = "degraded";
  // Maximum displacement along the vertex normal, as a fraction of the scene extent (the
  // diagonal of the model's bounding box). Normals come from the file, else from the faces.
  float geometry_noise = 0;
  // Fraction of faces to remove by edge collapse (meshoptimizer's meshopt_simplify), in [0,1);
  // the vertex count falls by about the same fraction. Colours, normals, radii, scalars and
  // texture coordinates carry over: per-face (wedge) texture coordinates are first turned into
  // per-vertex ones by splitting vertices along texture seams (meshoptimizer keeps such seams
  // consistent), and each material's faces are simplified separately so faces keep their
  // material.
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
// noise on a model with neither a texture nor vertex colours, texel noise without texture_dir,
// geometry noise on a point cloud without normals, simplification of a point cloud, parameters out
// of range).
mesh::Mesh Degrade(const mesh::Mesh& model, const DegradeOptions& options,
                   DegradeReport* report = nullptr);

}  // namespace rephoto::degrade
