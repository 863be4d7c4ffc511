#include "rephoto/splat/gaussians.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>
#include <string>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/ply_header.h"
#include "rephoto/io/ply_types.h"

namespace rephoto::splat {
namespace {

// PLY scalar types: io/ply_types.h.
using Type = io::PlyType;
inline int TypeSize(Type type) { return io::PlyTypeSize(type); }

// The header: io/ply_header.h, the project's one PLY header parser.
using Encoding = io::PlyEncoding;
using Property = io::PlyProperty;
using Element = io::PlyElement;
using Header = io::PlyHeader;
Header ReadHeader(std::istream& in, std::string_view name) { return io::ReadPlyHeader(in, name); }

template <typename T>
T LoadScalar(const char* p, bool swap) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  if (swap && sizeof(T) > 1) {
    auto bytes = std::bit_cast<std::array<char, sizeof(T)>>(value);
    std::reverse(bytes.begin(), bytes.end());
    value = std::bit_cast<T>(bytes);
  }
  return value;
}

double LoadValue(Type type, const char* p, bool swap) {
  switch (type) {
    case Type::kInt8:
      return LoadScalar<int8_t>(p, swap);
    case Type::kUInt8:
      return LoadScalar<uint8_t>(p, swap);
    case Type::kInt16:
      return LoadScalar<int16_t>(p, swap);
    case Type::kUInt16:
      return LoadScalar<uint16_t>(p, swap);
    case Type::kInt32:
      return LoadScalar<int32_t>(p, swap);
    case Type::kUInt32:
      return LoadScalar<uint32_t>(p, swap);
    case Type::kFloat32:
      return LoadScalar<float>(p, swap);
    case Type::kFloat64:
      return LoadScalar<double>(p, swap);
  }
  return 0;
}

// Reads the rest of the stream (the PLY body) into memory. The buffer grows with what is
// actually there, so a header's counts never drive an allocation.
std::string ReadBody(std::istream& in, std::string_view name) {
  std::string body;
  constexpr size_t kBlock = 1 << 22;
  while (in) {
    const size_t old_size = body.size();
    body.resize(old_size + kBlock);
    in.read(body.data() + old_size, kBlock);
    body.resize(old_size + static_cast<size_t>(in.gcount()));
  }
  REPHOTO_CHECK(!in.bad(), "{}: read error", name);
  return body;
}

// Walks the elements of a PLY body in file order. Each record's values are handed to a
// callback as doubles (list properties give NaN and are otherwise skipped), so no table of the
// whole element is ever built.
using RecordFn = std::function<void(uint64_t record, const double* values)>;

class BodyReader {
 public:
  BodyReader(const Header& header, std::string body, std::string_view name)
      : header_(header), body_(std::move(body)), name_(name) {}

  // Throws when the element that comes next cannot hold the records its header claims (call
  // before allocating anything for them).
  void CheckCount(size_t index) const {
    const Element& element = header_.elements[index];
    const size_t remaining = body_.size() - offset_;
    const size_t props = element.properties.size();
    uint64_t min_record = 1;  // bytes
    if (header_.encoding == Encoding::kAscii) {
      min_record = 2 * std::max<size_t>(props, 1);  // a digit and a separator per value
    } else if (!element.HasList()) {
      min_record = std::max<uint64_t>(element.RecordBytes(), 1);
    }
    REPHOTO_CHECK(element.count <= (remaining + 1) / min_record,
                  "{}: element '{}' claims {} records (at least {} bytes each) but the file "
                  "holds {} more bytes",
                  name_, element.name, element.count, min_record, remaining);
  }

  // Reads element `index` (elements must be visited in file order), calling fn for each record
  // (nullptr: skip the element).
  void Next(size_t index, const RecordFn* fn) {
    CheckCount(index);
    const Element& element = header_.elements[index];
    const size_t props = element.properties.size();
    std::vector<double> row(props);
    if (header_.encoding == Encoding::kAscii) {
      AsciiElement(element, fn, row);
      return;
    }
    const bool swap = (header_.encoding == Encoding::kBinaryBigEndian) !=
                      (std::endian::native == std::endian::big);
    if (!element.HasList()) {
      const uint64_t record = element.RecordBytes();
      if (fn != nullptr) {
        const char* p = body_.data() + offset_;
        for (uint64_t r = 0; r < element.count; ++r) {
          for (size_t k = 0; k < props; ++k) {
            row[k] = LoadValue(element.properties[k].type, p, swap);
            p += TypeSize(element.properties[k].type);
          }
          (*fn)(r, row.data());
        }
      }
      offset_ += element.count * record;
      return;
    }
    for (uint64_t r = 0; r < element.count; ++r) {
      for (size_t k = 0; k < props; ++k) {
        const Property& property = element.properties[k];
        if (property.is_list) {
          Need(TypeSize(property.count_type), element, r);
          const double n = LoadValue(property.count_type, body_.data() + offset_, swap);
          offset_ += TypeSize(property.count_type);
          REPHOTO_CHECK(n >= 0 && n <= 1e9, "{}: element '{}' record {}: bad list size", name_,
                        element.name, r);
          const uint64_t bytes = static_cast<uint64_t>(n) * TypeSize(property.type);
          Need(bytes, element, r);
          offset_ += bytes;
          row[k] = std::numeric_limits<double>::quiet_NaN();
        } else {
          Need(TypeSize(property.type), element, r);
          row[k] = LoadValue(property.type, body_.data() + offset_, swap);
          offset_ += TypeSize(property.type);
        }
      }
      if (fn != nullptr) (*fn)(r, row.data());
    }
  }

 private:
  void Need(uint64_t bytes, const Element& element, uint64_t record) const {
    REPHOTO_CHECK(bytes <= body_.size() - offset_,
                  "{}: element '{}' record {}: unexpected end of file (header promises {})", name_,
                  element.name, record, element.count);
  }

  std::string_view NextToken(const Element& element, uint64_t record) {
    while (offset_ < body_.size() && std::isspace(static_cast<unsigned char>(body_[offset_]))) {
      ++offset_;
    }
    const size_t begin = offset_;
    while (offset_ < body_.size() && !std::isspace(static_cast<unsigned char>(body_[offset_]))) {
      ++offset_;
    }
    REPHOTO_CHECK(offset_ > begin,
                  "{}: element '{}' record {}: unexpected end of file (header promises {})", name_,
                  element.name, record, element.count);
    return std::string_view(body_).substr(begin, offset_ - begin);
  }

  double ParseNumber(std::string_view token, const Element& element, uint64_t record) const {
    double value = 0;
    const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    REPHOTO_CHECK(ec == std::errc() && ptr == token.data() + token.size(),
                  "{}: element '{}' record {}: expected a number, got '{}'", name_, element.name,
                  record, token.substr(0, 32));
    return value;
  }

  void AsciiElement(const Element& element, const RecordFn* fn, std::vector<double>& row) {
    for (uint64_t r = 0; r < element.count; ++r) {
      for (size_t k = 0; k < element.properties.size(); ++k) {
        double value = ParseNumber(NextToken(element, r), element, r);
        if (element.properties[k].is_list) {
          REPHOTO_CHECK(value >= 0 && value <= 1e9, "{}: element '{}' record {}: bad list size",
                        name_, element.name, r);
          for (uint64_t i = 0; i < static_cast<uint64_t>(value); ++i) NextToken(element, r);
          value = std::numeric_limits<double>::quiet_NaN();
        }
        row[k] = value;
      }
      if (fn != nullptr) (*fn)(r, row.data());
    }
  }

  const Header& header_;
  std::string body_;
  std::string_view name_;
  size_t offset_ = 0;
};

float Sigmoid(double x) { return static_cast<float>(1.0 / (1.0 + std::exp(-x))); }

Eigen::Vector4f NormalizedQuaternion(Eigen::Vector4f q) {
  const float norm = q.norm();
  // torch.nn.functional.normalize: q / max(|q|, 1e-12); a zero quaternion stays zero, which
  // the covariance formula turns into the identity rotation.
  q /= std::max(norm, 1e-12f);
  if (norm < 1e-12f) q = Eigen::Vector4f(1, 0, 0, 0);
  return q;
}

// f_rest_<i> -> i, or -1.
int RestIndex(std::string_view name) {
  if (!name.starts_with("f_rest_")) return -1;
  const std::string_view digits = name.substr(7);
  int index = -1;
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), index);
  if (ec != std::errc() || ptr != digits.data() + digits.size() || index < 0) return -1;
  return index;
}

// Degree for n f_rest properties (channel-major, 3 * ((d + 1)^2 - 1)); nullopt if not 0..3.
std::optional<int> DegreeFromRestCount(int n) {
  for (int degree = 0; degree <= 3; ++degree) {
    if (n == 3 * ((degree + 1) * (degree + 1) - 1)) return degree;
  }
  return std::nullopt;
}

void CheckFinite(double value, std::string_view name, uint64_t record, std::string_view property) {
  REPHOTO_CHECK(std::isfinite(value), "{}: Gaussian {}: property '{}' is not finite", name, record,
                property);
}

// Finds the f_rest_* columns of `element`: column index per rest coefficient (channel-major).
std::vector<int> RestColumns(const Element& element, std::string_view name, int* degree) {
  int count = 0;
  int max_index = -1;
  for (const Property& p : element.properties) {
    const int index = RestIndex(p.name);
    if (index >= 0 && !p.is_list) {
      ++count;
      max_index = std::max(max_index, index);
    }
  }
  const std::optional<int> d = DegreeFromRestCount(count);
  REPHOTO_CHECK(d.has_value() && max_index == count - 1,
                "{}: {} f_rest_* properties (f_rest_0..f_rest_{}): unknown SH layout (expected "
                "0, 9, 24 or 45 consecutive ones for SH degree 0..3)",
                name, count, max_index);
  *degree = *d;
  std::vector<int> columns(static_cast<size_t>(count), -1);
  for (size_t k = 0; k < element.properties.size(); ++k) {
    const int index = RestIndex(element.properties[k].name);
    if (index >= 0 && !element.properties[k].is_list) {
      REPHOTO_CHECK(columns[index] < 0, "{}: property f_rest_{} appears twice", name, index);
      columns[index] = static_cast<int>(k);
    }
  }
  return columns;
}

int Require(const Element& element, std::string_view property, std::string_view name) {
  const int column = element.Find(property);
  REPHOTO_CHECK(column >= 0, "{}: element '{}' has no property '{}'", name, element.name, property);
  return column;
}

void Allocate(GaussianModel* model, uint64_t n) {
  model->positions.resize(n);
  model->scales.resize(n);
  model->rotations.resize(n);
  model->opacities.resize(n);
  model->sh.assign(n * model->ShCoefficients() * 3, 0.0f);
}

// Inria layout (and splatfacto's colour-only variant) from element `vertex_index`.
GaussianModel DecodeInria(const Header& header, BodyReader& reader, size_t vertex_index,
                          std::string_view name, GaussianFormat* format) {
  const Element& vertex = header.elements[vertex_index];
  const bool color_only = vertex.Find("f_dc_0") < 0 && vertex.Find("red") >= 0;
  if (format) *format = color_only ? GaussianFormat::kColorPly : GaussianFormat::kInriaPly;
  int degree = 0;
  std::vector<int> rest;
  if (!color_only) rest = RestColumns(vertex, name, &degree);
  const int columns_xyz[3] = {Require(vertex, "x", name), Require(vertex, "y", name),
                              Require(vertex, "z", name)};
  int columns_color[3];
  const char* const dc_names[3] = {"f_dc_0", "f_dc_1", "f_dc_2"};
  const char* const rgb_names[3] = {"red", "green", "blue"};
  for (int c = 0; c < 3; ++c) {
    columns_color[c] = Require(vertex, color_only ? rgb_names[c] : dc_names[c], name);
  }
  double color_scale = 1.0;
  if (color_only) {
    const Type type = vertex.properties[columns_color[0]].type;
    // Integer colours are scaled by the type's maximum (uchar 255, ushort 65535, ...).
    const bool is_signed = type == Type::kInt8 || type == Type::kInt16 || type == Type::kInt32;
    if (type != Type::kFloat32 && type != Type::kFloat64) {
      color_scale = 1.0 / (std::ldexp(1.0, 8 * TypeSize(type) - (is_signed ? 1 : 0)) - 1.0);
    }
  }
  const int column_opacity = Require(vertex, "opacity", name);
  int columns_scale[3], columns_rot[4];
  for (int i = 0; i < 3; ++i) columns_scale[i] = Require(vertex, fmt::format("scale_{}", i), name);
  for (int i = 0; i < 4; ++i) columns_rot[i] = Require(vertex, fmt::format("rot_{}", i), name);
  const int column_filter = vertex.Find("filter_3D");

  for (size_t e = 0; e < vertex_index; ++e) reader.Next(e, nullptr);
  reader.CheckCount(vertex_index);
  GaussianModel model;
  model.sh_degree = degree;
  const int k_count = model.ShCoefficients();
  Allocate(&model, vertex.count);
  const RecordFn decode = [&](uint64_t g, const double* row) {
    // Every property used must be finite; unused ones (normals, extras) may hold anything.
    auto get = [&](int column) {
      const double value = row[column];
      CheckFinite(value, name, g, vertex.properties[column].name);
      return value;
    };
    for (int i = 0; i < 3; ++i) model.positions[g][i] = static_cast<float>(get(columns_xyz[i]));
    float* sh = model.sh.data() + g * k_count * 3;
    for (int c = 0; c < 3; ++c) {
      sh[c] = color_only ? static_cast<float>((get(columns_color[c]) * color_scale - 0.5) / kShC0)
                         : static_cast<float>(get(columns_color[c]));
    }
    for (int k = 1; k < k_count; ++k) {
      for (int c = 0; c < 3; ++c) {
        sh[k * 3 + c] = static_cast<float>(get(rest[c * (k_count - 1) + (k - 1)]));
      }
    }
    Eigen::Vector3d scale;
    for (int i = 0; i < 3; ++i) scale[i] = std::exp(get(columns_scale[i]));
    double opacity = Sigmoid(get(column_opacity));
    if (column_filter >= 0) {
      // Mip-Splatting's 3D smoothing filter (get_scaling_with_3D_filter,
      // get_opacity_with_3D_filter).
      const double filter = get(column_filter);
      const Eigen::Vector3d squared = scale.cwiseProduct(scale);
      const Eigen::Vector3d filtered = squared.array() + filter * filter;
      opacity *= std::sqrt(squared.prod() / filtered.prod());
      scale = filtered.cwiseSqrt();
    }
    model.scales[g] = scale.cast<float>();
    model.opacities[g] = static_cast<float>(opacity);
    Eigen::Vector4f q;
    for (int i = 0; i < 4; ++i) q[i] = static_cast<float>(get(columns_rot[i]));
    model.rotations[g] = NormalizedQuaternion(q);
  };
  reader.Next(vertex_index, &decode);
  return model;
}

float Unorm(uint32_t value, int bits) {
  const uint32_t max = (1u << bits) - 1;
  return static_cast<float>(value & max) / static_cast<float>(max);
}
float Lerp(float a, float b, float t) { return a * (1 - t) + b * t; }

GaussianModel DecodeCompressed(const Header& header, BodyReader& reader, std::string_view name) {
  const Element* chunk = header.Find("chunk");
  const Element* vertex = header.Find("vertex");
  REPHOTO_CHECK(chunk != nullptr && vertex != nullptr && chunk < vertex,
                "{}: compressed PLY needs element 'chunk' before element 'vertex'", name);
  const uint64_t n = vertex->count;
  REPHOTO_CHECK(chunk->count >= (n + 255) / 256,
                "{}: {} chunks cannot hold {} Gaussians (256 per chunk)", name, chunk->count, n);
  const Element* sh_element = header.Find("sh");
  REPHOTO_CHECK(sh_element == nullptr || (sh_element->count == n && sh_element > vertex),
                "{}: element 'sh' must follow 'vertex' with one record per Gaussian", name);
  const char* const box_names[] = {
      "min_x",       "min_y",       "min_z",       "max_x",       "max_y",       "max_z",
      "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z",
      "min_r",       "min_g",       "min_b",       "max_r",       "max_g",       "max_b"};
  const bool has_color_range = chunk->Find("min_r") >= 0;
  int box_columns[18];
  for (int i = 0; i < 18; ++i) {
    box_columns[i] = (i < 12 || has_color_range) ? Require(*chunk, box_names[i], name) : -1;
  }
  const int packed[4] = {
      Require(*vertex, "packed_position", name), Require(*vertex, "packed_rotation", name),
      Require(*vertex, "packed_scale", name), Require(*vertex, "packed_color", name)};
  int degree = 0;
  std::vector<int> rest;
  if (sh_element != nullptr) rest = RestColumns(*sh_element, name, &degree);

  GaussianModel model;
  model.sh_degree = degree;
  const int k_count = model.ShCoefficients();
  std::vector<std::array<float, 18>> boxes;
  for (size_t e = 0; e < header.elements.size(); ++e) {
    const Element& element = header.elements[e];
    if (&element == chunk) {
      reader.CheckCount(e);
      boxes.resize(chunk->count);
      const RecordFn read_chunk = [&](uint64_t c, const double* row) {
        for (int i = 0; i < 18; ++i) {
          if (box_columns[i] < 0) {
            boxes[c][i] = i < 15 ? 0.0f : 1.0f;  // colours without a range lie in [0, 1]
            continue;
          }
          REPHOTO_CHECK(std::isfinite(row[box_columns[i]]), "{}: chunk {}: '{}' is not finite",
                        name, c, box_names[i]);
          boxes[c][i] = static_cast<float>(row[box_columns[i]]);
        }
      };
      reader.Next(e, &read_chunk);
    } else if (&element == vertex) {
      reader.CheckCount(e);
      Allocate(&model, n);
      const RecordFn read_vertex = [&](uint64_t g, const double* row) {
        const std::array<float, 18>& box = boxes[g / 256];
        uint32_t word[4];
        for (int i = 0; i < 4; ++i) {
          const double value = row[packed[i]];
          REPHOTO_CHECK(value >= 0 && value <= 4294967295.0 && value == std::floor(value),
                        "{}: Gaussian {}: property '{}' is not a 32-bit unsigned integer", name, g,
                        vertex->properties[packed[i]].name);
          word[i] = static_cast<uint32_t>(value);
        }
        const float t_pos[3] = {Unorm(word[0] >> 21, 11), Unorm(word[0] >> 11, 10),
                                Unorm(word[0], 11)};
        const float t_scale[3] = {Unorm(word[2] >> 21, 11), Unorm(word[2] >> 11, 10),
                                  Unorm(word[2], 11)};
        for (int i = 0; i < 3; ++i) {
          model.positions[g][i] = Lerp(box[i], box[3 + i], t_pos[i]);
          model.scales[g][i] = std::exp(Lerp(box[6 + i], box[9 + i], t_scale[i]));
        }
        // The three smaller components lie in [-1/sqrt2, 1/sqrt2].
        const float norm = std::sqrt(2.0f);
        const float others[3] = {(Unorm(word[1] >> 20, 10) - 0.5f) * norm,
                                 (Unorm(word[1] >> 10, 10) - 0.5f) * norm,
                                 (Unorm(word[1], 10) - 0.5f) * norm};
        const float largest_value = std::sqrt(std::max(
            0.0f, 1.0f - (others[0] * others[0] + others[1] * others[1] + others[2] * others[2])));
        const int largest = static_cast<int>(word[1] >> 30);
        Eigen::Vector4f q;
        for (int i = 0, o = 0; i < 4; ++i) q[i] = (i == largest) ? largest_value : others[o++];
        model.rotations[g] = NormalizedQuaternion(q);
        float* sh = model.sh.data() + g * k_count * 3;
        for (int ch = 0; ch < 3; ++ch) {
          const float color = Lerp(box[12 + ch], box[15 + ch], Unorm(word[3] >> (24 - 8 * ch), 8));
          sh[ch] = (color - 0.5f) / kShC0;
        }
        model.opacities[g] = Unorm(word[3], 8);
      };
      reader.Next(e, &read_vertex);
    } else if (&element == sh_element) {
      const size_t sh_count = static_cast<size_t>(k_count);
      const RecordFn read_sh = [&](uint64_t g, const double* row) {
        float* sh = model.sh.data() + g * sh_count * 3;
        for (size_t k = 1; k < sh_count; ++k) {
          for (size_t ch = 0; ch < 3; ++ch) {
            const double value = row[rest[ch * (sh_count - 1) + (k - 1)]];
            REPHOTO_CHECK(value >= 0 && value <= 255, "{}: Gaussian {}: SH byte out of range", name,
                          g);
            sh[k * 3 + ch] = static_cast<float>(((value + 0.5) / 256.0 - 0.5) * 8.0);
          }
        }
      };
      reader.Next(e, &read_sh);
    } else {
      reader.Next(e, nullptr);
    }
  }
  return model;
}

bool IsCompressed(const Element& vertex) {
  return vertex.Find("packed_position") >= 0 && vertex.Find("packed_rotation") >= 0;
}
bool IsGaussianVertex(const Element& vertex) {
  return IsCompressed(vertex) ||
         (vertex.Find("opacity") >= 0 && vertex.Find("scale_0") >= 0 && vertex.Find("rot_0") >= 0);
}

GaussianModel ReadPlyGaussians(std::istream& in, std::string_view name, GaussianFormat* format) {
  const Header header = ReadHeader(in, name);
  const Element* vertex = header.Find("vertex");
  REPHOTO_CHECK(vertex != nullptr, "{}: PLY has no 'vertex' element", name);
  REPHOTO_CHECK(IsGaussianVertex(*vertex),
                "{}: PLY vertices have no Gaussian properties (opacity, scale_0..2, rot_0..3)",
                name);
  BodyReader reader(header, ReadBody(in, name), name);
  if (IsCompressed(*vertex)) {
    if (format) *format = GaussianFormat::kCompressedPly;
    return DecodeCompressed(header, reader, name);
  }
  const size_t vertex_index = static_cast<size_t>(vertex - header.elements.data());
  return DecodeInria(header, reader, vertex_index, name, format);
}

GaussianModel ReadSplatGaussians(std::istream& in, std::string_view name) {
  const std::string body = ReadBody(in, name);
  REPHOTO_CHECK(body.size() % 32 == 0,
                "{}: .splat file of {} bytes is not a whole number of 32-byte Gaussians", name,
                body.size());
  const size_t n = body.size() / 32;
  GaussianModel model;
  model.sh_degree = 0;
  model.positions.resize(n);
  model.scales.resize(n);
  model.rotations.resize(n);
  model.opacities.resize(n);
  model.sh.resize(n * 3);
  const bool swap = std::endian::native == std::endian::big;
  for (size_t g = 0; g < n; ++g) {
    const char* p = body.data() + g * 32;
    for (int i = 0; i < 3; ++i) {
      model.positions[g][i] = LoadScalar<float>(p + 4 * i, swap);
      model.scales[g][i] = LoadScalar<float>(p + 12 + 4 * i, swap);
      CheckFinite(model.positions[g][i], name, g, "position");
      CheckFinite(model.scales[g][i], name, g, "scale");
      REPHOTO_CHECK(model.scales[g][i] >= 0, "{}: Gaussian {}: negative scale", name, g);
    }
    const auto* bytes = reinterpret_cast<const uint8_t*>(p + 24);
    for (int c = 0; c < 3; ++c) model.sh[g * 3 + c] = (bytes[c] / 255.0f - 0.5f) / kShC0;
    model.opacities[g] = bytes[3] / 255.0f;
    Eigen::Vector4f q;
    for (int i = 0; i < 4; ++i) q[i] = (static_cast<float>(bytes[4 + i]) - 128.0f) / 128.0f;
    model.rotations[g] = NormalizedQuaternion(q);
  }
  return model;
}

}  // namespace

void GaussianModel::Validate(std::string_view context) const {
  const size_t n = positions.size();
  REPHOTO_CHECK(sh_degree >= 0 && sh_degree <= 3, "{}: SH degree {} is not in 0..3", context,
                sh_degree);
  REPHOTO_CHECK(scales.size() == n && rotations.size() == n && opacities.size() == n &&
                    sh.size() == n * ShCoefficients() * 3,
                "{}: Gaussian arrays disagree in size", context);
  for (size_t g = 0; g < n; ++g) {
    REPHOTO_CHECK(positions[g].allFinite() && scales[g].allFinite() && rotations[g].allFinite() &&
                      std::isfinite(opacities[g]),
                  "{}: Gaussian {} is not finite", context, g);
    REPHOTO_CHECK(scales[g].minCoeff() >= 0, "{}: Gaussian {} has a negative scale", context, g);
    REPHOTO_CHECK(opacities[g] >= 0 && opacities[g] <= 1,
                  "{}: Gaussian {} has opacity {} outside [0, 1]", context, g, opacities[g]);
  }
  for (size_t i = 0; i < sh.size(); ++i) {
    REPHOTO_CHECK(std::isfinite(sh[i]), "{}: Gaussian {}: SH coefficient not finite", context,
                  i / (ShCoefficients() * 3));
  }
}

std::string_view GaussianFormatName(GaussianFormat format) {
  switch (format) {
    case GaussianFormat::kInriaPly:
      return "Inria PLY";
    case GaussianFormat::kColorPly:
      return "colour PLY (splatfacto)";
    case GaussianFormat::kCompressedPly:
      return "compressed PLY (SuperSplat)";
    case GaussianFormat::kSplat:
      return ".splat";
  }
  return "unknown";
}

GaussianModel ReadGaussians(std::istream& stream, std::string_view name, bool splat_format,
                            GaussianFormat* format) {
  GaussianModel model;
  if (splat_format) {
    if (format) *format = GaussianFormat::kSplat;
    model = ReadSplatGaussians(stream, name);
  } else {
    model = ReadPlyGaussians(stream, name, format);
  }
  REPHOTO_CHECK(model.size() > 0, "{}: no Gaussians", name);
  model.Validate(name);
  return model;
}

GaussianModel ReadGaussians(const std::filesystem::path& path, GaussianFormat* format) {
  std::ifstream in(path, std::ios::binary);
  REPHOTO_CHECK(in.good(), "{}: cannot open", path.string());
  return ReadGaussians(in, path.string(), path.extension() == ".splat", format);
}

bool IsGaussianPlyHeader(std::istream& stream) {
  try {
    const Header header = ReadHeader(stream, "");
    const Element* vertex = header.Find("vertex");
    return vertex != nullptr && IsGaussianVertex(*vertex);
  } catch (const Error&) {
    return false;
  }
}

bool IsGaussianFile(const std::filesystem::path& path) {
  if (path.extension() == ".splat") return true;
  std::ifstream in(path, std::ios::binary);
  if (!in.good()) return false;
  return IsGaussianPlyHeader(in);
}

void WriteInriaPly(std::ostream& out, const GaussianModel& model) {
  const int k_count = model.ShCoefficients();
  std::string header = fmt::format(
      "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float "
      "y\nproperty float z\nproperty float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n",
      model.size());
  for (int i = 0; i < 3 * (k_count - 1); ++i)
    header += fmt::format("property float f_rest_{}\n", i);
  header +=
      "property float opacity\nproperty float scale_0\nproperty float scale_1\nproperty float "
      "scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float "
      "rot_3\nend_header\n";
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  std::vector<float> record;
  for (size_t g = 0; g < model.size(); ++g) {
    record.clear();
    for (int i = 0; i < 3; ++i) record.push_back(model.positions[g][i]);
    const float* sh = model.sh.data() + g * k_count * 3;
    for (int c = 0; c < 3; ++c) record.push_back(sh[c]);
    for (int c = 0; c < 3; ++c) {
      for (int k = 1; k < k_count; ++k) record.push_back(sh[k * 3 + c]);
    }
    const double o = std::clamp<double>(model.opacities[g], 1e-7, 1 - 1e-7);
    record.push_back(static_cast<float>(std::log(o / (1 - o))));
    for (int i = 0; i < 3; ++i) record.push_back(std::log(model.scales[g][i]));
    for (int i = 0; i < 4; ++i) record.push_back(model.rotations[g][i]);
    static_assert(std::endian::native == std::endian::little, "writer assumes little endian");
    out.write(reinterpret_cast<const char*>(record.data()),
              static_cast<std::streamsize>(record.size() * sizeof(float)));
  }
  REPHOTO_CHECK(out.good(), "cannot write the Gaussian PLY");
}

void WriteInriaPly(const std::filesystem::path& path, const GaussianModel& model) {
  WriteFileAtomically(path, [&](const std::filesystem::path& temporary) {
    std::ofstream out(temporary, std::ios::binary);
    REPHOTO_CHECK(out.good(), "{}: cannot write", path.string());
    WriteInriaPly(out, model);
    out.close();
    REPHOTO_CHECK(out.good(), "{}: cannot write", path.string());
  });
}

}  // namespace rephoto::splat
