#include "rephoto/render/nearest_hit.h"

#include <gmock/gmock.h>

#include <cstdint>

#include "rephoto/core/error.h"

namespace rephoto::render {
namespace {

// An n x n grid of quads in the plane z = 0, two triangles each: the interior edges have two
// faces, the 4n outer edges one.
mesh::Mesh Grid(int n) {
  mesh::Mesh m;
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) m.positions.emplace_back(x, y, 0);
  }
  auto v = [&](int x, int y) { return static_cast<uint32_t>(y * (n + 1) + x); };
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      m.faces.push_back({v(x, y), v(x + 1, y), v(x + 1, y + 1)});
      m.faces.push_back({v(x, y), v(x + 1, y + 1), v(x, y + 1)});
    }
  }
  return m;
}

TEST(BorderSkirtsTest, GridHasItsOuterEdgesAsBordersAndLinksEveryInteriorEdge) {
  const int n = 7;
  const mesh::Mesh m = Grid(n);
  const BorderSkirts s = MakeBorderSkirts(m);
  int borders = 0;
  for (uint8_t b : s.face_borders) borders += __builtin_popcount(b);
  EXPECT_EQ(borders, 4 * n);
  EXPECT_EQ(s.triangles.size(), 2u * 4 * n);
  EXPECT_EQ(s.positions.size(), 4u * 4 * n);
  EXPECT_EQ(s.owner.size(), 4u * n);
  // Interior edges: 3n^2 edges in all (n(n+1) horizontal, as many vertical, n^2 diagonals),
  // minus the 4n outer ones; each links two half-edges, which point at each other and join
  // the same two vertices.
  size_t linked = 0;
  for (size_t he = 0; he < s.neighbors.size(); ++he) {
    const uint32_t other = s.neighbors[he];
    if (other == BorderSkirts::kNoNeighbor) continue;
    ++linked;
    EXPECT_EQ(s.neighbors[other], he);
    EXPECT_NE(other / 3, he / 3);
    const auto& f = m.faces[he / 3];
    const auto& g = m.faces[other / 3];
    const int k = static_cast<int>(he % 3), j = static_cast<int>(other % 3);
    EXPECT_EQ(std::minmax(f[k], f[(k + 1) % 3]), std::minmax(g[j], g[(j + 1) % 3]));
  }
  EXPECT_EQ(linked, 2u * (3 * n * n + 2 * n - 4 * n));
}

TEST(BorderSkirtsTest, AnEdgeOfThreeFacesLinksNoneAndIsNoBorder) {
  // Three triangles sharing the edge (0, 1), fanned around it.
  mesh::Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0.5, 1, 0}, {0.5, -1, 0}, {0.5, 0, 1}};
  m.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const BorderSkirts s = MakeBorderSkirts(m);
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(s.neighbors[3 * f + 0], BorderSkirts::kNoNeighbor) << f;
    EXPECT_EQ(s.face_borders[f] & 1, 0) << f;  // edge 0 of every face is (0, 1)
    EXPECT_EQ(s.face_borders[f] & 6, 6) << f;  // the other two edges are borders
  }
  EXPECT_EQ(s.owner.size(), 6u);
}

TEST(BorderSkirtsTest, AFaceReferringToAMissingVertexIsAnError) {
  mesh::Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 5}};
  EXPECT_THROW(MakeBorderSkirts(m), Error);
}

}  // namespace
}  // namespace rephoto::render
