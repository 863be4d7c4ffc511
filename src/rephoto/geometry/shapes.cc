#include "rephoto/geometry/shapes.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <unordered_map>

#include "rephoto/core/error.h"
#include "rephoto/geometry/surface_distance.h"

namespace rephoto::geometry {
namespace {

// Rings 0..last_ring of a latitude-longitude sphere (ring 0 = north pole, ring `rings` = south
// pole; ring k at polar angle pi k / rings). A last ring that is not a pole is an open rim.
mesh::Mesh UvBands(double radius, int rings, int segments, int last_ring,
                   const Eigen::Vector3d& center) {
  REPHOTO_CHECK(rings >= 2 && segments >= 3 && radius > 0, "bad sphere tessellation");
  mesh::Mesh mesh;
  auto vertex = [&](double theta, double phi) {
    const Eigen::Vector3d p(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                            std::cos(theta));
    mesh.positions.push_back((center + radius * p).cast<float>());
  };
  vertex(0, 0);  // north pole, index 0
  for (int k = 1; k <= std::min(last_ring, rings - 1); ++k) {
    // The equator ring is computed exactly at z = centre z.
    const double theta = 2 * k == rings ? std::numbers::pi / 2 : std::numbers::pi * k / rings;
    for (int s = 0; s < segments; ++s) vertex(theta, 2 * std::numbers::pi * s / segments);
  }
  auto ring_vertex = [&](int k, int s) {
    return static_cast<uint32_t>(1 + (k - 1) * segments + (s % segments));
  };
  for (int s = 0; s < segments; ++s) {
    mesh.faces.push_back({0, ring_vertex(1, s), ring_vertex(1, s + 1)});
  }
  for (int k = 1; k < std::min(last_ring, rings - 1); ++k) {
    for (int s = 0; s < segments; ++s) {
      const uint32_t a = ring_vertex(k, s), b = ring_vertex(k, s + 1);
      const uint32_t c = ring_vertex(k + 1, s), d = ring_vertex(k + 1, s + 1);
      mesh.faces.push_back({a, c, d});
      mesh.faces.push_back({a, d, b});
    }
  }
  if (last_ring == rings) {
    vertex(std::numbers::pi, 0);
    const auto south = static_cast<uint32_t>(mesh.positions.size() - 1);
    for (int s = 0; s < segments; ++s) {
      mesh.faces.push_back({ring_vertex(rings - 1, s), south, ring_vertex(rings - 1, s + 1)});
    }
  }
  return mesh;
}

}  // namespace

mesh::Mesh MakeIcosphere(double radius, int subdivisions, const Eigen::Vector3d& center) {
  REPHOTO_CHECK(subdivisions >= 0 && subdivisions <= 10 && radius > 0, "bad icosphere");
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> points = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                         {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                         {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (Eigen::Vector3d& p : points) p.normalize();
  std::vector<mesh::Triangle> faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < subdivisions; ++level) {
    std::unordered_map<uint64_t, uint32_t> midpoints;
    auto midpoint = [&](uint32_t a, uint32_t b) {
      const uint64_t key = (static_cast<uint64_t>(std::min(a, b)) << 32) | std::max(a, b);
      const auto [it, inserted] = midpoints.try_emplace(key, 0);
      if (inserted) {
        points.push_back((points[a] + points[b]).normalized());
        it->second = static_cast<uint32_t>(points.size() - 1);
      }
      return it->second;
    };
    std::vector<mesh::Triangle> next;
    next.reserve(4 * faces.size());
    for (const mesh::Triangle& f : faces) {
      const uint32_t ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]),
                     ca = midpoint(f[2], f[0]);
      next.push_back({f[0], ab, ca});
      next.push_back({f[1], bc, ab});
      next.push_back({f[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    faces = std::move(next);
  }
  mesh::Mesh mesh;
  mesh.positions.reserve(points.size());
  for (const Eigen::Vector3d& p : points)
    mesh.positions.push_back((center + radius * p).cast<float>());
  mesh.faces = std::move(faces);
  return mesh;
}

mesh::Mesh MakeUvSphere(double radius, int rings, int segments, const Eigen::Vector3d& center) {
  return UvBands(radius, rings, segments, rings, center);
}

mesh::Mesh MakeUvHemisphere(double radius, int rings, int segments, const Eigen::Vector3d& center) {
  return UvBands(radius, 2 * rings, segments, rings, center);
}

mesh::Mesh MakeRectangle(double x0, double y0, double x1, double y1, double z) {
  mesh::Mesh mesh;
  mesh.positions = {
      Eigen::Vector3d(x0, y0, z).cast<float>(), Eigen::Vector3d(x1, y0, z).cast<float>(),
      Eigen::Vector3d(x1, y1, z).cast<float>(), Eigen::Vector3d(x0, y1, z).cast<float>()};
  mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  return mesh;
}

double TessellationError(const mesh::Mesh& sphere, double radius, const Eigen::Vector3d& center) {
  double error = 0;
  for (const mesh::Triangle& f : sphere.faces) {
    const double d2 = PointTriangleDistanceSquared(center, sphere.positions[f[0]].cast<double>(),
                                                   sphere.positions[f[1]].cast<double>(),
                                                   sphere.positions[f[2]].cast<double>());
    error = std::max(error, radius - std::sqrt(d2));
  }
  return error;
}

}  // namespace rephoto::geometry
