#include "rephoto/mesh/mesh.h"

#include <cmath>

#include "rephoto/core/error.h"

namespace rephoto::mesh {

void Mesh::SetScalar(VertexScalar scalar) {
  std::erase_if(scalars, [&](const VertexScalar& s) { return s.name == scalar.name; });
  scalars.push_back(std::move(scalar));
}

bool Mesh::is_textured() const {
  if (!has_texcoords() || faces.empty()) return false;
  for (const Material& material : materials) {
    if (!material.diffuse_texture.empty()) return true;
  }
  return false;
}

void Mesh::Validate(std::string_view context) const {
  const size_t v = positions.size();
  REPHOTO_CHECK(v > 0, "{}: empty mesh (no vertices)", context);
  auto check_size = [&](size_t size, size_t expected, const char* what) {
    REPHOTO_CHECK(size == 0 || size == expected, "{}: {} has {} entries, expected {}", context,
                  what, size, expected);
  };
  check_size(normals.size(), v, "normals");
  check_size(colors.size(), v, "colours");
  check_size(radii.size(), v, "radii");
  check_size(vertex_texcoords.size(), v, "vertex texture coordinates");
  check_size(wedge_texcoords.size(), 3 * faces.size(), "wedge texture coordinates");
  check_size(face_materials.size(), faces.size(), "face materials");
  for (const VertexScalar& scalar : scalars) check_size(scalar.values.size(), v, "scalar");
  for (size_t i = 0; i < v; ++i) {
    REPHOTO_CHECK(positions[i].allFinite(), "{}: vertex {}: position is NaN or infinite", context,
                  i);
  }
  for (size_t i = 0; i < radii.size(); ++i) {
    REPHOTO_CHECK(std::isfinite(radii[i]) && radii[i] > 0,
                  "{}: vertex {}: radius {} is not positive", context, i, radii[i]);
  }
  for (size_t f = 0; f < faces.size(); ++f) {
    for (uint32_t index : faces[f]) {
      REPHOTO_CHECK(index < v, "{}: face {}: vertex index {} out of range ({} vertices)", context,
                    f, index, v);
    }
  }
  for (size_t f = 0; f < face_materials.size(); ++f) {
    const int m = face_materials[f];
    REPHOTO_CHECK(m >= -1 && m < static_cast<int>(materials.size()),
                  "{}: face {}: material {} out of range ({} materials)", context, f, m,
                  materials.size());
  }
}

std::vector<Eigen::Vector3f> ComputeVertexNormals(const Mesh& mesh) {
  std::vector<Eigen::Vector3f> normals(mesh.positions.size(), Eigen::Vector3f::Zero());
  for (const Triangle& t : mesh.faces) {
    const Eigen::Vector3f& p0 = mesh.positions[t[0]];
    // Cross product length = 2 * area: area weighting comes for free.
    const Eigen::Vector3f n = (mesh.positions[t[1]] - p0).cross(mesh.positions[t[2]] - p0);
    for (uint32_t index : t) normals[index] += n;
  }
  for (Eigen::Vector3f& n : normals) {
    const float length = n.norm();
    if (length > 0 && std::isfinite(length)) {
      n /= length;
    } else {
      n.setZero();
    }
  }
  return normals;
}

std::array<Eigen::Vector3f, 2> BoundingBox(const Mesh& mesh) {
  Eigen::Vector3f lo = mesh.positions.front(), hi = lo;
  for (const Eigen::Vector3f& p : mesh.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {lo, hi};
}

}  // namespace rephoto::mesh
