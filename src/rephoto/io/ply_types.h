// The scalar types of the PLY format (Turk 1994; names as in the header's "property" lines),
// shared by the mesh and Gaussian-splatting readers and writers.
//
// Thread safety: constant functions.
#pragma once

#include <optional>
#include <string_view>

namespace rephoto::io {

enum class PlyType { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat32, kFloat64 };

// The type of a header name: char/int8, uchar/uint8, short/int16, ushort/uint16, int/int32,
// uint/uint32, float/float32, double/float64; nullopt for anything else.
inline std::optional<PlyType> ParsePlyType(std::string_view name) {
  if (name == "char" || name == "int8") return PlyType::kInt8;
  if (name == "uchar" || name == "uint8") return PlyType::kUInt8;
  if (name == "short" || name == "int16") return PlyType::kInt16;
  if (name == "ushort" || name == "uint16") return PlyType::kUInt16;
  if (name == "int" || name == "int32") return PlyType::kInt32;
  if (name == "uint" || name == "uint32") return PlyType::kUInt32;
  if (name == "float" || name == "float32") return PlyType::kFloat32;
  if (name == "double" || name == "float64") return PlyType::kFloat64;
  return std::nullopt;
}

// Bytes of one value in a binary PLY.
inline int PlyTypeSize(PlyType type) {
  switch (type) {
    case PlyType::kInt8:
    case PlyType::kUInt8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUInt16:
      return 2;
    case PlyType::kInt32:
    case PlyType::kUInt32:
    case PlyType::kFloat32:
      return 4;
    case PlyType::kFloat64:
      return 8;
  }
  return 0;
}

}  // namespace rephoto::io
