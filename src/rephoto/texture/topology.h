// Mesh connectivity used by texturing (internal to texture/).
//
// Thread safety: pure functions of the mesh; the result is a value.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "rephoto/mesh/mesh.h"

namespace rephoto::texture {

// Pairs of faces (f < g) that share an edge (the same two vertex indices, either direction).
// An edge with more than two faces (non-manifold) links each face to the next one in face
// order. Sorted by (f, g), no duplicates.
std::vector<std::pair<uint32_t, uint32_t>> FacePairs(const mesh::Mesh& mesh);

// The faces around each vertex: faces[offsets[v] .. offsets[v + 1]), increasing.
struct VertexFaces {
  std::vector<uint32_t> offsets;
  std::vector<uint32_t> faces;
};
VertexFaces MakeVertexFaces(const mesh::Mesh& mesh);

}  // namespace rephoto::texture
