#include "rephoto/mesh/ply.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/limits.h"
#include "rephoto/io/ply_header.h"
#include "rephoto/io/ply_types.h"

namespace rephoto::mesh {
namespace {

// PLY scalar types: io/ply_types.h.
using Type = io::PlyType;
inline int TypeSize(Type type) { return io::PlyTypeSize(type); }

// Scale that maps an integer colour channel to [0,1]; 1 for floating-point types.
double ColorScale(Type type) {
  switch (type) {
    case Type::kInt8:
      return 1.0 / 127;
    case Type::kUInt8:
      return 1.0 / 255;
    case Type::kInt16:
      return 1.0 / 32767;
    case Type::kUInt16:
      return 1.0 / 65535;
    case Type::kInt32:
      return 1.0 / 2147483647.0;
    case Type::kUInt32:
      return 1.0 / 4294967295.0;
    default:
      return 1.0;
  }
}

// What a property means to the reader.
enum class Role {
  kSkip,
  kX,
  kY,
  kZ,
  kNx,
  kNy,
  kNz,
  kRed,
  kGreen,
  kBlue,
  kU,
  kV,
  kRadius,
  kScalar,
  kVertexIndices,
  kTexcoords,
  kTexnumber,
};

struct Property {
  std::string name;
  Type type = Type::kFloat32;
  bool is_list = false;
  Type count_type = Type::kUInt8;
  Role role = Role::kSkip;
  int scalar_index = -1;  // for Role::kScalar: index into Mesh::scalars
};

struct Element {
  std::string name;
  size_t count = 0;
  std::vector<Property> properties;
};

enum class Format { kAscii, kBinaryLittle, kBinaryBig };

Role VertexRole(std::string_view name) {
  if (name == "x") return Role::kX;
  if (name == "y") return Role::kY;
  if (name == "z") return Role::kZ;
  if (name == "nx") return Role::kNx;
  if (name == "ny") return Role::kNy;
  if (name == "nz") return Role::kNz;
  if (name == "red" || name == "r" || name == "diffuse_red") return Role::kRed;
  if (name == "green" || name == "g" || name == "diffuse_green") return Role::kGreen;
  if (name == "blue" || name == "b" || name == "diffuse_blue") return Role::kBlue;
  if (name == "u" || name == "s" || name == "texture_u" || name == "texture_s") return Role::kU;
  if (name == "v" || name == "t" || name == "texture_v" || name == "texture_t") return Role::kV;
  if (name == "radius") return Role::kRadius;
  if (name == "alpha" || name == "a" || name == "diffuse_alpha") return Role::kSkip;
  return Role::kScalar;
}

// Buffered reader over an istream: binary values and ASCII tokens, never copying the whole file.
class PlyInput {
 public:
  PlyInput(std::istream& stream, std::string_view name)
      : stream_(stream), name_(name), buffer_(kBufferSize) {}

  // Makes at least n bytes available at data(); false at end of file.
  bool Ensure(size_t n) {
    if (end_ - pos_ >= n) return true;
    std::memmove(buffer_.data(), buffer_.data() + pos_, end_ - pos_);
    end_ -= pos_;
    pos_ = 0;
    while (end_ < n && stream_) {
      stream_.read(reinterpret_cast<char*>(buffer_.data()) + end_,
                   static_cast<std::streamsize>(buffer_.size() - end_));
      end_ += static_cast<size_t>(stream_.gcount());
    }
    return end_ >= n;
  }
  const uint8_t* data() const { return buffer_.data() + pos_; }
  void Skip(size_t n) { pos_ += n; }

  // A header line without its line terminator; false at end of file.
  bool ReadLine(std::string& line) {
    line.clear();
    while (true) {
      if (!Ensure(1)) return false;  // a header line always ends with a line feed
      const uint8_t c = buffer_[pos_++];
      if (c == '\n') break;
      line.push_back(static_cast<char>(c));
      if (line.size() > 100000) ThrowError("{}: header line too long (not a PLY file?)", name_);
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }

  // The next whitespace-separated ASCII token as a number; false at end of file.
  bool ReadAsciiNumber(double& value, bool& malformed) {
    malformed = false;
    while (true) {
      if (!Ensure(1)) return false;
      const uint8_t c = buffer_[pos_];
      if (c != ' ' && c != '\t' && c != '\n' && c != '\r') break;
      ++pos_;
    }
    char token[128];
    size_t length = 0;
    while (Ensure(1)) {
      const uint8_t c = buffer_[pos_];
      if (c == ' ' || c == '\t' || c == '\n' || c == '\r') break;
      if (length + 1 >= sizeof(token)) {
        malformed = true;
        return true;
      }
      token[length++] = static_cast<char>(c);
      ++pos_;
    }
    const char* begin = token;
    if (length > 0 && token[0] == '+') ++begin;  // from_chars rejects a leading '+'
    const auto result = std::from_chars(begin, token + length, value);
    malformed = result.ec != std::errc() || result.ptr != token + length;
    if (result.ec == std::errc::result_out_of_range) {
      malformed = false;
      value = std::strtod(std::string(token, length).c_str(), nullptr);
    }
    return true;
  }

  // Bytes left in the stream (including the buffer), if the stream can tell.
  std::optional<uint64_t> RemainingBytes() {
    // Reading ran into the end of the stream: the rest is in the buffer. (A failed read also
    // makes tellg() fail, which had hidden the size of every file smaller than the buffer.)
    if (stream_.eof()) return end_ - pos_;
    const std::streampos here = stream_.tellg();
    if (here == std::streampos(-1)) return std::nullopt;
    stream_.seekg(0, std::ios::end);
    const std::streampos end = stream_.tellg();
    stream_.seekg(here);
    if (end == std::streampos(-1) || !stream_) {
      stream_.clear();
      return std::nullopt;
    }
    return static_cast<uint64_t>(end - here) + (end_ - pos_);
  }

 private:
  static constexpr size_t kBufferSize = 1 << 20;
  std::istream& stream_;
  std::string name_;
  std::vector<uint8_t> buffer_;
  size_t pos_ = 0;
  size_t end_ = 0;
};

class PlyReader {
 public:
  PlyReader(std::istream& stream, std::string_view name, const std::filesystem::path& base_dir)
      : input_(stream, name), name_(name), base_dir_(base_dir) {}

  Mesh Read() {
    ReadHeader();
    CheckSizes();
    for (const Element& element : elements_) ReadElement(element);
    mesh_.Validate(name_);
    return std::move(mesh_);
  }

 private:
  // The header (io/ply_header.h, the project's one PLY header parser), then this reader's view
  // of it: the roles of the properties and the texture files named in comments.
  void ReadHeader() {
    const io::PlyHeader header =
        io::ParsePlyHeader([this](std::string& line) { return input_.ReadLine(line); }, name_);
    switch (header.encoding) {
      case io::PlyEncoding::kAscii:
        format_ = Format::kAscii;
        break;
      case io::PlyEncoding::kBinaryLittleEndian:
        format_ = Format::kBinaryLittle;
        break;
      case io::PlyEncoding::kBinaryBigEndian:
        format_ = Format::kBinaryBig;
        break;
    }
    for (const io::PlyElement& in : header.elements) {
      Element element;
      element.name = in.name;
      REPHOTO_CHECK(in.count <= std::numeric_limits<size_t>::max(),
                    "{}: element '{}': count {} is too large", name_, in.name, in.count);
      element.count = static_cast<size_t>(in.count);
      for (const io::PlyProperty& p : in.properties) {
        Property property;
        property.name = p.name;
        property.type = p.type;
        property.is_list = p.is_list;
        property.count_type = p.count_type;
        element.properties.push_back(std::move(property));
      }
      elements_.push_back(std::move(element));
    }
    for (const std::string& comment : header.comments) {
      // "TextureFile <file>" (MeshLab's, OpenMVS's and mvs-texturing's way to name a texture).
      constexpr std::string_view kTag = "TextureFile";
      if (!comment.starts_with(kTag) ||
          (comment.size() > kTag.size() && comment[kTag.size()] != ' ' &&
           comment[kTag.size()] != '\t')) {
        continue;
      }
      std::string file = comment.substr(kTag.size());
      const size_t first = file.find_first_not_of(" \t");
      file = first == std::string::npos ? std::string() : file.substr(first);
      while (!file.empty() && (file.back() == ' ' || file.back() == '\t')) file.pop_back();
      if (file.empty()) continue;
      Material material;
      material.name = file;
      std::filesystem::path path(file);
      material.diffuse_texture = path.is_absolute() || base_dir_.empty() ? path : base_dir_ / path;
      mesh_.materials.push_back(std::move(material));
    }
    AssignRoles();
  }

  void AssignRoles() {
    for (Element& element : elements_) {
      if (element.name == "vertex") {
        REPHOTO_CHECK(vertex_element_ == nullptr, "{}: more than one vertex element", name_);
        vertex_element_ = &element;
        for (Property& p : element.properties) {
          if (p.is_list) continue;  // unknown list: skipped
          p.role = VertexRole(p.name);
          if (p.role == Role::kScalar) {
            p.scalar_index = static_cast<int>(mesh_.scalars.size());
            mesh_.scalars.push_back({p.name, {}});
          }
        }
      } else if (element.name == "face") {
        for (Property& p : element.properties) {
          if (p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
            p.role = Role::kVertexIndices;
          } else if (p.is_list && p.name == "texcoord") {
            p.role = Role::kTexcoords;
          } else if (!p.is_list && p.name == "texnumber") {
            p.role = Role::kTexnumber;
          }
        }
      }
    }
    REPHOTO_CHECK(vertex_element_ != nullptr, "{}: no vertex element", name_);
    bool has[3] = {false, false, false};
    for (const Property& p : vertex_element_->properties) {
      if (p.role == Role::kX) has[0] = true;
      if (p.role == Role::kY) has[1] = true;
      if (p.role == Role::kZ) has[2] = true;
    }
    REPHOTO_CHECK(has[0] && has[1] && has[2], "{}: vertex element lacks x, y or z", name_);
  }

  // The fewest bytes one record of `element` takes in the file: binary, the sizes of its
  // scalars and list counts; ASCII, one digit and one separator per value. At least 1.
  uint64_t MinRecordBytes(const Element& element) const {
    uint64_t record = 0;
    for (const Property& p : element.properties) {
      if (format_ == Format::kAscii) {
        record += 2;
      } else {
        record += p.is_list ? TypeSize(p.count_type) : TypeSize(p.type);
      }
    }
    return std::max<uint64_t>(record, 1);
  }

  // Before anything is allocated: a header that promises more records than the rest of the file
  // can hold is rejected (when the stream can tell its size), and so is one whose vertices and
  // faces would need more than --max-memory (core/limits.h) once read.
  void CheckSizes() {
    const auto remaining = input_.RemainingBytes();
    if (remaining) remaining_bytes_ = *remaining;
    uint64_t minimum = 0;
    for (const Element& element : elements_) {
      if (element.properties.empty()) continue;  // takes no bytes, is never stored
      const uint64_t bytes = SaturatingMultiply(MinRecordBytes(element), element.count);
      minimum = bytes > UINT64_MAX - minimum ? UINT64_MAX : minimum + bytes;
      // An ASCII file may end without a separator after its last value.
      const uint64_t slack = format_ == Format::kAscii ? 1 : 0;
      REPHOTO_CHECK(!remaining || minimum <= remaining_bytes_ + slack,
                    "{}: header promises {} {} elements ({} bytes at least) but only {} bytes "
                    "of data follow (truncated file?)",
                    name_, element.count, element.name, minimum, remaining_bytes_);
    }
    CheckMemory();
  }

  void CheckMemory() const {
    uint64_t vertex_bytes = 0, vertices = 0, face_bytes = 0, faces = 0;
    if (vertex_element_ != nullptr) {
      bool normals = false, colors = false, texcoords = false, radii = false;
      for (const Property& p : vertex_element_->properties) {
        normals |= p.role == Role::kNx || p.role == Role::kNy || p.role == Role::kNz;
        colors |= p.role == Role::kRed || p.role == Role::kGreen || p.role == Role::kBlue;
        texcoords |= p.role == Role::kU || p.role == Role::kV;
        radii |= p.role == Role::kRadius;
      }
      vertices = vertex_element_->count;
      const uint64_t per_vertex = sizeof(Eigen::Vector3f) * (1 + normals + colors) +
                                  sizeof(Eigen::Vector2f) * texcoords + sizeof(float) * radii +
                                  sizeof(float) * mesh_.scalars.size();
      vertex_bytes = SaturatingMultiply(vertices, per_vertex);
    }
    for (const Element& element : elements_) {
      if (element.name != "face") continue;
      bool texcoords = false, texnumber = false;
      for (const Property& p : element.properties) {
        texcoords |= p.role == Role::kTexcoords;
        texnumber |= p.role == Role::kTexnumber;
      }
      // At least one triangle per face (polygons become more).
      faces = element.count;
      const uint64_t per_face =
          sizeof(Triangle) + 3 * sizeof(Eigen::Vector2f) * texcoords + sizeof(int) * texnumber;
      face_bytes = SaturatingMultiply(faces, per_face);
    }
    const uint64_t total =
        vertex_bytes > UINT64_MAX - face_bytes ? UINT64_MAX : vertex_bytes + face_bytes;
    CheckAllocation(name_,
                    faces == 0 ? fmt::format("{} vertices", vertices)
                               : fmt::format("{} vertices and {} faces", vertices, faces),
                    total);
  }

  // Capacity worth reserving for `element`'s records: never more than the rest of the file can
  // hold, and a bounded start when the stream cannot tell its size (the vectors grow as the
  // records arrive, so a header that lies costs nothing).
  size_t ReserveCount(const Element& element) const {
    constexpr uint64_t kUnknownSizeReserve = uint64_t{1} << 20;
    const uint64_t fits = remaining_bytes_ == std::numeric_limits<uint64_t>::max()
                              ? kUnknownSizeReserve
                              : remaining_bytes_ / MinRecordBytes(element) + 1;
    return static_cast<size_t>(std::min<uint64_t>(element.count, fits));
  }

  [[noreturn]] void EndOfFile(const Element& element, size_t index) const {
    ThrowError("{}: {} {}: unexpected end of file (header promises {} {} elements)", name_,
               element.name, index, element.count, element.name);
  }

  double ReadValue(Type type, const Element& element, size_t index) {
    if (format_ == Format::kAscii) {
      double value = 0;
      bool malformed = false;
      if (!input_.ReadAsciiNumber(value, malformed)) EndOfFile(element, index);
      REPHOTO_CHECK(!malformed, "{}: {} {}: malformed number", name_, element.name, index);
      return value;
    }
    const int size = TypeSize(type);
    if (!input_.Ensure(size)) EndOfFile(element, index);
    uint8_t bytes[8];
    std::memcpy(bytes, input_.data(), size);
    input_.Skip(size);
    if ((format_ == Format::kBinaryBig) != (std::endian::native == std::endian::big)) {
      std::reverse(bytes, bytes + size);
    }
    switch (type) {
      case Type::kInt8: {
        int8_t v;
        std::memcpy(&v, bytes, 1);
        return v;
      }
      case Type::kUInt8:
        return bytes[0];
      case Type::kInt16: {
        int16_t v;
        std::memcpy(&v, bytes, 2);
        return v;
      }
      case Type::kUInt16: {
        uint16_t v;
        std::memcpy(&v, bytes, 2);
        return v;
      }
      case Type::kInt32: {
        int32_t v;
        std::memcpy(&v, bytes, 4);
        return v;
      }
      case Type::kUInt32: {
        uint32_t v;
        std::memcpy(&v, bytes, 4);
        return v;
      }
      case Type::kFloat32: {
        float v;
        std::memcpy(&v, bytes, 4);
        return v;
      }
      case Type::kFloat64: {
        double v;
        std::memcpy(&v, bytes, 8);
        return v;
      }
    }
    return 0;
  }

  size_t ReadListCount(const Property& p, const Element& element, size_t index) {
    const double count = ReadValue(p.count_type, element, index);
    REPHOTO_CHECK(count >= 0 && count == std::floor(count) && count < 1e9,
                  "{}: {} {}: bad list length {}", name_, element.name, index, count);
    return static_cast<size_t>(count);
  }

  void SkipValues(Type type, size_t n, const Element& element, size_t index) {
    if (format_ == Format::kAscii) {
      for (size_t i = 0; i < n; ++i) ReadValue(type, element, index);
      return;
    }
    const size_t bytes = n * TypeSize(type);
    size_t done = 0;
    while (done < bytes) {
      const size_t step = std::min<size_t>(bytes - done, 1 << 16);
      if (!input_.Ensure(step)) EndOfFile(element, index);
      input_.Skip(step);
      done += step;
    }
  }

  void ReadElement(const Element& element) {
    if (&element == vertex_element_) {
      ReadVertices(element);
    } else if (element.name == "face") {
      ReadFaces(element);
    } else if (!element.properties.empty()) {
      for (size_t i = 0; i < element.count; ++i) {
        for (const Property& p : element.properties) {
          if (p.is_list) {
            SkipValues(p.type, ReadListCount(p, element, i), element, i);
          } else {
            SkipValues(p.type, 1, element, i);
          }
        }
      }
    }
  }

  void ReadVertices(const Element& element) {
    bool normals = false, colors = false, texcoords = false, radii = false;
    for (const Property& p : element.properties) {
      normals |= p.role == Role::kNx || p.role == Role::kNy || p.role == Role::kNz;
      colors |= p.role == Role::kRed || p.role == Role::kGreen || p.role == Role::kBlue;
      texcoords |= p.role == Role::kU || p.role == Role::kV;
      radii |= p.role == Role::kRadius;
    }
    const size_t n = element.count;
    const size_t reserve = ReserveCount(element);
    mesh_.positions.reserve(reserve);
    if (normals) mesh_.normals.reserve(reserve);
    if (colors) mesh_.colors.reserve(reserve);
    if (texcoords) mesh_.vertex_texcoords.reserve(reserve);
    if (radii) mesh_.radii.reserve(reserve);
    for (VertexScalar& s : mesh_.scalars) s.values.reserve(reserve);
    for (size_t i = 0; i < n; ++i) {
      Eigen::Vector3f position(0, 0, 0), normal(0, 0, 0), color(0, 0, 0);
      Eigen::Vector2f uv(0, 0);
      float radius = 0;
      for (const Property& p : element.properties) {
        if (p.is_list) {
          SkipValues(p.type, ReadListCount(p, element, i), element, i);
          continue;
        }
        const double value = ReadValue(p.type, element, i);
        switch (p.role) {
          case Role::kX:
            position.x() = static_cast<float>(value);
            break;
          case Role::kY:
            position.y() = static_cast<float>(value);
            break;
          case Role::kZ:
            position.z() = static_cast<float>(value);
            break;
          case Role::kNx:
            normal.x() = static_cast<float>(value);
            break;
          case Role::kNy:
            normal.y() = static_cast<float>(value);
            break;
          case Role::kNz:
            normal.z() = static_cast<float>(value);
            break;
          case Role::kRed:
            color.x() = static_cast<float>(value * ColorScale(p.type));
            break;
          case Role::kGreen:
            color.y() = static_cast<float>(value * ColorScale(p.type));
            break;
          case Role::kBlue:
            color.z() = static_cast<float>(value * ColorScale(p.type));
            break;
          case Role::kU:
            uv.x() = static_cast<float>(value);
            break;
          case Role::kV:
            uv.y() = static_cast<float>(value);
            break;
          case Role::kRadius:
            radius = static_cast<float>(value);
            break;
          case Role::kScalar:
            mesh_.scalars[p.scalar_index].values.push_back(static_cast<float>(value));
            break;
          default:
            break;
        }
      }
      mesh_.positions.push_back(position);
      if (normals) mesh_.normals.push_back(normal);
      if (colors) mesh_.colors.push_back(color);
      if (texcoords) mesh_.vertex_texcoords.push_back(uv);
      if (radii) mesh_.radii.push_back(radius);
    }
  }

  void ReadFaces(const Element& element) {
    bool has_indices = false, has_texcoords = false, has_texnumber = false;
    for (const Property& p : element.properties) {
      has_indices |= p.role == Role::kVertexIndices;
      has_texcoords |= p.role == Role::kTexcoords;
      has_texnumber |= p.role == Role::kTexnumber;
    }
    REPHOTO_CHECK(has_indices || element.count == 0, "{}: face element has no vertex_indices list",
                  name_);
    const size_t reserve = ReserveCount(element);
    mesh_.faces.reserve(reserve);
    if (has_texcoords) mesh_.wedge_texcoords.reserve(3 * reserve);
    if (has_texnumber) mesh_.face_materials.reserve(reserve);
    std::vector<int64_t> polygon;
    std::vector<Eigen::Vector2f> corners;
    for (size_t f = 0; f < element.count; ++f) {
      polygon.clear();
      corners.clear();
      int texnumber = 0;
      for (const Property& p : element.properties) {
        if (p.role == Role::kVertexIndices) {
          const size_t n = ReadListCount(p, element, f);
          for (size_t k = 0; k < n; ++k) {
            const double index = ReadValue(p.type, element, f);
            REPHOTO_CHECK(index >= 0 && index < 4294967295.0,
                          "{}: face {}: vertex index {} out of range", name_, f, index);
            polygon.push_back(static_cast<int64_t>(index));
          }
        } else if (p.role == Role::kTexcoords) {
          const size_t n = ReadListCount(p, element, f);
          REPHOTO_CHECK(n % 2 == 0, "{}: face {}: texcoord list has odd length {}", name_, f, n);
          for (size_t k = 0; k < n / 2; ++k) {
            const float u = static_cast<float>(ReadValue(p.type, element, f));
            const float v = static_cast<float>(ReadValue(p.type, element, f));
            corners.emplace_back(u, v);
          }
        } else if (p.role == Role::kTexnumber) {
          texnumber = static_cast<int>(ReadValue(p.type, element, f));
        } else if (p.is_list) {
          SkipValues(p.type, ReadListCount(p, element, f), element, f);
        } else {
          SkipValues(p.type, 1, element, f);
        }
      }
      if (polygon.size() < 3) continue;  // points and edges are not surfaces
      if (has_texcoords) {
        REPHOTO_CHECK(corners.size() == polygon.size(),
                      "{}: face {}: {} texture coordinates for {} corners", name_, f,
                      corners.size(), polygon.size());
      }
      for (size_t k = 1; k + 1 < polygon.size(); ++k) {
        mesh_.faces.push_back({static_cast<uint32_t>(polygon[0]), static_cast<uint32_t>(polygon[k]),
                               static_cast<uint32_t>(polygon[k + 1])});
        if (has_texcoords) {
          mesh_.wedge_texcoords.push_back(corners[0]);
          mesh_.wedge_texcoords.push_back(corners[k]);
          mesh_.wedge_texcoords.push_back(corners[k + 1]);
        }
        if (has_texnumber) mesh_.face_materials.push_back(texnumber);
      }
    }
  }

  PlyInput input_;
  std::string name_;
  std::filesystem::path base_dir_;
  Format format_ = Format::kAscii;
  std::vector<Element> elements_;
  const Element* vertex_element_ = nullptr;
  uint64_t remaining_bytes_ = std::numeric_limits<uint64_t>::max();
  Mesh mesh_;
};

// Appends binary little-endian values or ASCII text, flushing to the stream in large blocks.
class PlyOutput {
 public:
  PlyOutput(std::ostream& stream, bool ascii) : stream_(stream), ascii_(ascii) {
    buffer_.reserve(kFlushSize + 4096);
  }
  ~PlyOutput() = default;

  void Text(std::string_view text) { buffer_.append(text); }
  template <typename T>
  void Value(T value) {
    if (ascii_) {
      if (!first_in_line_) buffer_.push_back(' ');
      if constexpr (std::is_same_v<T, uint8_t>) {
        fmt::format_to(std::back_inserter(buffer_), "{}", static_cast<int>(value));
      } else {
        fmt::format_to(std::back_inserter(buffer_), "{}", value);
      }
      first_in_line_ = false;
    } else {
      char bytes[sizeof(T)];
      std::memcpy(bytes, &value, sizeof(T));
      if constexpr (std::endian::native == std::endian::big) std::reverse(bytes, bytes + sizeof(T));
      buffer_.append(bytes, sizeof(T));
    }
  }
  void EndRecord() {
    if (ascii_) buffer_.push_back('\n');
    first_in_line_ = true;
    if (buffer_.size() >= kFlushSize) Flush();
  }
  void Flush() {
    stream_.write(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
    buffer_.clear();
  }

 private:
  static constexpr size_t kFlushSize = 1 << 20;
  std::ostream& stream_;
  bool ascii_;
  bool first_in_line_ = true;
  std::string buffer_;
};

uint8_t ToByte(float value) {
  if (!(value > 0)) return 0;  // also NaN
  if (value >= 1) return 255;
  return static_cast<uint8_t>(std::lround(value * 255.0f));
}

}  // namespace

void QuantizeColorsAsPly(std::vector<Eigen::Vector3f>* colors) {
  for (Eigen::Vector3f& color : *colors) {
    for (int k = 0; k < 3; ++k) {
      color[k] = static_cast<float>(ToByte(color[k]) * ColorScale(Type::kUInt8));
    }
  }
}

Mesh ReadPly(std::istream& stream, std::string_view name, const std::filesystem::path& base_dir) {
  PlyReader reader(stream, name, base_dir);
  return reader.Read();
}

Mesh ReadPly(const std::filesystem::path& path) {
  std::ifstream stream(path, std::ios::binary);
  REPHOTO_CHECK(stream.is_open(), "{}: cannot open file", path.string());
  return ReadPly(stream, path.string(), path.parent_path());
}

void WritePly(std::ostream& stream, const Mesh& mesh, PlyEncoding encoding) {
  const bool ascii = encoding == PlyEncoding::kAscii;
  const bool wedges = !mesh.wedge_texcoords.empty();
  const bool texnumbers = !mesh.face_materials.empty();
  PlyOutput out(stream, ascii);
  out.Text("ply\n");
  out.Text(ascii ? "format ascii 1.0\n" : "format binary_little_endian 1.0\n");
  out.Text("comment written by rephoto\n");
  for (const Material& material : mesh.materials) {
    if (!material.diffuse_texture.empty()) {
      out.Text(fmt::format("comment TextureFile {}\n", material.diffuse_texture.string()));
    }
  }
  out.Text(fmt::format("element vertex {}\n", mesh.positions.size()));
  out.Text("property float x\nproperty float y\nproperty float z\n");
  if (!mesh.normals.empty()) out.Text("property float nx\nproperty float ny\nproperty float nz\n");
  if (!mesh.colors.empty()) {
    out.Text("property uchar red\nproperty uchar green\nproperty uchar blue\n");
  }
  if (!mesh.vertex_texcoords.empty()) {
    out.Text("property float texture_u\nproperty float texture_v\n");
  }
  if (!mesh.radii.empty()) out.Text("property float radius\n");
  for (const VertexScalar& scalar : mesh.scalars) {
    out.Text(fmt::format("property float {}\n", scalar.name));
  }
  if (!mesh.faces.empty()) {
    out.Text(fmt::format("element face {}\n", mesh.faces.size()));
    out.Text("property list uchar int vertex_indices\n");
    if (wedges) out.Text("property list uchar float texcoord\n");
    if (texnumbers) out.Text("property int texnumber\n");
  }
  out.Text("end_header\n");
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    for (int k = 0; k < 3; ++k) out.Value(mesh.positions[i][k]);
    if (!mesh.normals.empty()) {
      for (int k = 0; k < 3; ++k) out.Value(mesh.normals[i][k]);
    }
    if (!mesh.colors.empty()) {
      for (int k = 0; k < 3; ++k) out.Value(ToByte(mesh.colors[i][k]));
    }
    if (!mesh.vertex_texcoords.empty()) {
      out.Value(mesh.vertex_texcoords[i].x());
      out.Value(mesh.vertex_texcoords[i].y());
    }
    if (!mesh.radii.empty()) out.Value(mesh.radii[i]);
    for (const VertexScalar& scalar : mesh.scalars) out.Value(scalar.values[i]);
    out.EndRecord();
  }
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    out.Value(uint8_t{3});
    for (uint32_t index : mesh.faces[f]) out.Value(static_cast<int32_t>(index));
    if (wedges) {
      out.Value(uint8_t{6});
      for (int k = 0; k < 3; ++k) {
        out.Value(mesh.wedge_texcoords[3 * f + k].x());
        out.Value(mesh.wedge_texcoords[3 * f + k].y());
      }
    }
    if (texnumbers) out.Value(static_cast<int32_t>(mesh.face_materials[f]));
    out.EndRecord();
  }
  out.Flush();
}

void WritePly(const std::filesystem::path& path, const Mesh& mesh, PlyEncoding encoding) {
  WriteFileAtomically(path, [&](const std::filesystem::path& temporary) {
    std::ofstream stream(temporary, std::ios::binary);
    REPHOTO_CHECK(stream.is_open(), "{}: cannot open for writing", path.string());
    WritePly(stream, mesh, encoding);
    stream.flush();
    REPHOTO_CHECK(stream.good(), "{}: write failed (disk full?)", path.string());
  });
}

}  // namespace rephoto::mesh
