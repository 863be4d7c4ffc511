// Wavefront OBJ + MTL reading (through tinyobjloader).
//
// Positions, optional per-vertex colours ("v x y z r g b", all vertices or none), normals,
// texture coordinates and materials (Kd, map_Kd). Polygons are fan-triangulated. Because OBJ
// indexes normals and texture coordinates per corner: texture coordinates become wedge texture
// coordinates (Mesh::wedge_texcoords); normals become per-vertex normals (the normalized sum of
// the normals referenced by a vertex's corners). map_Kd paths are resolved against the MTL
// file's folder (the OBJ's folder). Errors name the file: a missing file, a parse error,
// or a face indexing a missing vertex (Mesh::Validate).
//
// Thread safety: reentrant (tinyobjloader keeps no global state); concurrent calls may read
// different or the same files.
#pragma once

#include <filesystem>
#include <istream>
#include <string_view>

#include "rephoto/mesh/mesh.h"

namespace rephoto::mesh {

Mesh ReadObj(const std::filesystem::path& path);

// The same from a stream: `name` prefixes error messages; `base_dir` is the folder mtllib files
// and map_Kd textures are resolved against (empty: the working directory). With `mtl`, every
// mtllib statement reads that stream instead of a file (tests and fuzzers: no file is opened).
// OBJ files hold no counts: memory grows with the content read, never with a claim.
Mesh ReadObj(std::istream& stream, std::string_view name,
             const std::filesystem::path& base_dir = {}, std::istream* mtl = nullptr);

}  // namespace rephoto::mesh
