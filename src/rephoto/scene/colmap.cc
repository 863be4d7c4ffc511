#include "rephoto/scene/colmap.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <climits>
#include <cmath>
#include <cstring>
#include <fstream>
#include <set>
#include <unordered_map>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/reader_util.h"

namespace rephoto::scene {
namespace {

namespace fs = std::filesystem;

// COLMAP writes unit quaternions with 17 digits; derived files print fewer. A norm further
// than this from 1 is a corrupt record, not rounding.
constexpr double kQuaternionNormTolerance = 1e-4;
// Bounds on what a count in a binary header may reserve up front, so a corrupt count cannot
// allocate gigabytes before truncation is detected.
constexpr uint64_t kMaxReserve = 1 << 10;
constexpr size_t kMaxNameLength = 1 << 16;

camera::Pose PoseFromQuaternion(const Eigen::Vector4d& q, const Eigen::Vector3d& translation,
                                std::string_view where) {
  REPHOTO_CHECK(q.allFinite() && translation.allFinite(), "{}: pose has a NaN or infinite value",
                where);
  const double norm = q.norm();
  REPHOTO_CHECK(std::abs(norm - 1) <= kQuaternionNormTolerance,
                "{}: quaternion ({}, {}, {}, {}) has norm {:.9g}, expected 1", where, q[0], q[1],
                q[2], q[3], norm);
  camera::Pose pose = camera::Pose::FromQuaternion(q[0], q[1], q[2], q[3], translation);
  pose.Validate(where);
  return pose;
}

// ---------------------------------------------------------------------------------------------
// Binary helpers (little-endian, as COLMAP's ReadBinaryLittleEndian / WriteBinaryLittleEndian).

template <typename T>
T FromLittleEndian(const unsigned char* bytes) {
  static_assert(std::is_trivially_copyable_v<T>);
  unsigned char ordered[sizeof(T)];
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(ordered, bytes, sizeof(T));
  } else {
    for (size_t i = 0; i < sizeof(T); ++i) ordered[i] = bytes[sizeof(T) - 1 - i];
  }
  T value;
  std::memcpy(&value, ordered, sizeof(T));
  return value;
}

template <typename T>
void WriteLittleEndian(std::ostream& out, T value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if constexpr (std::endian::native != std::endian::little) {
    std::reverse(bytes, bytes + sizeof(T));
  }
  out.write(reinterpret_cast<const char*>(bytes), sizeof(T));
}

class BinaryReader {
 public:
  BinaryReader(std::istream& in, std::string_view name) : in_(in), name_(name) {}

  void BeginRecord(uint64_t index, uint64_t count) {
    record_ = index;
    count_ = count;
    record_offset_ = offset_;
  }

  // "<name>: record <i> of <n> (byte <offset>)", or "<name>: header" before the first record.
  std::string Where() const {
    if (!record_) {
      return fmt::format("{}: header", name_);
    }
    return fmt::format("{}: record {} of {} (byte {})", name_, *record_, count_, record_offset_);
  }

  template <typename T>
  T Read(std::string_view what) {
    unsigned char bytes[sizeof(T)];
    in_.read(reinterpret_cast<char*>(bytes), sizeof(T));
    if (in_.gcount() != static_cast<std::streamsize>(sizeof(T))) {
      REPHOTO_CHECK(!in_.bad(), "{}: read error", Where());
      ThrowError("{}: file is truncated (unexpected end while reading {})", Where(), what);
    }
    offset_ += sizeof(T);
    return FromLittleEndian<T>(bytes);
  }

  double ReadFinite(std::string_view what) {
    const double value = Read<double>(what);
    REPHOTO_CHECK(std::isfinite(value), "{}: {} is not finite", Where(), what);
    return value;
  }

  std::string ReadNullTerminated(std::string_view what) {
    std::string text;
    while (true) {
      const char c = Read<char>(what);
      if (c == '\0') {
        return text;
      }
      text.push_back(c);
      REPHOTO_CHECK(text.size() <= kMaxNameLength, "{}: {} longer than {} bytes (corrupt file?)",
                    Where(), what, kMaxNameLength);
    }
  }

 private:
  std::istream& in_;
  std::string name_;
  uint64_t offset_ = 0;
  uint64_t record_offset_ = 0;
  uint64_t count_ = 0;
  std::optional<uint64_t> record_;
};

camera::Camera MakeValidatedCamera(camera::CameraModel model, long long width, long long height,
                                   std::vector<double> params, std::string_view where) {
  REPHOTO_CHECK(width > 0 && height > 0 && width <= INT_MAX && height <= INT_MAX,
                "{}: image size {}x{} is not a positive int", where, width, height);
  camera::Camera camera;
  camera.model = model;
  camera.width = static_cast<int>(width);
  camera.height = static_cast<int>(height);
  camera.params = std::move(params);
  camera.Validate(where);
  return camera;
}

std::ifstream OpenForReading(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  REPHOTO_CHECK(in.is_open(), "{}: cannot open file", path.string());
  return in;
}

template <typename Write>
void WriteModelFile(const fs::path& path, Write write) {
  WriteFileAtomically(path, [&](const fs::path& temporary) {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    REPHOTO_CHECK(out.is_open(), "{}: cannot create file", temporary.string());
    write(out);
    out.flush();
    REPHOTO_CHECK(out.good(), "{}: write failed", temporary.string());
  });
}

// Lines of a COLMAP text file with "<name>:<line>" positions. Unlike LineReader it sets no
// length bound: a POINTS2D line holds every keypoint of an image, which with COLMAP's larger
// feature settings is megabytes of text.
class TextLines {
 public:
  TextLines(std::istream& in, std::string_view name) : in_(in), name_(name) {}

  // The next line ('\r' stripped); false at the end of the stream.
  bool Next(std::string& line) {
    if (!std::getline(in_, line)) {
      REPHOTO_CHECK(!in_.bad(), "{}: read error after line {}", name_, line_number_);
      return false;
    }
    ++line_number_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }

  // The next line that is neither blank nor a '#' comment (COLMAP trims, then skips these).
  bool NextContent(std::string& line) {
    while (Next(line)) {
      const size_t first = line.find_first_not_of(" \t\r\n\v\f");
      if (first != std::string::npos && line[first] != '#') return true;
    }
    return false;
  }

  std::string Where() const { return fmt::format("{}:{}", name_, line_number_); }

 private:
  std::istream& in_;
  std::string name_;
  int line_number_ = 0;
};

bool IsAllDigits(const std::string& text) {
  return !text.empty() &&
         std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Text readers.

std::map<uint32_t, camera::Camera> ReadColmapCamerasText(std::istream& in, std::string_view name) {
  TextLines reader(in, name);
  std::map<uint32_t, camera::Camera> cameras;
  std::map<uint32_t, std::string> defined_at;
  std::string line;
  while (reader.NextContent(line)) {
    const std::string where = reader.Where();
    const std::vector<std::string_view> tokens = SplitTokens(line);
    RequireTokenCount(tokens, 4, where, "CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]", true);
    const auto id =
        static_cast<uint32_t>(ParseInteger(tokens[0], where, "CAMERA_ID", 0, UINT32_MAX));
    const std::optional<camera::CameraModel> model = camera::ParseCameraModel(tokens[1]);
    REPHOTO_CHECK(model.has_value(), "{}: unknown camera model '{}'", where, tokens[1]);
    const long long width = ParseInteger(tokens[2], where, "WIDTH", 1, INT_MAX);
    const long long height = ParseInteger(tokens[3], where, "HEIGHT", 1, INT_MAX);
    std::vector<double> params;
    for (size_t i = 4; i < tokens.size(); ++i) {
      params.push_back(ParseFiniteDouble(tokens[i], where, fmt::format("PARAMS[{}]", i - 4)));
    }
    auto [it, inserted] = defined_at.emplace(id, where);
    REPHOTO_CHECK(inserted, "{}: camera id {} defined twice (first at {})", where, id, it->second);
    cameras.emplace(id, MakeValidatedCamera(*model, width, height, std::move(params), where));
  }
  return cameras;
}

std::vector<ColmapImage> ReadColmapImagesText(std::istream& in, std::string_view name) {
  TextLines reader(in, name);
  std::vector<ColmapImage> images;
  std::string line;
  while (reader.NextContent(line)) {
    ColmapImage image;
    image.where = reader.Where();
    const std::string& where = image.where;
    const std::vector<std::string_view> tokens = SplitTokens(line);
    RequireTokenCount(tokens, 10, where, "IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", true);
    image.image_id =
        static_cast<uint32_t>(ParseInteger(tokens[0], where, "IMAGE_ID", 0, UINT32_MAX));
    for (int i = 0; i < 4; ++i) {
      image.quaternion[i] = ParseFiniteDouble(tokens[1 + i], where, "quaternion");
    }
    for (int i = 0; i < 3; ++i) {
      image.translation[i] = ParseFiniteDouble(tokens[5 + i], where, "translation");
    }
    image.camera_id =
        static_cast<uint32_t>(ParseInteger(tokens[8], where, "CAMERA_ID", 0, UINT32_MAX));
    // The name is the rest of the line (trailing blanks dropped).
    std::string_view rest(line);
    rest.remove_prefix(static_cast<size_t>(tokens[9].data() - line.data()));
    image.name = std::string(rest.substr(0, rest.find_last_not_of(" \t\r") + 1));
    PoseFromQuaternion(image.quaternion, image.translation, where);

    // POINTS2D: always the next line, possibly empty; a missing last line counts as empty.
    std::string points_line;
    if (reader.Next(points_line)) {
      const std::string points_where = reader.Where();
      const std::vector<std::string_view> values = SplitTokens(points_line);
      REPHOTO_CHECK(values.size() % 3 == 0,
                    "{}: POINTS2D of image {} has {} values, not a multiple of 3 (X Y POINT3D_ID)",
                    points_where, image.image_id, values.size());
      image.points2d.reserve(values.size() / 3);
      image.point3d_ids.reserve(values.size() / 3);
      for (size_t i = 0; i < values.size(); i += 3) {
        image.points2d.emplace_back(ParseFiniteDouble(values[i], points_where, "POINTS2D X"),
                                    ParseFiniteDouble(values[i + 1], points_where, "POINTS2D Y"));
        const long long id = ParseInteger(values[i + 2], points_where, "POINT3D_ID", -1, LLONG_MAX);
        image.point3d_ids.push_back(id < 0 ? ColmapImage::kNoPoint3D : static_cast<uint64_t>(id));
      }
    }
    images.push_back(std::move(image));
  }
  return images;
}

std::vector<ColmapPoint3D> ReadColmapPoints3DText(std::istream& in, std::string_view name) {
  TextLines reader(in, name);
  std::vector<ColmapPoint3D> points;
  std::string line;
  while (reader.NextContent(line)) {
    ColmapPoint3D point;
    point.where = reader.Where();
    const std::string& where = point.where;
    const std::vector<std::string_view> tokens = SplitTokens(line);
    RequireTokenCount(tokens, 8, where, "POINT3D_ID X Y Z R G B ERROR TRACK[]", true);
    REPHOTO_CHECK((tokens.size() - 8) % 2 == 0,
                  "{}: TRACK has {} values, not (IMAGE_ID, POINT2D_IDX) pairs", where,
                  tokens.size() - 8);
    point.point3d_id =
        static_cast<uint64_t>(ParseInteger(tokens[0], where, "POINT3D_ID", 0, LLONG_MAX));
    for (int i = 0; i < 3; ++i) {
      point.position[i] = ParseFiniteDouble(tokens[1 + i], where, "XYZ");
      point.color[i] = static_cast<uint8_t>(ParseInteger(tokens[4 + i], where, "RGB", 0, 255));
    }
    point.error = ParseFiniteDouble(tokens[7], where, "ERROR");
    point.track.reserve((tokens.size() - 8) / 2);
    for (size_t i = 8; i < tokens.size(); i += 2) {
      point.track.emplace_back(
          static_cast<uint32_t>(ParseInteger(tokens[i], where, "IMAGE_ID", 0, UINT32_MAX)),
          static_cast<uint32_t>(ParseInteger(tokens[i + 1], where, "POINT2D_IDX", 0, UINT32_MAX)));
    }
    points.push_back(std::move(point));
  }
  return points;
}

// ---------------------------------------------------------------------------------------------
// Binary readers.

std::map<uint32_t, camera::Camera> ReadColmapCamerasBinary(std::istream& in,
                                                           std::string_view name) {
  BinaryReader reader(in, name);
  const auto count = reader.Read<uint64_t>("the number of cameras");
  std::map<uint32_t, camera::Camera> cameras;
  for (uint64_t i = 0; i < count; ++i) {
    reader.BeginRecord(i, count);
    const auto id = reader.Read<uint32_t>("camera_id");
    const auto model_id = reader.Read<int32_t>("model_id");
    const std::optional<camera::CameraModel> model = camera::CameraModelFromId(model_id);
    REPHOTO_CHECK(model.has_value(), "{}: camera {}: unknown camera model id {}", reader.Where(),
                  id, model_id);
    const auto width = reader.Read<uint64_t>("width");
    const auto height = reader.Read<uint64_t>("height");
    std::vector<double> params(camera::CameraModelParamCount(*model));
    for (double& param : params) {
      param = reader.Read<double>("params");
    }
    const std::string where = fmt::format("{} (camera {})", reader.Where(), id);
    REPHOTO_CHECK(width <= INT_MAX && height <= INT_MAX, "{}: image size {}x{} is too large", where,
                  width, height);
    REPHOTO_CHECK(!cameras.contains(id), "{}: camera id {} defined twice", where, id);
    cameras.emplace(id,
                    MakeValidatedCamera(*model, static_cast<long long>(width),
                                        static_cast<long long>(height), std::move(params), where));
  }
  return cameras;
}

std::vector<ColmapImage> ReadColmapImagesBinary(std::istream& in, std::string_view name) {
  BinaryReader reader(in, name);
  const auto count = reader.Read<uint64_t>("the number of images");
  std::vector<ColmapImage> images;
  images.reserve(std::min(count, kMaxReserve));
  for (uint64_t i = 0; i < count; ++i) {
    reader.BeginRecord(i, count);
    ColmapImage image;
    image.where = reader.Where();
    image.image_id = reader.Read<uint32_t>("image_id");
    for (int k = 0; k < 4; ++k) {
      image.quaternion[k] = reader.Read<double>("quaternion");
    }
    for (int k = 0; k < 3; ++k) {
      image.translation[k] = reader.Read<double>("translation");
    }
    image.camera_id = reader.Read<uint32_t>("camera_id");
    image.name = reader.ReadNullTerminated("name");
    const auto num_points = reader.Read<uint64_t>("the number of 2D points");
    image.points2d.reserve(std::min(num_points, kMaxReserve));
    image.point3d_ids.reserve(std::min(num_points, kMaxReserve));
    for (uint64_t k = 0; k < num_points; ++k) {
      const double x = reader.ReadFinite("a 2D point x");
      const double y = reader.ReadFinite("a 2D point y");
      image.points2d.emplace_back(x, y);
      image.point3d_ids.push_back(reader.Read<uint64_t>("a 2D point's point3D_id"));
    }
    image.where = fmt::format("{} (image {} '{}')", image.where, image.image_id, image.name);
    PoseFromQuaternion(image.quaternion, image.translation, image.where);
    images.push_back(std::move(image));
  }
  return images;
}

std::vector<ColmapPoint3D> ReadColmapPoints3DBinary(std::istream& in, std::string_view name) {
  BinaryReader reader(in, name);
  const auto count = reader.Read<uint64_t>("the number of points");
  std::vector<ColmapPoint3D> points;
  points.reserve(std::min(count, kMaxReserve));
  for (uint64_t i = 0; i < count; ++i) {
    reader.BeginRecord(i, count);
    ColmapPoint3D point;
    point.point3d_id = reader.Read<uint64_t>("point3D_id");
    point.where = fmt::format("{} (point {})", reader.Where(), point.point3d_id);
    for (int k = 0; k < 3; ++k) {
      point.position[k] = reader.Read<double>("xyz");
    }
    REPHOTO_CHECK(point.position.allFinite(), "{}: position is not finite", point.where);
    for (int k = 0; k < 3; ++k) {
      point.color[k] = reader.Read<uint8_t>("rgb");
    }
    point.error = reader.ReadFinite("error");
    const auto track_length = reader.Read<uint64_t>("track_length");
    point.track.reserve(std::min(track_length, kMaxReserve));
    for (uint64_t k = 0; k < track_length; ++k) {
      const auto image_id = reader.Read<uint32_t>("a track image_id");
      const auto point2d_idx = reader.Read<uint32_t>("a track point2D_idx");
      point.track.emplace_back(image_id, point2d_idx);
    }
    points.push_back(std::move(point));
  }
  return points;
}

// ---------------------------------------------------------------------------------------------
// Writers.

void WriteColmapCamerasText(std::ostream& out, const std::map<uint32_t, camera::Camera>& cameras) {
  out << "# Camera list with one line of data per camera:\n"
      << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      << "# Number of cameras: " << cameras.size() << '\n';
  for (const auto& [id, camera] : cameras) {
    std::string line = fmt::format("{} {} {} {}", id, camera::CameraModelName(camera.model),
                                   camera.width, camera.height);
    for (const double param : camera.params) {
      line += fmt::format(" {}", param);
    }
    out << line << '\n';
  }
}

void WriteColmapImagesText(std::ostream& out, const std::vector<ColmapImage>& images) {
  size_t observations = 0;
  for (const ColmapImage& image : images) {
    observations += std::count_if(image.point3d_ids.begin(), image.point3d_ids.end(),
                                  [](uint64_t id) { return id != ColmapImage::kNoPoint3D; });
  }
  out << "# Image list with two lines of data per image:\n"
      << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      << "# Number of images: " << images.size() << ", mean observations per image: "
      << (images.empty() ? 0.0 : static_cast<double>(observations) / images.size()) << '\n';
  std::string line;
  for (const ColmapImage& image : images) {
    const Eigen::Vector4d& q = image.quaternion;
    const Eigen::Vector3d& t = image.translation;
    out << fmt::format("{} {} {} {} {} {} {} {} {} {}\n", image.image_id, q[0], q[1], q[2], q[3],
                       t[0], t[1], t[2], image.camera_id, image.name);
    line.clear();
    for (size_t i = 0; i < image.points2d.size(); ++i) {
      if (i > 0) line += ' ';
      const uint64_t id = image.point3d_ids[i];
      if (id == ColmapImage::kNoPoint3D) {
        line += fmt::format("{} {} -1", image.points2d[i].x(), image.points2d[i].y());
      } else {
        line += fmt::format("{} {} {}", image.points2d[i].x(), image.points2d[i].y(), id);
      }
    }
    out << line << '\n';
  }
}

void WriteColmapPoints3DText(std::ostream& out, const std::vector<ColmapPoint3D>& points) {
  size_t track_elements = 0;
  for (const ColmapPoint3D& point : points) track_elements += point.track.size();
  out << "# 3D point list with one line of data per point:\n"
      << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
      << "# Number of points: " << points.size() << ", mean track length: "
      << (points.empty() ? 0.0 : static_cast<double>(track_elements) / points.size()) << '\n';
  std::string line;
  for (const ColmapPoint3D& point : points) {
    line = fmt::format("{} {} {} {} {} {} {} {}", point.point3d_id, point.position.x(),
                       point.position.y(), point.position.z(), int{point.color[0]},
                       int{point.color[1]}, int{point.color[2]}, point.error);
    for (const auto& [image_id, point2d_idx] : point.track) {
      line += fmt::format(" {} {}", image_id, point2d_idx);
    }
    out << line << '\n';
  }
}

void WriteColmapCamerasBinary(std::ostream& out,
                              const std::map<uint32_t, camera::Camera>& cameras) {
  WriteLittleEndian<uint64_t>(out, cameras.size());
  for (const auto& [id, camera] : cameras) {
    REPHOTO_CHECK(
        static_cast<int>(camera.params.size()) == camera::CameraModelParamCount(camera.model),
        "camera {}: {} parameters for a {} camera", id, camera.params.size(),
        camera::CameraModelName(camera.model));
    WriteLittleEndian<uint32_t>(out, id);
    WriteLittleEndian<int32_t>(out, static_cast<int32_t>(camera.model));
    WriteLittleEndian<uint64_t>(out, static_cast<uint64_t>(camera.width));
    WriteLittleEndian<uint64_t>(out, static_cast<uint64_t>(camera.height));
    for (const double param : camera.params) {
      WriteLittleEndian<double>(out, param);
    }
  }
}

void WriteColmapImagesBinary(std::ostream& out, const std::vector<ColmapImage>& images) {
  WriteLittleEndian<uint64_t>(out, images.size());
  for (const ColmapImage& image : images) {
    REPHOTO_CHECK(image.points2d.size() == image.point3d_ids.size(),
                  "image {}: {} 2D points but {} point3D ids", image.image_id,
                  image.points2d.size(), image.point3d_ids.size());
    REPHOTO_CHECK(image.name.find('\0') == std::string::npos, "image {}: name contains a NUL",
                  image.image_id);
    WriteLittleEndian<uint32_t>(out, image.image_id);
    for (int k = 0; k < 4; ++k) WriteLittleEndian<double>(out, image.quaternion[k]);
    for (int k = 0; k < 3; ++k) WriteLittleEndian<double>(out, image.translation[k]);
    WriteLittleEndian<uint32_t>(out, image.camera_id);
    out.write(image.name.c_str(), static_cast<std::streamsize>(image.name.size() + 1));
    WriteLittleEndian<uint64_t>(out, image.points2d.size());
    for (size_t i = 0; i < image.points2d.size(); ++i) {
      WriteLittleEndian<double>(out, image.points2d[i].x());
      WriteLittleEndian<double>(out, image.points2d[i].y());
      WriteLittleEndian<uint64_t>(out, image.point3d_ids[i]);
    }
  }
}

void WriteColmapPoints3DBinary(std::ostream& out, const std::vector<ColmapPoint3D>& points) {
  WriteLittleEndian<uint64_t>(out, points.size());
  for (const ColmapPoint3D& point : points) {
    WriteLittleEndian<uint64_t>(out, point.point3d_id);
    for (int k = 0; k < 3; ++k) WriteLittleEndian<double>(out, point.position[k]);
    for (int k = 0; k < 3; ++k) WriteLittleEndian<uint8_t>(out, point.color[k]);
    WriteLittleEndian<double>(out, point.error);
    WriteLittleEndian<uint64_t>(out, point.track.size());
    for (const auto& [image_id, point2d_idx] : point.track) {
      WriteLittleEndian<uint32_t>(out, image_id);
      WriteLittleEndian<uint32_t>(out, point2d_idx);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Folders and scenes.

std::optional<ColmapFormat> DetectColmapFormat(const fs::path& model_dir) {
  const auto all_exist = [&](std::string_view extension) {
    for (const char* stem : {"cameras", "images", "points3D"}) {
      if (!fs::is_regular_file(model_dir / fmt::format("{}{}", stem, extension))) return false;
    }
    return true;
  };
  if (all_exist(".bin")) return ColmapFormat::kBinary;
  if (all_exist(".txt")) return ColmapFormat::kText;
  return std::nullopt;
}

ColmapModel ReadColmapModel(const fs::path& model_dir) {
  const std::optional<ColmapFormat> format = DetectColmapFormat(model_dir);
  if (!format) {
    std::vector<std::string> missing;
    for (const char* file : {"cameras", "images", "points3D"}) {
      if (!fs::exists(model_dir / fmt::format("{}.bin", file)) &&
          !fs::exists(model_dir / fmt::format("{}.txt", file))) {
        missing.push_back(file);
      }
    }
    ThrowError(
        "{}: not a COLMAP model folder: needs cameras, images and points3D all as .bin or all "
        "as .txt{}",
        model_dir.string(),
        missing.empty() ? std::string(" (they are mixed)")
                        : fmt::format(" (missing: {})", fmt::join(missing, ", ")));
  }
  ColmapModel model;
  const bool binary = *format == ColmapFormat::kBinary;
  const char* extension = binary ? ".bin" : ".txt";
  {
    const fs::path path = model_dir / fmt::format("cameras{}", extension);
    std::ifstream in = OpenForReading(path);
    model.cameras = binary ? ReadColmapCamerasBinary(in, path.string())
                           : ReadColmapCamerasText(in, path.string());
  }
  {
    const fs::path path = model_dir / fmt::format("images{}", extension);
    std::ifstream in = OpenForReading(path);
    model.images = binary ? ReadColmapImagesBinary(in, path.string())
                          : ReadColmapImagesText(in, path.string());
  }
  {
    const fs::path path = model_dir / fmt::format("points3D{}", extension);
    std::ifstream in = OpenForReading(path);
    model.points = binary ? ReadColmapPoints3DBinary(in, path.string())
                          : ReadColmapPoints3DText(in, path.string());
  }
  return model;
}

Scene SceneFromColmap(const ColmapModel& model, const fs::path& image_root) {
  Scene scene;
  scene.image_root = image_root;
  for (const auto& [id, camera] : model.cameras) {
    REPHOTO_CHECK(id <= INT_MAX, "camera id {} is too large (at most {})", id, INT_MAX);
    scene.cameras.emplace(static_cast<int>(id), camera);
  }
  std::unordered_map<uint32_t, int> view_of_image;
  std::unordered_map<std::string, const ColmapImage*> image_of_name;
  scene.views.reserve(model.images.size());
  for (const ColmapImage& image : model.images) {
    const auto [it, inserted] =
        view_of_image.emplace(image.image_id, static_cast<int>(scene.views.size()));
    REPHOTO_CHECK(inserted, "{}: image id {} is used twice (first at {})", image.where,
                  image.image_id, model.images[it->second].where);
    REPHOTO_CHECK(!image.name.empty(), "{}: image {} has an empty name", image.where,
                  image.image_id);
    std::string name = CheckedImageName(image.name, image.where);
    const auto [name_it, name_inserted] = image_of_name.emplace(name, &image);
    REPHOTO_CHECK(name_inserted, "{}: image name '{}' is used twice (first at {})", image.where,
                  name, name_it->second->where);
    REPHOTO_CHECK(model.cameras.contains(image.camera_id),
                  "{}: image {} refers to camera id {}, which the cameras file does not define",
                  image.where, image.image_id, image.camera_id);
    View view;
    view.name = std::move(name);
    view.image_path = image_root / view.name;
    view.camera_id = static_cast<int>(image.camera_id);
    view.cam_from_world = PoseFromQuaternion(image.quaternion, image.translation, image.where);
    scene.views.push_back(std::move(view));
  }
  scene.points.reserve(model.points.size());
  std::unordered_map<uint64_t, const ColmapPoint3D*> point_of_id;
  for (const ColmapPoint3D& record : model.points) {
    const auto [it, inserted] = point_of_id.emplace(record.point3d_id, &record);
    REPHOTO_CHECK(inserted, "{}: point3D id {} is used twice (first at {})", record.where,
                  record.point3d_id, it->second->where);
    REPHOTO_CHECK(record.position.allFinite(), "{}: position is not finite", record.where);
    Point3D point;
    point.position = record.position;
    point.color = record.color;
    point.track.reserve(record.track.size());
    for (const auto& [image_id, point2d_idx] : record.track) {
      const auto view = view_of_image.find(image_id);
      REPHOTO_CHECK(view != view_of_image.end(),
                    "{}: track refers to image id {}, which the images file does not define",
                    record.where, image_id);
      const ColmapImage& image = model.images[view->second];
      REPHOTO_CHECK(point2d_idx < image.points2d.size(),
                    "{}: track refers to POINT2D_IDX {} of image {}, which has {} 2D points",
                    record.where, point2d_idx, image_id, image.points2d.size());
      point.track.push_back(Observation{view->second, image.points2d[point2d_idx]});
    }
    scene.points.push_back(std::move(point));
  }
  return scene;
}

ColmapModel ColmapFromScene(const Scene& scene) {
  ColmapModel model;
  for (const auto& [id, camera] : scene.cameras) {
    REPHOTO_CHECK(id > 0, "camera id {} cannot be written to COLMAP (ids are positive)", id);
    camera.Validate(fmt::format("camera {}", id));
    model.cameras.emplace(static_cast<uint32_t>(id), camera);
  }
  model.images.resize(scene.views.size());
  for (size_t i = 0; i < scene.views.size(); ++i) {
    const View& view = scene.views[i];
    REPHOTO_CHECK(scene.cameras.contains(view.camera_id),
                  "view {} '{}' refers to missing camera {}", i, view.name, view.camera_id);
    REPHOTO_CHECK(!view.name.empty() && view.name.find_first_of("\n\r") == std::string::npos &&
                      view.name.find('\0') == std::string::npos,
                  "view {}: name '{}' cannot be written to COLMAP", i, view.name);
    ColmapImage& image = model.images[i];
    image.image_id = static_cast<uint32_t>(i + 1);
    image.quaternion = view.cam_from_world.Quaternion();
    image.translation = view.cam_from_world.translation;
    image.camera_id = static_cast<uint32_t>(view.camera_id);
    image.name = view.name;
  }
  model.points.resize(scene.points.size());
  for (size_t p = 0; p < scene.points.size(); ++p) {
    const Point3D& point = scene.points[p];
    ColmapPoint3D& record = model.points[p];
    record.point3d_id = p + 1;
    record.position = point.position;
    record.color = point.color;
    record.error = -1;
    for (const Observation& observation : point.track) {
      REPHOTO_CHECK(observation.view_index >= 0 &&
                        observation.view_index < static_cast<int>(scene.views.size()),
                    "point {}: observation refers to view {}, but there are {} views", p,
                    observation.view_index, scene.views.size());
      ColmapImage& image = model.images[observation.view_index];
      record.track.emplace_back(image.image_id, static_cast<uint32_t>(image.points2d.size()));
      image.points2d.push_back(observation.pixel);
      image.point3d_ids.push_back(record.point3d_id);
    }
  }
  return model;
}

fs::path DefaultColmapImageRoot(const fs::path& model_dir) {
  fs::path dir = fs::absolute(model_dir).lexically_normal();
  if (!dir.has_filename()) dir = dir.parent_path();  // trailing separator
  const fs::path project =
      IsAllDigits(dir.filename().string()) ? dir.parent_path().parent_path() : dir.parent_path();
  return project / "images";
}

Scene ReadColmap(const fs::path& model_dir, const ColmapReadOptions& options) {
  const ColmapModel model = ReadColmapModel(model_dir);
  return SceneFromColmap(
      model, options.image_root ? *options.image_root : DefaultColmapImageRoot(model_dir));
}

void WriteColmap(const Scene& scene, const fs::path& model_dir, ColmapFormat format) {
  const ColmapModel model = ColmapFromScene(scene);
  if (format == ColmapFormat::kBinary) {
    WriteModelFile(model_dir / "cameras.bin",
                   [&](std::ostream& out) { WriteColmapCamerasBinary(out, model.cameras); });
    WriteModelFile(model_dir / "images.bin",
                   [&](std::ostream& out) { WriteColmapImagesBinary(out, model.images); });
    WriteModelFile(model_dir / "points3D.bin",
                   [&](std::ostream& out) { WriteColmapPoints3DBinary(out, model.points); });
  } else {
    WriteModelFile(model_dir / "cameras.txt",
                   [&](std::ostream& out) { WriteColmapCamerasText(out, model.cameras); });
    WriteModelFile(model_dir / "images.txt",
                   [&](std::ostream& out) { WriteColmapImagesText(out, model.images); });
    WriteModelFile(model_dir / "points3D.txt",
                   [&](std::ostream& out) { WriteColmapPoints3DText(out, model.points); });
  }
}

}  // namespace rephoto::scene
