// Writers of texture_mesh.h: OBJ + MTL + PNG atlases, PLY, and the JSON report.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"
#include "rephoto/texture/texture_mesh.h"

namespace rephoto::texture {
namespace {

namespace fs = std::filesystem;

// NAME of …/NAME.obj with blanks replaced (MTL statements end at a blank).
std::string BaseName(const fs::path& path) {
  std::string stem = path.stem().string();
  std::replace_if(
      stem.begin(), stem.end(), [](char c) { return c == ' ' || c == '\t'; }, '_');
  REPHOTO_CHECK(!stem.empty(), "{}: the output needs a file name", path.string());
  return stem;
}

std::string AtlasName(const std::string& base, size_t i) {
  return fmt::format("{}_atlas_{}.png", base, i);
}

void WriteAtlases(const fs::path& folder, const std::string& base, const TexturedMesh& textured) {
  for (size_t i = 0; i < textured.atlases.size(); ++i) {
    const Image8& atlas = textured.atlases[i];
    io::WritePng8(folder / AtlasName(base, i), {atlas.data(), atlas.size()}, atlas.width(),
                  atlas.height(), atlas.channels());
  }
}

void WriteText(const fs::path& path, const std::string& text) {
  WriteFileAtomically(path, [&](const fs::path& temporary) {
    std::FILE* file = std::fopen(temporary.c_str(), "wb");
    REPHOTO_CHECK(file != nullptr, "{}: cannot open for writing: {}", path.string(),
                  std::strerror(errno));
    const size_t written = std::fwrite(text.data(), 1, text.size(), file);
    const int closed = std::fclose(file);
    REPHOTO_CHECK(written == text.size() && closed == 0, "{}: write failed: {}", path.string(),
                  std::strerror(errno));
  });
}

}  // namespace

void WriteTexturedObj(const fs::path& path, const TexturedMesh& textured) {
  const mesh::Mesh& mesh = textured.mesh;
  REPHOTO_CHECK(mesh.wedge_texcoords.size() == 3 * mesh.faces.size() &&
                    mesh.face_materials.size() == mesh.faces.size(),
                "{}: the mesh has no texture coordinates to write", path.string());
  const fs::path folder = path.parent_path();
  const std::string base = BaseName(path);
  WriteAtlases(folder, base, textured);
  std::string mtl = "# written by rephoto texture\n";
  for (size_t i = 0; i < textured.atlases.size(); ++i) {
    mtl += fmt::format("newmtl atlas_{}\nKa 0 0 0\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd {}\n\n", i,
                       AtlasName(base, i));
  }
  WriteText(folder / (base + ".mtl"), mtl);

  // One vt per distinct (vertex, coordinate): corners of one vertex inside a patch share it.
  const size_t wedges = mesh.wedge_texcoords.size();
  std::vector<std::array<uint32_t, 4>> keys(wedges);  // vertex, u bits, v bits, wedge
  for (size_t w = 0; w < wedges; ++w) {
    uint32_t u, v;
    std::memcpy(&u, &mesh.wedge_texcoords[w].x(), 4);
    std::memcpy(&v, &mesh.wedge_texcoords[w].y(), 4);
    keys[w] = {mesh.faces[w / 3][w % 3], u, v, static_cast<uint32_t>(w)};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<uint32_t> vt_of_wedge(wedges);
  std::vector<uint32_t> vt_wedge;  // first wedge of each vt
  for (size_t i = 0; i < wedges; ++i) {
    if (i == 0 || keys[i][0] != keys[i - 1][0] || keys[i][1] != keys[i - 1][1] ||
        keys[i][2] != keys[i - 1][2]) {
      vt_wedge.push_back(keys[i][3]);
    }
    vt_of_wedge[keys[i][3]] = static_cast<uint32_t>(vt_wedge.size());  // 1-based
  }

  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out),
                 "# written by rephoto texture: {} vertices, {} faces, {} atlases\nmtllib {}.mtl\n",
                 mesh.positions.size(), mesh.faces.size(), textured.atlases.size(), base);
  for (const Eigen::Vector3f& p : mesh.positions) {
    fmt::format_to(std::back_inserter(out), "v {} {} {}\n", p.x(), p.y(), p.z());
  }
  for (uint32_t w : vt_wedge) {
    fmt::format_to(std::back_inserter(out), "vt {} {}\n", mesh.wedge_texcoords[w].x(),
                   mesh.wedge_texcoords[w].y());
  }
  // Faces grouped by atlas, in face order within each.
  for (size_t atlas = 0; atlas < textured.atlases.size(); ++atlas) {
    fmt::format_to(std::back_inserter(out), "usemtl atlas_{}\n", atlas);
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      if (mesh.face_materials[f] != static_cast<int>(atlas)) continue;
      const mesh::Triangle& t = mesh.faces[f];
      fmt::format_to(std::back_inserter(out), "f {}/{} {}/{} {}/{}\n", t[0] + 1, vt_of_wedge[3 * f],
                     t[1] + 1, vt_of_wedge[3 * f + 1], t[2] + 1, vt_of_wedge[3 * f + 2]);
    }
  }
  WriteText(path, std::string(out.data(), out.size()));
}

void WriteTexturedPly(const fs::path& path, const TexturedMesh& textured,
                      mesh::PlyEncoding encoding) {
  const fs::path folder = path.parent_path();
  const std::string base = BaseName(path);
  WriteAtlases(folder, base, textured);
  mesh::Mesh mesh = textured.mesh;
  for (size_t i = 0; i < mesh.materials.size(); ++i) {
    mesh.materials[i].diffuse_texture = AtlasName(base, i);
  }
  mesh::WritePly(path, mesh, encoding);
}

std::string TextureReportJson(const TextureReport& r) {
  nlohmann::ordered_json json;
  json["schema"] = "rephoto.texture/1";
  json["vertices"] = r.vertices;
  json["faces"] = r.faces;
  json["views_given"] = r.views_given;
  json["views_used"] = r.views_used;
  json["visible_faces"] = r.visible_faces;
  json["textured_faces"] = r.textured_faces;
  json["partial_faces"] = r.partial_faces;
  json["filled_faces"] = r.filled_faces;
  json["default_faces"] = r.default_faces;
  json["candidates"] = r.candidates;
  json["inconsistent_candidates"] = r.inconsistent_candidates;
  json["mrf_initial_energy"] = r.mrf_initial_energy;
  json["mrf_energy"] = r.mrf_energy;
  json["mrf_moves"] = r.mrf_moves;
  json["patches"] = r.patches;
  json["seam_vertices"] = r.seam_vertices;
  json["leveling_iterations"] = r.leveling_iterations;
  json["atlases"] = r.atlases;
  json["atlas_texels"] = r.atlas_texels;
  json["reassigned_texels"] = r.reassigned_texels;
  json["seconds"] = {{"visibility", r.seconds_visibility}, {"consistency", r.seconds_consistency},
                     {"selection", r.seconds_selection},   {"leveling", r.seconds_leveling},
                     {"atlas", r.seconds_atlas},           {"total", r.seconds_total}};
  return json.dump(2) + "\n";
}

void WriteTextureReport(const fs::path& path, const TextureReport& report) {
  WriteTextFileAtomically(path, TextureReportJson(report));
}

}  // namespace rephoto::texture
