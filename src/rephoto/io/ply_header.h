// The header of a PLY file (Turk 1994), parsed in one place for every PLY reader of the project:
// meshes and point clouds (mesh/ply.h), 3D Gaussians (splat/gaussians.h) and the rewrite that
// adds a per-vertex scalar (splat/scalar_ply.h).
//
// Accepted: the line "ply", then lines through "end_header", each ending in LF or CRLF:
//   format ascii|binary_little_endian|binary_big_endian VERSION
//   element NAME COUNT                          (COUNT a decimal integer < 2^64)
//   property TYPE NAME                          (TYPE as io/ply_types.h)
//   property list COUNT_TYPE ITEM_TYPE NAME     (COUNT_TYPE an integer type)
//   comment TEXT, obj_info TEXT, blank lines
// Limits (checked on the bytes read, before anything is allocated for them): a line of at most
// 64 KiB, a header of at most 1 MiB. Errors are rephoto::Error with one line naming the file
// and, where it applies, the header line: "mesh.ply: header line 4: bad property 'property
// fancy x'".
//
// Thread safety: pure functions.
#pragma once

#include <cstdint>
#include <functional>
#include <istream>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/io/ply_types.h"

namespace rephoto::io {

enum class PlyEncoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;  // the item type for lists
  bool is_list = false;
  PlyType count_type = PlyType::kUInt8;  // lists only
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;

  // Index of the scalar (non-list) property `property`, or -1.
  int Find(std::string_view property) const;
  bool HasList() const;
  // Bytes of one binary record (meaningful without lists).
  uint64_t RecordBytes() const;
};

struct PlyHeader {
  PlyEncoding encoding = PlyEncoding::kAscii;
  std::vector<PlyElement> elements;
  std::vector<std::string> comments;  // the text after "comment " of each comment line
  uint64_t bytes = 0;                 // of the header, through end_header's line feed

  const PlyElement* Find(std::string_view element) const;  // nullptr when absent
};

// Parses lines handed out by `next_line` (a line without its LF; false at the end of the
// input). `name` names the file in errors.
PlyHeader ParsePlyHeader(const std::function<bool(std::string& line)>& next_line,
                         std::string_view name);

// Reads the header from a stream, which is left at the first byte of the body.
PlyHeader ReadPlyHeader(std::istream& in, std::string_view name);

// The header of a PLY file held in memory (the body starts at bytes[header.bytes]).
PlyHeader ParsePlyHeader(std::string_view bytes, std::string_view name);

}  // namespace rephoto::io
