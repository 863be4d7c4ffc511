// Helpers shared by rephoto's scene readers: line-oriented text parsing with file:line errors,
// and the lookup of image sizes for formats that do not store them.
//
// Every parse failure throws rephoto::Error "<name>:<line>: <what is wrong>" where <name> is the
// name the caller gave for the stream (usually the file path).
//
// Thread safety: the free functions are pure; a LineReader holds the position in its stream and
// belongs to one thread.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <istream>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/scene/scene.h"

namespace rephoto::scene {

// Reads a text stream line by line and splits lines into whitespace-separated tokens.
class LineReader {
 public:
  LineReader(std::istream& in, std::string name) : in_(in), name_(std::move(name)) {}

  // Next line (without the end-of-line, '\r' stripped); false at end of stream. Throws on a
  // stream error or on a line longer than 1 MiB (binary garbage).
  bool NextLine(std::string& line);
  // Next line that is neither empty/blank nor, when `comment` is non-zero, starts with
  // `comment` (after leading blanks). false at end of stream.
  bool NextContentLine(std::string& line, char comment = '\0');
  // Like NextContentLine but throws "<name>:<line>: unexpected end of file, expected <what>".
  std::string RequireLine(std::string_view what, char comment = '\0');

  // Tokens of the next content line; throws at end of file (naming `what`).
  std::vector<std::string_view> RequireTokens(std::string_view what, char comment = '\0');

  int line_number() const { return line_number_; }
  const std::string& name() const { return name_; }
  // "<name>:<line>" for messages about the current line.
  std::string Where() const;

 private:
  std::istream& in_;
  std::string name_;
  std::string buffer_;
  int line_number_ = 0;
};

// Whitespace-separated tokens of `line` (views into it).
std::vector<std::string_view> SplitTokens(std::string_view line);

// Parse numbers; throw "<where>: <field>: expected a number, got '<token>'". ParseFiniteDouble
// also rejects NaN and inf ("<field> is not finite").
double ParseDouble(std::string_view token, std::string_view where, std::string_view field);
double ParseFiniteDouble(std::string_view token, std::string_view where, std::string_view field);
// Integer in [min_value, max_value].
long long ParseInteger(std::string_view token, std::string_view where, std::string_view field,
                       long long min_value, long long max_value);

// Throws "<where>: expected <count> values (<what>), got <n>" unless tokens.size() == count
// (or >= count when `allow_more`).
void RequireTokenCount(const std::vector<std::string_view>& tokens, size_t count,
                       std::string_view where, std::string_view what, bool allow_more = false);

// Reads `N` finite doubles from tokens[first..first+N).
template <int N>
Eigen::Matrix<double, N, 1> ParseVector(const std::vector<std::string_view>& tokens, size_t first,
                                        std::string_view where, std::string_view field) {
  Eigen::Matrix<double, N, 1> values;
  for (int i = 0; i < N; ++i) {
    values[i] = ParseFiniteDouble(tokens.at(first + i), where, field);
  }
  return values;
}

// Image size lookup for formats that do not store the image size: returns (width, height) of
// the image with this name. Throws Error naming the image when it cannot be determined.
struct ImageSize {
  int width = 0;
  int height = 0;
};
using ImageSizeLookup = std::function<ImageSize(const std::string& image_name)>;

// Reads sizes from the image file headers under `image_root` (io::ReadImageHeader).
ImageSizeLookup ImageSizesFromDisk(const std::filesystem::path& image_root);
// The same size for every image (tests, fuzzers, formats with one known size).
ImageSizeLookup FixedImageSize(int width, int height);

// Throws "<context>: ..." if the camera or the pose is invalid (camera::Camera::Validate,
// camera::Pose::Validate).
void ValidateCameraAndPose(const camera::Camera& camera, const camera::Pose& pose,
                           std::string_view context);

// Builds a cam_from_world pose. Text formats print rotations with few digits (Strecha: 6), so
// `rotation` may deviate from a rotation by up to `tolerance` (max |R^T R - I| entry); within
// that it is replaced by the nearest rotation (camera::NearestRotation). Larger deviations, a
// reflection and NaN/inf throw "<context>: ...".
camera::Pose MakePose(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation,
                      std::string_view context, double tolerance = 1e-4);

// The id of a camera in scene.cameras equal to `camera` (same model, size and parameters),
// adding it with the next free id (1 for the first) when there is none. Keeps the cameras of
// formats that store intrinsics per image shared where they are identical.
int AddOrReuseCamera(Scene& scene, const camera::Camera& camera);

}  // namespace rephoto::scene
