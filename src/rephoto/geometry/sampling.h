// Uniform, area-weighted, seeded samples on a mesh's surface (or a point cloud's points).
//
// Mesh (faces present): sample i (0 <= i < count) takes u_i = (i + r_i) / count with r_i uniform
// in [0,1) and picks the face whose interval of the cumulative area (in face order) contains
// u_i, so the samples are stratified over the area: every face of area A receives A / total *
// count samples up to +-1, and samples come out in face order (spatially coherent for meshes
// whose neighbouring faces are stored together, which speeds up distance queries). Inside the
// face the point is uniform: p = (1 - sqrt(a)) p0 + sqrt(a) (1 - b) p1 + sqrt(a) b p2 with a, b
// uniform in [0,1). Degenerate faces (zero area) receive no samples.
// Point cloud (no faces): the points themselves (all of them when count >= the point count, in
// order; else the points floor((i + r_i) * V / count), a stratified subset in order).
// Randomness: splitmix64 seeded with seed + i per sample, so the samples are bit-for-bit the same
// on any machine and thread count. Positions are in the mesh's frame and units.
// Thread safety: pure function (runs in parallel through core/parallel.h).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string_view>
#include <vector>

#include "rephoto/mesh/mesh.h"

namespace rephoto::geometry {

struct SurfaceSamples {
  std::vector<Eigen::Vector3f> positions;
  // Index of the face each sample lies on (meshes), or of the point (point clouds).
  std::vector<uint32_t> sources;
};

// Total area of the faces (0 for a point cloud), in squared model units, summed in double.
double SurfaceArea(const mesh::Mesh& mesh);

// See the file comment. Throws Error "<name>: ..." when count is 0, the mesh has no vertices, or
// it has faces whose total area is 0.
SurfaceSamples SampleSurface(const mesh::Mesh& mesh, size_t count, uint64_t seed,
                             std::string_view name = "mesh");

}  // namespace rephoto::geometry
