// One entry point for reading any supported model file.
//
// Thread safety: reentrant; concurrent calls may read the same or different files.
#pragma once

#include <filesystem>

#include "rephoto/mesh/mesh.h"

namespace rephoto::mesh {

// Reads a PLY (detected by its "ply" magic, any extension) or an OBJ (.obj extension) file;
// throws Error naming the file for anything else or any problem (see ply.h, obj.h).
Mesh ReadMesh(const std::filesystem::path& path);

}  // namespace rephoto::mesh
