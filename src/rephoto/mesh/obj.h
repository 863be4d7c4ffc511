// Wavefront OBJ + MTL reading (through tinyobjloader).
//
// Positions, optional per-vertex colours ("v x y z r g b", all vertices or none), normals,
// texture coordinates and materials (Kd, map_Kd). Polygons are fan-triangulated. Because OBJ
// indexes normals and texture coordinates per corner: texture coordinates become wedge texture
// coordinates (Mesh::wedge_texcoords); normals become per-vertex normals (the normalized sum of
// the normals referenced by a vertex's corners). map_Kd paths are resolved against the MTL
// file's folder (the OBJ's folder). Errors name the file: a missing file, a parse error,
// or a face indexing a missing vertex (Mesh::Validate).
#pragma once

#include <filesystem>

#include "rephoto/mesh/mesh.h"

namespace rephoto::mesh {

Mesh ReadObj(const std::filesystem::path& path);

}  // namespace rephoto::mesh
