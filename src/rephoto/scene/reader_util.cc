#include "rephoto/scene/reader_util.h"

#include <charconv>
#include <cmath>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/io/image_io.h"

namespace rephoto::scene {

namespace {
constexpr size_t kMaxLineLength = size_t{1} << 20;

bool IsBlank(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
}
}  // namespace

bool LineReader::NextLine(std::string& line) {
  line.clear();
  if (!in_.good()) {
    REPHOTO_CHECK(!in_.bad(), "{}: read error after line {}", name_, line_number_);
    return false;
  }
  // Read character by character in chunks through getline, bounding the length.
  std::getline(in_, line);
  if (in_.bad()) ThrowError("{}: read error at line {}", name_, line_number_ + 1);
  if (in_.fail() && line.empty()) return false;  // end of stream, nothing read
  ++line_number_;
  REPHOTO_CHECK(line.size() <= kMaxLineLength,
                "{}:{}: line longer than {} bytes (not a text file?)", name_, line_number_,
                kMaxLineLength);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return true;
}

bool LineReader::NextContentLine(std::string& line, char comment) {
  while (NextLine(line)) {
    size_t first = 0;
    while (first < line.size() && IsBlank(line[first])) ++first;
    if (first == line.size()) continue;
    if (comment != '\0' && line[first] == comment) continue;
    return true;
  }
  return false;
}

std::string LineReader::RequireLine(std::string_view what, char comment) {
  std::string line;
  REPHOTO_CHECK(NextContentLine(line, comment), "{}:{}: unexpected end of file, expected {}", name_,
                line_number_ + 1, what);
  return line;
}

std::vector<std::string_view> LineReader::RequireTokens(std::string_view what, char comment) {
  buffer_ = RequireLine(what, comment);
  return SplitTokens(buffer_);
}

std::string LineReader::Where() const { return fmt::format("{}:{}", name_, line_number_); }

std::vector<std::string_view> SplitTokens(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && IsBlank(line[i])) ++i;
    const size_t start = i;
    while (i < line.size() && !IsBlank(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

double ParseDouble(std::string_view token, std::string_view where, std::string_view field) {
  std::string_view text = token;
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec == std::errc::result_out_of_range) {
    ThrowError("{}: {}: number out of range: '{}'", where, field, token);
  }
  REPHOTO_CHECK(ec == std::errc() && end == text.data() + text.size() && !text.empty(),
                "{}: {}: expected a number, got '{}'", where, field, token);
  return value;
}

double ParseFiniteDouble(std::string_view token, std::string_view where, std::string_view field) {
  const double value = ParseDouble(token, where, field);
  REPHOTO_CHECK(std::isfinite(value), "{}: {} is not finite ('{}')", where, field, token);
  return value;
}

long long ParseInteger(std::string_view token, std::string_view where, std::string_view field,
                       long long min_value, long long max_value) {
  std::string_view text = token;
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  long long value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  REPHOTO_CHECK(ec != std::errc::result_out_of_range, "{}: {}: integer out of range: '{}'", where,
                field, token);
  REPHOTO_CHECK(ec == std::errc() && end == text.data() + text.size() && !text.empty(),
                "{}: {}: expected an integer, got '{}'", where, field, token);
  REPHOTO_CHECK(value >= min_value && value <= max_value, "{}: {} = {} is outside [{}, {}]", where,
                field, value, min_value, max_value);
  return value;
}

void RequireTokenCount(const std::vector<std::string_view>& tokens, size_t count,
                       std::string_view where, std::string_view what, bool allow_more) {
  const bool ok = allow_more ? tokens.size() >= count : tokens.size() == count;
  REPHOTO_CHECK(ok, "{}: expected {}{} values ({}), got {}", where, allow_more ? "at least " : "",
                count, what, tokens.size());
}

ImageSizeLookup ImageSizesFromDisk(const std::filesystem::path& image_root) {
  return [image_root](const std::string& image_name) {
    const std::filesystem::path path = image_root / image_name;
    REPHOTO_CHECK(std::filesystem::exists(path),
                  "{}: image not found; this format does not store the image size, so the photo "
                  "is needed",
                  path.string());
    const io::ImageHeader header = io::ReadImageHeader(path);
    return ImageSize{header.width, header.height};
  };
}

ImageSizeLookup FixedImageSize(int width, int height) {
  return [width, height](const std::string&) { return ImageSize{width, height}; };
}

void ValidateCameraAndPose(const camera::Camera& camera, const camera::Pose& pose,
                           std::string_view context) {
  camera.Validate(context);
  pose.Validate(context);
}

camera::Pose MakePose(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation,
                      std::string_view context, double tolerance) {
  REPHOTO_CHECK(translation.allFinite(), "{}: translation has a NaN or infinite entry", context);
  camera::Pose pose;
  pose.rotation = camera::NearestRotation(rotation, tolerance, context);
  pose.translation = translation;
  pose.Validate(context);
  return pose;
}

int AddOrReuseCamera(Scene& scene, const camera::Camera& camera) {
  for (const auto& [id, existing] : scene.cameras) {
    if (existing == camera) return id;
  }
  const int id = scene.cameras.empty() ? 1 : scene.cameras.rbegin()->first + 1;
  scene.cameras.emplace(id, camera);
  return id;
}

}  // namespace rephoto::scene
