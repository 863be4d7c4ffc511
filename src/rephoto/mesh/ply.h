// PLY (Stanford polygon file format) reading and writing.
//
// Reading: ascii, binary_little_endian and binary_big_endian; every PLY scalar type (char/int8,
// uchar/uint8, short/int16, ushort/uint16, int/int32, uint/uint32, float/float32,
// double/float64). Element "vertex": x, y, z; nx, ny, nz; red, green, blue (alpha ignored;
// also r/g/b, diffuse_red/...) as integers (scaled by the type's maximum, e.g. uchar /255) or
// floats (as stored); texture coordinates u/v, s/t, texture_u/texture_v or texture_s/texture_t;
// radius. Any other scalar vertex property is kept as a Mesh::scalars entry (as float).
// Element "face": list vertex_indices or vertex_index (polygons fan-triangulated); optional list
// "texcoord" (2 floats per corner, OpenMVS/MeshLab) and scalar "texnumber" (index of the
// "comment TextureFile <path>" line, which becomes a Material). Unknown elements and properties
// (scalars and lists) are skipped. The data is streamed through a fixed buffer.
// Every problem is a rephoto::Error naming the file and, where known, the element and record:
// "mesh.ply: face 41: unexpected end of file (header promises 100 faces)".
// Before anything is allocated, the element counts of the header are checked: against the bytes
// left in the file (binary: the fixed part of each record; ASCII: two bytes per value), when
// the stream can tell, and the vertex and face arrays they imply against --max-memory
// (core/limits.h): "huge.ply: 4000000000 vertices need 44.7 GiB, more than --max-memory ...".
//
// Thread safety: reentrant; concurrent reads are fine, concurrent writes must go to different paths
// (each write is atomic, core/file.h).
#pragma once

#include <filesystem>
#include <istream>
#include <string_view>

#include "rephoto/mesh/mesh.h"

namespace rephoto::mesh {

// Reads a PLY file and validates the mesh (Mesh::Validate). Texture paths from TextureFile
// comments are resolved against the file's folder.
Mesh ReadPly(const std::filesystem::path& path);

// The same from a stream (binary mode); `name` prefixes error messages, `base_dir` resolves
// relative texture paths.
Mesh ReadPly(std::istream& stream, std::string_view name,
             const std::filesystem::path& base_dir = {});

enum class PlyEncoding { kBinaryLittleEndian, kAscii };

// Writes the mesh atomically. Vertex: x y z (float), nx ny nz (float) if present, red green
// blue (uchar, round(255 * clamp(c, 0, 1))) if present, texture_u texture_v (float) for vertex
// texture coordinates, radius (float), then each Mesh::scalars entry as a float property.
// Face: vertex_indices (list uchar int), texcoord (list uchar float, 6 per face) for wedge
// coordinates and texnumber (int) when there are face materials. Materials with textures are
// written as "comment TextureFile <path>" (paths as stored in the mesh). Throws Error naming the
// path when it cannot be written.
// Vertex colours exactly as WritePly stores them (8 bits per channel, rounded, clamped to
// [0, 1]) and ReadPly reads them back: a model rendered from memory then gives the same pixels
// as the same model read from its PLY.
void QuantizeColorsAsPly(std::vector<Eigen::Vector3f>* colors);

void WritePly(const std::filesystem::path& path, const Mesh& mesh,
              PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian);

// The same into a stream (binary mode).
void WritePly(std::ostream& stream, const Mesh& mesh,
              PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian);

}  // namespace rephoto::mesh
