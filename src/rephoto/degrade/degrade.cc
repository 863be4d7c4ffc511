#include "rephoto/degrade/degrade.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/degrade/simplex_noise.h"

namespace rephoto::degrade {
namespace {

// Keeps only the vertices `faces` reference, in their original order, remapping faces and
// per-vertex attributes.
void CompactVertices(mesh::Mesh& m) {
  constexpr uint32_t kUnused = std::numeric_limits<uint32_t>::max();
  std::vector<uint32_t> remap(m.positions.size(), kUnused);
  for (const auto& f : m.faces) {
    for (uint32_t v : f) remap[v] = 0;
  }
  uint32_t next = 0;
  for (auto& r : remap) {
    if (r != kUnused) r = next++;
  }
  auto compact = [&](auto& values) {
    if (values.empty()) return;
    size_t out = 0;
    for (size_t v = 0; v < remap.size(); ++v) {
      if (remap[v] != kUnused) values[out++] = values[v];
    }
    values.resize(out);
  };
  compact(m.positions);
  compact(m.normals);
  compact(m.colors);
  compact(m.radii);
  compact(m.vertex_texcoords);
  for (auto& s : m.scalars) compact(s.values);
  for (auto& f : m.faces) {
    for (auto& v : f) v = remap[v];
  }
}

void Simplify(mesh::Mesh& m, float fraction) {
  REPHOTO_CHECK(!m.is_point_cloud(), "simplification needs a mesh with faces, not a point cloud");
  REPHOTO_CHECK(m.wedge_texcoords.empty(),
                "simplification of meshes with per-face texture coordinates is not supported");
  const size_t index_count = m.faces.size() * 3;
  const size_t target =
      static_cast<size_t>(std::llround(static_cast<double>(m.faces.size()) * (1.0 - fraction))) * 3;
  std::vector<unsigned int> simplified(index_count);
  const auto* indices = reinterpret_cast<const unsigned int*>(m.faces.data());
  const auto* positions = reinterpret_cast<const float*>(m.positions.data());
  // target_error 1 (relative to the mesh extent) lets the face budget decide, as the paper's
  // n_simp fixes the amount of removed geometry rather than an error bound.
  size_t count = meshopt_simplify(simplified.data(), indices, index_count, positions,
                                  m.positions.size(), sizeof(Eigen::Vector3f), target, 1.f, 0,
                                  nullptr);
  if (count > target + target / 20 + 3) {
    // Topology-preserving collapse got stuck (e.g. many borders): fall back to clustering.
    count = meshopt_simplifySloppy(simplified.data(), indices, index_count, positions,
                                   m.positions.size(), sizeof(Eigen::Vector3f), target, 1.f,
                                   nullptr);
  }
  m.faces.resize(count / 3);
  std::copy(simplified.begin(), simplified.begin() + static_cast<std::ptrdiff_t>(count),
            reinterpret_cast<unsigned int*>(m.faces.data()));
  m.face_materials.clear();  // face order changed; per-face materials no longer apply
  CompactVertices(m);
}

}  // namespace

mesh::Mesh Degrade(const mesh::Mesh& model, const DegradeOptions& options,
                   DegradeReport* report) {
  REPHOTO_CHECK(options.texture_noise >= 0 && std::isfinite(options.texture_noise),
                "texture noise must be >= 0 (got {})", options.texture_noise);
  REPHOTO_CHECK(options.geometry_noise >= 0 && std::isfinite(options.geometry_noise),
                "geometry noise must be >= 0 (got {})", options.geometry_noise);
  REPHOTO_CHECK(options.simplify >= 0 && options.simplify < 1,
                "simplification fraction must be in [0, 1) (got {})", options.simplify);
  REPHOTO_CHECK(!model.positions.empty(), "cannot degrade an empty model");

  mesh::Mesh m = model;
  const auto box = mesh::BoundingBox(m);
  const double extent = (box[1] - box[0]).norm();
  DegradeReport local;
  local.vertices_before = m.positions.size();
  local.extent = extent;

  if (options.simplify > 0) Simplify(m, options.simplify);
  local.vertices_after = m.positions.size();
  local.removed_fraction =
      1.0 - static_cast<double>(local.vertices_after) / static_cast<double>(local.vertices_before);

  const float to_noise = extent > 0 ? options.noise_frequency / static_cast<float>(extent) : 1.f;
  const int64_t n = static_cast<int64_t>(m.positions.size());

  if (options.geometry_noise > 0) {
    if (m.normals.empty()) {
      REPHOTO_CHECK(!m.is_point_cloud(), "geometry noise on a point cloud needs vertex normals");
      m.normals = mesh::ComputeVertexNormals(m);
    }
    const SimplexNoise noise(options.seed * 4 + 0);
    const float amplitude = options.geometry_noise * static_cast<float>(extent);
    ParallelFor(0, n, 4096, [&](int64_t b, int64_t e) {
      for (int64_t v = b; v < e; ++v) {
        Eigen::Vector3f normal = m.normals[v];
        const float length = normal.norm();
        if (!(length > 0)) continue;
        m.positions[v] += (amplitude * noise.Noise(m.positions[v] * to_noise) / length) * normal;
      }
    });
    // The surface moved: normals from faces are recomputed, file normals are kept as they were
    // given only for point clouds.
    if (!m.is_point_cloud()) m.normals = mesh::ComputeVertexNormals(m);
  }

  if (options.texture_noise > 0) {
    REPHOTO_CHECK(!m.colors.empty(), "texture noise needs vertex colours (the model has none)");
    const SimplexNoise noise_r(options.seed * 4 + 1), noise_g(options.seed * 4 + 2),
        noise_b(options.seed * 4 + 3);
    ParallelFor(0, n, 4096, [&](int64_t b, int64_t e) {
      for (int64_t v = b; v < e; ++v) {
        // Sample the noise at the undisplaced position so texture and geometry noise are
        // independent of each other.
        const Eigen::Vector3f p = model.positions.size() == m.positions.size() &&
                                          options.simplify == 0
                                      ? model.positions[v] * to_noise
                                      : m.positions[v] * to_noise;
        Eigen::Vector3f& c = m.colors[v];
        c.x() = std::clamp(c.x() + options.texture_noise * noise_r.Noise(p), 0.f, 1.f);
        c.y() = std::clamp(c.y() + options.texture_noise * noise_g.Noise(p), 0.f, 1.f);
        c.z() = std::clamp(c.z() + options.texture_noise * noise_b.Noise(p), 0.f, 1.f);
      }
    });
  }
  if (report) *report = local;
  return m;
}

}  // namespace rephoto::degrade
