#include "rephoto/degrade/degrade.h"

#include <fmt/format.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_map>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/degrade/simplex_noise.h"
#include "rephoto/io/image_io.h"

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

// Turns per-face (wedge) texture coordinates into per-vertex ones: a vertex used with several
// texture coordinates (a texture seam) is split into one vertex per coordinate.
void WedgesToVertexTexcoords(mesh::Mesh& m) {
  if (m.wedge_texcoords.empty()) return;
  struct Key {
    uint32_t vertex;
    float u, v;
    bool operator==(const Key& o) const { return vertex == o.vertex && u == o.u && v == o.v; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      uint32_t u, v;
      std::memcpy(&u, &k.u, 4);
      std::memcpy(&v, &k.v, 4);
      return (size_t{k.vertex} * 0x9E3779B97F4A7C15ULL) ^ (size_t{u} * 0xBF58476D1CE4E5B9ULL) ^
             (size_t{v} * 0x94D049BB133111EBULL);
    }
  };
  std::unordered_map<Key, uint32_t, KeyHash> index;
  index.reserve(m.faces.size() * 2);
  std::vector<uint32_t> source;  // new vertex -> old vertex
  std::vector<Eigen::Vector2f> texcoords;
  for (size_t f = 0; f < m.faces.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector2f uv = m.wedge_texcoords[3 * f + c];
      const Key key{m.faces[f][c], uv.x(), uv.y()};
      auto [it, inserted] = index.try_emplace(key, static_cast<uint32_t>(source.size()));
      if (inserted) {
        source.push_back(key.vertex);
        texcoords.push_back(uv);
      }
      m.faces[f][c] = it->second;
    }
  }
  auto gather = [&](auto& values) {
    if (values.empty()) return;
    std::remove_reference_t<decltype(values)> out;
    out.reserve(source.size());
    for (uint32_t s : source) out.push_back(values[s]);
    values = std::move(out);
  };
  gather(m.positions);
  gather(m.normals);
  gather(m.colors);
  gather(m.radii);
  for (auto& scalar : m.scalars) gather(scalar.values);
  m.vertex_texcoords = std::move(texcoords);
  m.wedge_texcoords.clear();
}

// Simplifies one group of faces (indices into the shared vertex arrays) to about
// (1 - fraction) of its faces.
std::vector<mesh::Triangle> SimplifyFaces(const std::vector<mesh::Triangle>& faces,
                                          const std::vector<Eigen::Vector3f>& positions,
                                          float fraction) {
  const size_t index_count = faces.size() * 3;
  const size_t target =
      static_cast<size_t>(std::llround(static_cast<double>(faces.size()) * (1.0 - fraction))) * 3;
  std::vector<unsigned int> simplified(index_count);
  const auto* indices = reinterpret_cast<const unsigned int*>(faces.data());
  const auto* vertex_data = reinterpret_cast<const float*>(positions.data());
  // target_error 1 (relative to the mesh extent) lets the face budget decide, as the paper's
  // n_simp fixes the amount of removed geometry rather than an error bound.
  size_t count =
      meshopt_simplify(simplified.data(), indices, index_count, vertex_data, positions.size(),
                       sizeof(Eigen::Vector3f), target, 1.f, 0, nullptr);
  if (count > target + target / 20 + 3) {
    // Topology-preserving collapse got stuck (e.g. many borders): fall back to clustering.
    count = meshopt_simplifySloppy(simplified.data(), indices, index_count, vertex_data,
                                   positions.size(), sizeof(Eigen::Vector3f), target, 1.f, nullptr);
  }
  std::vector<mesh::Triangle> out(count / 3);
  std::copy(simplified.begin(), simplified.begin() + static_cast<std::ptrdiff_t>(count),
            reinterpret_cast<unsigned int*>(out.data()));
  return out;
}

void Simplify(mesh::Mesh& m, float fraction) {
  REPHOTO_CHECK(!m.is_point_cloud(), "simplification needs a mesh with faces, not a point cloud");
  WedgesToVertexTexcoords(m);
  if (m.face_materials.empty()) {
    m.faces = SimplifyFaces(m.faces, m.positions, fraction);
  } else {
    // One group per material, so every output face keeps its material.
    int max_material = -1;
    for (int material : m.face_materials) max_material = std::max(max_material, material);
    std::vector<mesh::Triangle> faces;
    std::vector<int> materials;
    for (int material = -1; material <= max_material; ++material) {
      std::vector<mesh::Triangle> group;
      for (size_t f = 0; f < m.faces.size(); ++f) {
        if (m.face_materials[f] == material) group.push_back(m.faces[f]);
      }
      if (group.empty()) continue;
      const auto simplified = SimplifyFaces(group, m.positions, fraction);
      faces.insert(faces.end(), simplified.begin(), simplified.end());
      materials.insert(materials.end(), simplified.size(), material);
    }
    m.faces = std::move(faces);
    m.face_materials = std::move(materials);
  }
  CompactVertices(m);
}

// Texel noise (see DegradeOptions::texture_noise): per textured material, the surface point of
// every covered texel, then the noise offset at that point.
void AddTexelNoise(mesh::Mesh& m, const std::vector<Eigen::Vector3f>& base_positions,
                   float to_noise, const DegradeOptions& options,
                   const std::array<SimplexNoise, 3>& noise) {
  REPHOTO_CHECK(!options.texture_dir.empty(),
                "texel noise on a textured mesh needs a folder for the noisy textures");
  std::filesystem::create_directories(options.texture_dir);
  for (size_t material = 0; material < m.materials.size(); ++material) {
    auto& mat = m.materials[material];
    if (mat.diffuse_texture.empty()) continue;
    Image texture = io::ReadImage(mat.diffuse_texture);
    const int w = texture.width(), h = texture.height();
    // Surface point per texel; NaN x = no face covers it.
    std::vector<Eigen::Vector3f> point(size_t(w) * h, Eigen::Vector3f::Constant(std::nanf("")));
    std::vector<float> distance(size_t(w) * h, std::numeric_limits<float>::infinity());
    for (size_t f = 0; f < m.faces.size(); ++f) {
      if (m.FaceMaterial(f) != static_cast<int>(material)) continue;
      // Texel-centre coordinates: texel (i, j) has its centre at X = i, Y = j.
      Eigen::Vector2f t[3];
      for (int c = 0; c < 3; ++c) {
        const Eigen::Vector2f uv = m.Texcoord(f, c);
        t[c] = Eigen::Vector2f(uv.x() * w - 0.5f, (1.f - uv.y()) * h - 0.5f);
      }
      const float area =
          (t[1] - t[0]).x() * (t[2] - t[0]).y() - (t[1] - t[0]).y() * (t[2] - t[0]).x();
      if (!(std::abs(area) > 1e-12f) || !std::isfinite(area)) continue;
      const float x0 = std::floor(std::min({t[0].x(), t[1].x(), t[2].x()})) - 1;
      const float x1 = std::ceil(std::max({t[0].x(), t[1].x(), t[2].x()})) + 1;
      const float y0 = std::floor(std::min({t[0].y(), t[1].y(), t[2].y()})) - 1;
      const float y1 = std::ceil(std::max({t[0].y(), t[1].y(), t[2].y()})) + 1;
      if (x1 - x0 > 4.f * w || y1 - y0 > 4.f * h) continue;  // absurd coordinates
      const Eigen::Vector3f& p0 = base_positions[m.faces[f][0]];
      const Eigen::Vector3f& p1 = base_positions[m.faces[f][1]];
      const Eigen::Vector3f& p2 = base_positions[m.faces[f][2]];
      for (float y = y0; y <= y1; ++y) {
        for (float x = x0; x <= x1; ++x) {
          // Barycentric coordinates of the texel centre.
          const Eigen::Vector2f q(x, y);
          auto edge = [](const Eigen::Vector2f& a, const Eigen::Vector2f& b,
                         const Eigen::Vector2f& p) {
            return (b - a).x() * (p - a).y() - (b - a).y() * (p - a).x();
          };
          const float b0 = edge(t[1], t[2], q) / area, b1 = edge(t[2], t[0], q) / area,
                      b2 = 1.f - b0 - b1;
          // Distance (in texels, approximately) outside the triangle; 0 inside.
          float outside = 0;
          for (int c = 0; c < 3; ++c) {
            const float bc = c == 0 ? b0 : c == 1 ? b1 : b2;
            if (bc < 0) {
              const Eigen::Vector2f& a = t[(c + 1) % 3];
              const Eigen::Vector2f& b = t[(c + 2) % 3];
              outside =
                  std::max(outside, std::abs(edge(a, b, q)) / std::max((b - a).norm(), 1e-12f));
            }
          }
          if (outside > 1.f) continue;
          const int i = ((static_cast<int>(x) % w) + w) % w;  // GL_REPEAT
          const int j = ((static_cast<int>(y) % h) + h) % h;
          const size_t k = size_t(j) * w + i;
          if (outside >= distance[k]) continue;  // a face covering the texel better wins
          distance[k] = outside;
          point[k] = b0 * p0 + b1 * p1 + b2 * p2;
        }
      }
    }
    // Grey textures become colour: the noise is independent per channel.
    const int channels = texture.channels();
    const int out_channels = channels == 1 ? 3 : channels == 2 ? 4 : channels;
    Image out(w, h, out_channels);
    ParallelFor(0, h, 16, [&](int64_t row_begin, int64_t row_end) {
      for (int64_t y = row_begin; y < row_end; ++y) {
        for (int x = 0; x < w; ++x) {
          const size_t k = size_t(y) * w + x;
          const float* in = texture.data() + k * channels;
          float* o = out.data() + k * out_channels;
          const bool grey = channels <= 2;
          for (int c = 0; c < 3; ++c) o[c] = in[grey ? 0 : c];
          if (out_channels == 4) o[3] = in[channels - 1];
          if (std::isnan(point[k].x())) continue;
          const Eigen::Vector3f p = point[k] * to_noise;
          for (int c = 0; c < 3; ++c) {
            o[c] = std::clamp(o[c] + options.texture_noise * noise[c].Noise(p), 0.f, 1.f);
          }
        }
      }
    });
    const std::string name = mat.name.empty() ? std::to_string(material) : mat.name;
    std::string safe;
    for (char ch : name)
      safe += std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' ? ch : '_';
    const auto path = std::filesystem::absolute(
        options.texture_dir / fmt::format("{}_{}.png", options.texture_prefix, safe));
    io::WritePng(path, out);
    mat.diffuse_texture = path;
  }
}

}  // namespace

mesh::Mesh Degrade(const mesh::Mesh& model, const DegradeOptions& options, DegradeReport* report) {
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
  // Texture noise is sampled at the positions before geometry noise, so the two defects are
  // independent of each other.
  const std::vector<Eigen::Vector3f> base_positions =
      options.texture_noise > 0 ? m.positions : std::vector<Eigen::Vector3f>{};

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
    const std::array<SimplexNoise, 3> noise{SimplexNoise(options.seed * 4 + 1),
                                            SimplexNoise(options.seed * 4 + 2),
                                            SimplexNoise(options.seed * 4 + 3)};
    if (m.is_textured()) {
      AddTexelNoise(m, base_positions, to_noise, options, noise);
    } else {
      REPHOTO_CHECK(!m.colors.empty(),
                    "texture noise needs a texture or vertex colours (the model has neither)");
      ParallelFor(0, n, 4096, [&](int64_t b, int64_t e) {
        for (int64_t v = b; v < e; ++v) {
          const Eigen::Vector3f p = base_positions[v] * to_noise;
          Eigen::Vector3f& c = m.colors[v];
          for (int k = 0; k < 3; ++k) {
            c[k] = std::clamp(c[k] + options.texture_noise * noise[k].Noise(p), 0.f, 1.f);
          }
        }
      });
    }
  }
  if (report) *report = local;
  return m;
}

}  // namespace rephoto::degrade
