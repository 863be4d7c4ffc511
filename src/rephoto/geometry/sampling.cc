#include "rephoto/geometry/sampling.h"

#include <algorithm>
#include <cmath>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/degrade/simplex_noise.h"

namespace rephoto::geometry {
namespace {

double FaceArea(const mesh::Mesh& mesh, const mesh::Triangle& face) {
  const Eigen::Vector3d p0 = mesh.positions[face[0]].cast<double>();
  const Eigen::Vector3d p1 = mesh.positions[face[1]].cast<double>();
  const Eigen::Vector3d p2 = mesh.positions[face[2]].cast<double>();
  return 0.5 * (p1 - p0).cross(p2 - p0).norm();
}

// The per-sample generator: independent of chunking and thread count.
uint64_t SampleState(uint64_t seed, size_t i) {
  uint64_t state = seed + 0x632BE59BD9B4E019ULL * (static_cast<uint64_t>(i) + 1);
  degrade::SplitMix64(state);
  return state;
}

}  // namespace

double SurfaceArea(const mesh::Mesh& mesh) {
  double area = 0;
  for (const mesh::Triangle& face : mesh.faces) area += FaceArea(mesh, face);
  return area;
}

SurfaceSamples SampleSurface(const mesh::Mesh& mesh, size_t count, uint64_t seed,
                             std::string_view name) {
  REPHOTO_CHECK(count > 0, "{}: the number of samples must be positive", name);
  REPHOTO_CHECK(mesh.vertex_count() > 0, "{}: the model has no vertices", name);
  SurfaceSamples samples;
  if (mesh.is_point_cloud()) {
    const size_t n = mesh.vertex_count();
    if (count >= n) {
      samples.positions = mesh.positions;
      samples.sources.resize(n);
      for (size_t i = 0; i < n; ++i) samples.sources[i] = static_cast<uint32_t>(i);
      return samples;
    }
    samples.positions.resize(count);
    samples.sources.resize(count);
    for (size_t i = 0; i < count; ++i) {
      uint64_t state = SampleState(seed, i);
      const double u =
          (static_cast<double>(i) + degrade::UniformDouble(state)) / static_cast<double>(count);
      const size_t index = std::min(n - 1, static_cast<size_t>(u * static_cast<double>(n)));
      samples.positions[i] = mesh.positions[index];
      samples.sources[i] = static_cast<uint32_t>(index);
    }
    return samples;
  }

  // Cumulative area, normalized to [0, 1].
  std::vector<double> cumulative(mesh.face_count());
  double total = 0;
  for (size_t f = 0; f < mesh.face_count(); ++f) {
    total += FaceArea(mesh, mesh.faces[f]);
    cumulative[f] = total;
  }
  REPHOTO_CHECK(total > 0 && std::isfinite(total), "{}: the surface has no area ({} faces)", name,
                mesh.face_count());
  for (double& c : cumulative) c /= total;
  cumulative.back() = 1.0;

  samples.positions.resize(count);
  samples.sources.resize(count);
  ParallelFor(0, static_cast<int64_t>(count), 1 << 14, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      uint64_t state = SampleState(seed, static_cast<size_t>(i));
      const double u =
          (static_cast<double>(i) + degrade::UniformDouble(state)) / static_cast<double>(count);
      // First face whose cumulative area exceeds u (zero-area faces are never chosen: their
      // interval is empty).
      size_t f = static_cast<size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), u) -
                                     cumulative.begin());
      f = std::min(f, cumulative.size() - 1);
      const double a = std::sqrt(degrade::UniformDouble(state));
      const double b = degrade::UniformDouble(state);
      const mesh::Triangle& face = mesh.faces[f];
      const Eigen::Vector3d p = (1 - a) * mesh.positions[face[0]].cast<double>() +
                                a * (1 - b) * mesh.positions[face[1]].cast<double>() +
                                a * b * mesh.positions[face[2]].cast<double>();
      samples.positions[static_cast<size_t>(i)] = p.cast<float>();
      samples.sources[static_cast<size_t>(i)] = static_cast<uint32_t>(f);
    }
  });
  return samples;
}

}  // namespace rephoto::geometry
