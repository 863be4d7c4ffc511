#include "rephoto/mesh/obj.h"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <initializer_list>
#include <map>
#include <sstream>
#include <string_view>

#include "rephoto/core/error.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/mesh/read_mesh.h"

namespace rephoto::mesh {
namespace {

std::string FirstLine(const std::string& text) {
  std::string line = text.substr(0, text.find('\n'));
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
  return line;
}

// The statements of `in` whose keyword (first word) is one of `keywords`, one per line.
// rephoto reads only positions (with colours), texture coordinates, normals, faces, groups and
// materials; tinyobjloader's parsers of the other statements are where hostile files hurt
// (a skin-weight line "vw 1 5e30" converted an out-of-range float to int, undefined
// behaviour; "vw 0 -1 0.5" failed the whole file), so they never see them.
std::string KeepStatements(std::istream& in, std::initializer_list<std::string_view> keywords) {
  std::string kept, line;
  while (std::getline(in, line)) {
    size_t begin = 0;
    while (begin < line.size() && (line[begin] == ' ' || line[begin] == '\t')) ++begin;
    size_t end = begin;
    while (end < line.size() && line[end] != ' ' && line[end] != '\t' && line[end] != '\r') ++end;
    const std::string_view keyword = std::string_view(line).substr(begin, end - begin);
    if (std::find(keywords.begin(), keywords.end(), keyword) == keywords.end()) continue;
    kept.append(line, begin);
    kept.push_back('\n');
  }
  return kept;
}

// Reads every mtllib file through KeepStatements: from `mtl` when given, else from
// `base_dir` + the name (as tinyobj::MaterialFileReader does).
class FilteringMaterialReader : public tinyobj::MaterialReader {
 public:
  FilteringMaterialReader(std::string base_dir, std::istream* mtl)
      : base_dir_(std::move(base_dir)), mtl_(mtl) {}

  bool operator()(const std::string& material_id, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* material_map, std::string* warn,
                  std::string* err) override {
    std::ifstream file;
    std::istream* in = mtl_;
    if (in == nullptr) {
      file.open(base_dir_ + material_id, std::ios::binary);
      if (!file.is_open()) {
        if (warn != nullptr) *warn += "Material file [ " + material_id + " ] not found.\n";
        return false;
      }
      in = &file;
    }
    std::istringstream kept(KeepStatements(*in, {"newmtl", "Kd", "map_Kd"}));
    tinyobj::LoadMtl(material_map, materials, &kept, warn, err);
    return true;
  }

 private:
  std::string base_dir_;
  std::istream* mtl_;
};

}  // namespace

Mesh ReadObj(const std::filesystem::path& path) {
  const std::string name = path.string();
  REPHOTO_CHECK(std::filesystem::is_regular_file(path), "{}: cannot open file", name);
  std::ifstream stream(path, std::ios::binary);
  REPHOTO_CHECK(stream.is_open(), "{}: cannot open file", name);
  return ReadObj(stream, name, path.parent_path());
}

Mesh ReadObj(std::istream& stream, std::string_view name_view,
             const std::filesystem::path& base_path, std::istream* mtl) {
  const std::string name(name_view);
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string warn, err;
  std::string base_dir = base_path.string();
  if (!base_dir.empty()) base_dir += '/';
  FilteringMaterialReader material_reader(base_dir, mtl);
  std::istringstream kept(
      KeepStatements(stream, {"v", "vt", "vn", "f", "g", "o", "usemtl", "mtllib"}));
  const bool ok = tinyobj::LoadObj(&attrib, &shapes, &materials, &warn, &err, &kept,
                                   &material_reader, /*triangulate=*/false,
                                   /*default_vcols_fallback=*/false);
  REPHOTO_CHECK(ok, "{}: {}", name, err.empty() ? std::string("cannot parse OBJ") : FirstLine(err));

  Mesh mesh;
  const size_t v = attrib.vertices.size() / 3;
  REPHOTO_CHECK(v > 0, "{}: empty mesh (no vertices)", name);
  mesh.positions.resize(v);
  for (size_t i = 0; i < v; ++i) {
    mesh.positions[i] = Eigen::Vector3f(attrib.vertices[3 * i], attrib.vertices[3 * i + 1],
                                        attrib.vertices[3 * i + 2]);
  }
  if (attrib.colors.size() == 3 * v) {
    mesh.colors.resize(v);
    for (size_t i = 0; i < v; ++i) {
      mesh.colors[i] =
          Eigen::Vector3f(attrib.colors[3 * i], attrib.colors[3 * i + 1], attrib.colors[3 * i + 2]);
    }
  }
  for (const tinyobj::material_t& m : materials) {
    Material material;
    material.name = m.name;
    material.diffuse = Eigen::Vector3f(m.diffuse[0], m.diffuse[1], m.diffuse[2]);
    if (!m.diffuse_texname.empty()) {
      std::filesystem::path texture(m.diffuse_texname);
      material.diffuse_texture = texture.is_absolute() ? texture : base_path / texture;
    }
    mesh.materials.push_back(std::move(material));
  }

  bool any_texcoord = false, any_normal = false, any_material = false;
  for (const tinyobj::shape_t& shape : shapes) {
    for (const tinyobj::index_t& index : shape.mesh.indices) {
      any_texcoord |= index.texcoord_index >= 0;
      any_normal |= index.normal_index >= 0;
    }
    for (int material : shape.mesh.material_ids) any_material |= material >= 0;
  }
  std::vector<Eigen::Vector3f> normal_sums;
  if (any_normal) normal_sums.assign(v, Eigen::Vector3f::Zero());
  const size_t normal_count = attrib.normals.size() / 3;
  const size_t texcoord_count = attrib.texcoords.size() / 2;
  for (size_t s = 0; s < shapes.size(); ++s) {
    const tinyobj::mesh_t& shape = shapes[s].mesh;
    size_t offset = 0;
    for (size_t f = 0; f < shape.num_face_vertices.size(); ++f) {
      const size_t n = shape.num_face_vertices[f];
      // Fan triangulation (v0, vk, vk+1), as for PLY; tinyobjloader's own triangulation of
      // rc10 produced overlapping triangles for a plain quad.
      for (size_t fan = 1; fan + 1 < n; ++fan) {
        const size_t face_number = mesh.faces.size();
        const size_t corners[3] = {offset, offset + fan, offset + fan + 1};
        Triangle triangle;
        for (size_t k = 0; k < 3; ++k) {
          const tinyobj::index_t& index = shape.indices[corners[k]];
          REPHOTO_CHECK(index.vertex_index >= 0 && static_cast<size_t>(index.vertex_index) < v,
                        "{}: face {}: vertex index {} out of range ({} vertices)", name,
                        face_number, index.vertex_index, v);
          triangle[k] = static_cast<uint32_t>(index.vertex_index);
          if (any_texcoord) {
            Eigen::Vector2f uv(0, 0);
            if (index.texcoord_index >= 0) {
              REPHOTO_CHECK(static_cast<size_t>(index.texcoord_index) < texcoord_count,
                            "{}: face {}: texture coordinate index {} out of range", name,
                            face_number, index.texcoord_index);
              uv = Eigen::Vector2f(attrib.texcoords[2 * index.texcoord_index],
                                   attrib.texcoords[2 * index.texcoord_index + 1]);
            }
            mesh.wedge_texcoords.push_back(uv);
          }
          if (any_normal && index.normal_index >= 0) {
            REPHOTO_CHECK(static_cast<size_t>(index.normal_index) < normal_count,
                          "{}: face {}: normal index {} out of range", name, face_number,
                          index.normal_index);
            normal_sums[triangle[k]] += Eigen::Vector3f(attrib.normals[3 * index.normal_index],
                                                        attrib.normals[3 * index.normal_index + 1],
                                                        attrib.normals[3 * index.normal_index + 2]);
          }
        }
        mesh.faces.push_back(triangle);
        if (any_material) {
          const int material = f < shape.material_ids.size() ? shape.material_ids[f] : -1;
          mesh.face_materials.push_back(material < static_cast<int>(materials.size()) ? material
                                                                                      : -1);
        }
      }
      offset += n;
    }
  }
  if (any_normal) {
    for (Eigen::Vector3f& normal : normal_sums) {
      const float length = normal.norm();
      if (length > 0) normal /= length;
    }
    mesh.normals = std::move(normal_sums);
  }
  mesh.Validate(name);
  return mesh;
}

Mesh ReadMesh(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::ifstream stream(path, std::ios::binary);
  REPHOTO_CHECK(stream.is_open(), "{}: cannot open file", name);
  char magic[4] = {0, 0, 0, 0};
  stream.read(magic, 4);
  if (stream.gcount() >= 3 && std::string_view(magic, 3) == "ply" &&
      (stream.gcount() == 3 || magic[3] == '\n' || magic[3] == '\r')) {
    stream.clear();
    stream.seekg(0);
    return ReadPly(stream, name, path.parent_path());
  }
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (extension == ".obj") return ReadObj(path);
  ThrowError("{}: unknown model format (expected a PLY or an .obj file)", name);
}

}  // namespace rephoto::mesh
