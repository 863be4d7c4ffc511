#include "rephoto/texture/topology.h"

#include <algorithm>
#include <array>

namespace rephoto::texture {

std::vector<std::pair<uint32_t, uint32_t>> FacePairs(const mesh::Mesh& mesh) {
  // (min vertex, max vertex, face) per face edge, sorted: faces of one edge are adjacent.
  std::vector<std::array<uint32_t, 3>> edges;
  edges.reserve(3 * mesh.faces.size());
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const mesh::Triangle& t = mesh.faces[f];
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = t[k], b = t[(k + 1) % 3];
      if (a == b) continue;
      edges.push_back({std::min(a, b), std::max(a, b), static_cast<uint32_t>(f)});
    }
  }
  std::sort(edges.begin(), edges.end());
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  for (size_t i = 1; i < edges.size(); ++i) {
    if (edges[i][0] == edges[i - 1][0] && edges[i][1] == edges[i - 1][1] &&
        edges[i][2] != edges[i - 1][2]) {
      pairs.emplace_back(edges[i - 1][2], edges[i][2]);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

VertexFaces MakeVertexFaces(const mesh::Mesh& mesh) {
  VertexFaces out;
  out.offsets.assign(mesh.positions.size() + 1, 0);
  for (const mesh::Triangle& t : mesh.faces) {
    for (int k = 0; k < 3; ++k) ++out.offsets[t[k] + 1];
  }
  for (size_t v = 0; v < mesh.positions.size(); ++v) out.offsets[v + 1] += out.offsets[v];
  out.faces.resize(out.offsets.back());
  std::vector<uint32_t> fill(out.offsets.begin(), out.offsets.end() - 1);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh.faces[f][k];
      // A degenerate face listing a vertex twice is listed once.
      if (fill[v] > out.offsets[v] && out.faces[fill[v] - 1] == f) continue;
      out.faces[fill[v]++] = static_cast<uint32_t>(f);
    }
  }
  // Compact the slots left by degenerate faces.
  std::vector<uint32_t> offsets(out.offsets.size(), 0);
  size_t write = 0;
  for (size_t v = 0; v + 1 < out.offsets.size(); ++v) {
    offsets[v] = static_cast<uint32_t>(write);
    for (uint32_t i = out.offsets[v]; i < fill[v]; ++i) out.faces[write++] = out.faces[i];
  }
  offsets.back() = static_cast<uint32_t>(write);
  out.faces.resize(write);
  out.offsets = std::move(offsets);
  return out;
}

}  // namespace rephoto::texture
