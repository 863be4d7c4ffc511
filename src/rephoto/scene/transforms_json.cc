#include "rephoto/scene/transforms_json.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/scene/image_name.h"

namespace rephoto::scene {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A transform_matrix printed with few digits is not exactly a rotation; beyond this it is wrong.
constexpr double kRotationTolerance = 1e-4;
constexpr const char* kExtensionsToTry[] = {".png", ".jpg", ".jpeg", ".exr"};

// The intrinsics keys of one object (top level or frame); absent keys stay unset.
struct Intrinsics {
  std::optional<double> fl_x, fl_y, camera_angle_x, camera_angle_y, cx, cy, w, h;
  std::optional<double> k1, k2, k3, k4, p1, p2;
  std::optional<std::string> camera_model;
  std::optional<bool> is_fisheye;
};

std::optional<double> GetNumber(const json& object, const char* key, std::string_view where) {
  const auto it = object.find(key);
  if (it == object.end() || it->is_null()) return std::nullopt;
  REPHOTO_CHECK(it->is_number(), "{}.{}: expected a number, got {}", where, key, it->dump());
  const double value = it->get<double>();
  REPHOTO_CHECK(std::isfinite(value), "{}.{}: value is not finite", where, key);
  return value;
}

// Overrides `into` with the keys present in `object`.
void ReadIntrinsics(const json& object, std::string_view where, Intrinsics& into) {
  const auto set = [&](std::optional<double>& field, const char* key) {
    if (std::optional<double> value = GetNumber(object, key, where)) field = value;
  };
  set(into.fl_x, "fl_x");
  set(into.fl_y, "fl_y");
  set(into.camera_angle_x, "camera_angle_x");
  set(into.camera_angle_y, "camera_angle_y");
  set(into.cx, "cx");
  set(into.cy, "cy");
  set(into.w, "w");
  set(into.h, "h");
  set(into.k1, "k1");
  set(into.k2, "k2");
  set(into.k3, "k3");
  set(into.k4, "k4");
  set(into.p1, "p1");
  set(into.p2, "p2");
  if (const auto it = object.find("camera_model"); it != object.end()) {
    REPHOTO_CHECK(it->is_string(), "{}.camera_model: expected a string, got {}", where, it->dump());
    into.camera_model = it->get<std::string>();
  }
  if (const auto it = object.find("is_fisheye"); it != object.end()) {
    REPHOTO_CHECK(it->is_boolean(), "{}.is_fisheye: expected true or false, got {}", where,
                  it->dump());
    into.is_fisheye = it->get<bool>();
  }
}

int ImageDimension(double value, std::string_view where, const char* key) {
  REPHOTO_CHECK(value >= 1 && value <= 1 << 30 && value == std::floor(value),
                "{}: {} = {} is not a positive whole number of pixels", where, key, value);
  return static_cast<int>(value);
}

camera::Camera MakeCamera(const Intrinsics& in, int width, int height, std::string_view where) {
  using camera::CameraModel;
  double fx = 0;
  if (in.fl_x) {
    fx = *in.fl_x;
  } else if (in.camera_angle_x) {
    REPHOTO_CHECK(*in.camera_angle_x > 0 && *in.camera_angle_x < M_PI,
                  "{}: camera_angle_x = {} is not in (0, pi)", where, *in.camera_angle_x);
    fx = 0.5 * width / std::tan(0.5 * *in.camera_angle_x);
  } else {
    ThrowError("{}: no focal length (needs fl_x or camera_angle_x)", where);
  }
  double fy = fx;
  if (in.fl_y) {
    fy = *in.fl_y;
  } else if (in.camera_angle_y && !in.fl_x) {
    // Only derive fy from the angle when fx came from an angle too; instant-ngp files carry
    // rounded camera_angle_y next to the exact fl_x/fl_y.
    REPHOTO_CHECK(*in.camera_angle_y > 0 && *in.camera_angle_y < M_PI,
                  "{}: camera_angle_y = {} is not in (0, pi)", where, *in.camera_angle_y);
    fy = 0.5 * height / std::tan(0.5 * *in.camera_angle_y);
  }
  const double cx = in.cx.value_or(0.5 * width);
  const double cy = in.cy.value_or(0.5 * height);
  const double k1 = in.k1.value_or(0), k2 = in.k2.value_or(0), k3 = in.k3.value_or(0),
               k4 = in.k4.value_or(0), p1 = in.p1.value_or(0), p2 = in.p2.value_or(0);

  std::string model_name;
  if (in.camera_model) {
    model_name = *in.camera_model;
  } else if (in.is_fisheye.value_or(false)) {
    model_name = "OPENCV_FISHEYE";
  } else if (k1 != 0 || k2 != 0 || k3 != 0 || k4 != 0 || p1 != 0 || p2 != 0) {
    model_name = "OPENCV";
  } else {
    model_name = "PINHOLE";
  }

  camera::Camera camera;
  camera.width = width;
  camera.height = height;
  if (model_name == "OPENCV_FISHEYE") {
    REPHOTO_CHECK(p1 == 0 && p2 == 0,
                  "{}: OPENCV_FISHEYE has no tangential distortion, but p1/p2 are set", where);
    camera.model = CameraModel::kOpenCvFisheye;
    camera.params = {fx, fy, cx, cy, k1, k2, k3, k4};
  } else if (model_name == "OPENCV" || model_name == "SIMPLE_RADIAL" || model_name == "RADIAL") {
    // nerfstudio reads the same k1..k4, p1, p2 keys for all three names.
    REPHOTO_CHECK(k4 == 0, "{}: k4 = {} (an r^8 term) has no COLMAP camera model equivalent", where,
                  k4);
    if (k3 != 0) {
      camera.model = CameraModel::kFullOpenCv;
      camera.params = {fx, fy, cx, cy, k1, k2, p1, p2, k3, 0, 0, 0};
    } else {
      camera.model = CameraModel::kOpenCv;
      camera.params = {fx, fy, cx, cy, k1, k2, p1, p2};
    }
  } else if (model_name == "PINHOLE" || model_name == "SIMPLE_PINHOLE") {
    REPHOTO_CHECK(k1 == 0 && k2 == 0 && k3 == 0 && k4 == 0 && p1 == 0 && p2 == 0,
                  "{}: camera_model {} but distortion coefficients are set", where, model_name);
    camera.model = CameraModel::kPinhole;
    camera.params = {fx, fy, cx, cy};
  } else {
    ThrowError(
        "{}: unsupported camera_model '{}' (OPENCV, OPENCV_FISHEYE, PINHOLE, SIMPLE_PINHOLE, "
        "SIMPLE_RADIAL, RADIAL)",
        where, model_name);
  }
  camera.Validate(where);
  return camera;
}

// The name relative to the image root (base_dir unless `image_root` is given), checked by the
// rule of scene/image_name.h before any file is looked at; a missing extension is resolved
// against the files under the root.
std::string ResolveImageName(const std::string& file_path, const fs::path& base_dir,
                             const fs::path& image_root, std::string_view where) {
  std::string raw = file_path;
  if (!image_root.empty() && !file_path.starts_with('/')) {
    // Relative to base_dir as the format says, then named relative to the image root that
    // confines them (the check below refuses what lands outside it).
    const fs::path root = fs::absolute(image_root).lexically_normal();
    raw = (fs::absolute(base_dir) / file_path)
              .lexically_normal()
              .lexically_relative(root)
              .generic_string();
    if (raw.empty()) raw = file_path;
  }
  fs::path path(CheckedImageName(raw, where));
  if (!path.has_extension() && path.has_filename()) {
    fs::path chosen = path;
    chosen += kExtensionsToTry[0];
    for (const char* extension : kExtensionsToTry) {
      fs::path candidate = path;
      candidate += extension;
      if (fs::exists((image_root.empty() ? base_dir : image_root) / candidate)) {
        chosen = candidate;
        break;
      }
    }
    path = chosen;
  }
  return path.generic_string();
}

std::string GetPathString(const json& frame, const char* key, std::string_view where) {
  const auto it = frame.find(key);
  REPHOTO_CHECK(it->is_string() && !it->get<std::string>().empty(),
                "{}.{}: expected a non-empty string, got {}", where, key, it->dump());
  return it->get<std::string>();
}

camera::Pose PoseFromTransformMatrix(const json& value, std::string_view where) {
  REPHOTO_CHECK(value.is_array() && (value.size() == 4 || value.size() == 3),
                "{}: expected a 4x4 (or 3x4) array of numbers", where);
  Eigen::Matrix4d c2w = Eigen::Matrix4d::Identity();
  for (size_t r = 0; r < value.size(); ++r) {
    const json& row = value[r];
    REPHOTO_CHECK(row.is_array() && row.size() == 4, "{}[{}]: expected 4 numbers, got {}", where, r,
                  row.dump());
    for (size_t c = 0; c < 4; ++c) {
      REPHOTO_CHECK(row[c].is_number(), "{}[{}][{}]: expected a number, got {}", where, r, c,
                    row[c].dump());
      c2w(r, c) = row[c].get<double>();
    }
  }
  REPHOTO_CHECK(c2w.allFinite(), "{}: has a NaN or infinite entry", where);
  REPHOTO_CHECK((c2w.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() <= 1e-6,
                "{}: last row is not (0 0 0 1)", where);
  // OpenGL camera axes (y up, looking along -z) to rephoto's (y down, z forward).
  Eigen::Matrix3d world_from_cam = c2w.topLeftCorner<3, 3>();
  world_from_cam.col(1) *= -1;
  world_from_cam.col(2) *= -1;
  const Eigen::Matrix3d rotation = world_from_cam.transpose();
  const Eigen::Vector3d center = c2w.topRightCorner<3, 1>();
  return MakePose(rotation, -rotation * center, where, kRotationTolerance);
}

json TransformMatrixFromPose(const camera::Pose& pose) {
  Eigen::Matrix3d world_from_cam = pose.rotation.transpose();
  world_from_cam.col(1) *= -1;
  world_from_cam.col(2) *= -1;
  const Eigen::Vector3d center = pose.Center();
  json matrix = json::array();
  for (int r = 0; r < 3; ++r) {
    matrix.push_back({world_from_cam(r, 0), world_from_cam(r, 1), world_from_cam(r, 2), center[r]});
  }
  matrix.push_back({0.0, 0.0, 0.0, 1.0});
  return matrix;
}

// Adds the keys describing `camera` to `object`.
void WriteIntrinsics(const camera::Camera& camera, json& object, std::string_view where) {
  using camera::CameraModel;
  camera.Validate(where);
  const std::vector<double>& p = camera.params;
  std::string model;
  std::vector<std::pair<const char*, double>> distortion;
  switch (camera.model) {
    case CameraModel::kSimplePinhole:
    case CameraModel::kPinhole:
      model = "PINHOLE";
      break;
    case CameraModel::kSimpleRadial:
      model = "OPENCV";
      distortion = {{"k1", p[3]}, {"k2", 0.0}, {"p1", 0.0}, {"p2", 0.0}};
      break;
    case CameraModel::kRadial:
      model = "OPENCV";
      distortion = {{"k1", p[3]}, {"k2", p[4]}, {"p1", 0.0}, {"p2", 0.0}};
      break;
    case CameraModel::kOpenCv:
      model = "OPENCV";
      distortion = {{"k1", p[4]}, {"k2", p[5]}, {"p1", p[6]}, {"p2", p[7]}};
      break;
    case CameraModel::kFullOpenCv:
      REPHOTO_CHECK(p[9] == 0 && p[10] == 0 && p[11] == 0,
                    "{}: FULL_OPENCV with k4/k5/k6 (rational distortion) cannot be written to "
                    "transforms.json",
                    where);
      model = "OPENCV";
      distortion = {{"k1", p[4]}, {"k2", p[5]}, {"p1", p[6]}, {"p2", p[7]}, {"k3", p[8]}};
      break;
    case CameraModel::kOpenCvFisheye:
      model = "OPENCV_FISHEYE";
      distortion = {{"k1", p[4]}, {"k2", p[5]}, {"k3", p[6]}, {"k4", p[7]}};
      break;
    case CameraModel::kSimpleRadialFisheye:
      model = "OPENCV_FISHEYE";
      distortion = {{"k1", p[3]}, {"k2", 0.0}, {"k3", 0.0}, {"k4", 0.0}};
      break;
    case CameraModel::kRadialFisheye:
      model = "OPENCV_FISHEYE";
      distortion = {{"k1", p[3]}, {"k2", p[4]}, {"k3", 0.0}, {"k4", 0.0}};
      break;
    case CameraModel::kFov:
    case CameraModel::kThinPrismFisheye:
      ThrowError("{}: {} cameras cannot be written to transforms.json", where,
                 camera::CameraModelName(camera.model));
  }
  object["camera_model"] = model;
  object["fl_x"] = camera.FocalLengthX();
  object["fl_y"] = camera.FocalLengthY();
  object["cx"] = camera.PrincipalPointX();
  object["cy"] = camera.PrincipalPointY();
  object["w"] = camera.width;
  object["h"] = camera.height;
  object["camera_angle_x"] = 2 * std::atan(0.5 * camera.width / camera.FocalLengthX());
  object["camera_angle_y"] = 2 * std::atan(0.5 * camera.height / camera.FocalLengthY());
  for (const auto& [key, value] : distortion) {
    object[key] = value;
  }
}

std::string PathRelativeTo(const fs::path& path, const fs::path& base_dir) {
  const fs::path absolute = fs::absolute(path).lexically_normal();
  const fs::path relative = absolute.lexically_relative(fs::absolute(base_dir).lexically_normal());
  return (relative.empty() ? absolute : relative).generic_string();
}

}  // namespace

Scene ReadTransformsJson(std::istream& in, std::string_view name, const fs::path& base_dir,
                         const ImageSizeLookup& image_size, const fs::path& image_root) {
  const fs::path root_dir = image_root.empty() ? base_dir : image_root;
  json root;
  try {
    root = json::parse(in);
  } catch (const json::exception& error) {
    ThrowError("{}: invalid JSON: {}", name, error.what());
  }
  REPHOTO_CHECK(root.is_object(), "{}: expected a JSON object at the top level", name);
  const auto frames_it = root.find("frames");
  REPHOTO_CHECK(frames_it != root.end() && frames_it->is_array(), "{}: no \"frames\" array", name);
  const json& frames = *frames_it;

  Intrinsics shared;
  ReadIntrinsics(root, name, shared);

  Scene scene;
  scene.image_root = root_dir;
  std::set<std::string> names;
  std::vector<std::string> image_names;
  image_names.reserve(frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    const std::string where = fmt::format("{}: frames[{}]", name, i);
    REPHOTO_CHECK(frames[i].is_object(), "{}: expected an object", where);
    REPHOTO_CHECK(frames[i].contains("file_path"), "{}: no file_path", where);
    image_names.push_back(ResolveImageName(GetPathString(frames[i], "file_path", where), base_dir,
                                           image_root, where + ".file_path"));
  }

  // Size of the first frame's image that exists, for files without w/h (NeRF-synthetic).
  std::optional<ImageSize> first_image_size;
  const auto fallback_size = [&]() -> ImageSize {
    if (!first_image_size) {
      REPHOTO_CHECK(!image_names.empty(), "{}: no frames to take the image size from", name);
      std::string chosen = image_names.front();
      for (const std::string& image_name : image_names) {
        if (fs::exists(root_dir / image_name)) {
          chosen = image_name;
          break;
        }
      }
      first_image_size = image_size(chosen);
    }
    return *first_image_size;
  };

  scene.views.reserve(frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    const json& frame = frames[i];
    const std::string where = fmt::format("{}: frames[{}]", name, i);
    Intrinsics intrinsics = shared;
    ReadIntrinsics(frame, where, intrinsics);
    int width = 0, height = 0;
    if (intrinsics.w && intrinsics.h) {
      width = ImageDimension(*intrinsics.w, where, "w");
      height = ImageDimension(*intrinsics.h, where, "h");
    } else {
      const ImageSize size = fallback_size();
      width = intrinsics.w ? ImageDimension(*intrinsics.w, where, "w") : size.width;
      height = intrinsics.h ? ImageDimension(*intrinsics.h, where, "h") : size.height;
    }
    const camera::Camera camera = MakeCamera(intrinsics, width, height, where);

    REPHOTO_CHECK(frame.contains("transform_matrix"), "{}: no transform_matrix", where);
    View view;
    view.cam_from_world =
        PoseFromTransformMatrix(frame.at("transform_matrix"), where + ".transform_matrix");
    view.name = image_names[i];
    REPHOTO_CHECK(names.insert(view.name).second, "{}: image '{}' appears twice", where, view.name);
    view.image_path = root_dir / view.name;
    if (frame.contains("mask_path") && !frame.at("mask_path").is_null()) {
      view.mask_path = root_dir / ResolveImageName(GetPathString(frame, "mask_path", where),
                                                   base_dir, image_root, where + ".mask_path");
    }
    view.camera_id = AddOrReuseCamera(scene, camera);
    scene.views.push_back(std::move(view));
  }
  return scene;
}

Scene ReadTransformsJson(const fs::path& path, const fs::path& image_root) {
  std::ifstream in(path, std::ios::binary);
  REPHOTO_CHECK(in.is_open(), "{}: cannot open file", path.string());
  const fs::path base_dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  return ReadTransformsJson(in, path.string(), base_dir,
                            ImageSizesFromDisk(image_root.empty() ? base_dir : image_root),
                            image_root);
}

std::string TransformsJsonFromScene(const Scene& scene, const fs::path& base_dir) {
  std::set<int> used_cameras;
  for (const View& view : scene.views) used_cameras.insert(view.camera_id);
  for (int id : used_cameras) {
    REPHOTO_CHECK(scene.cameras.contains(id), "scene: a view refers to missing camera {}", id);
  }
  const bool shared = used_cameras.size() == 1;

  json root = json::object();
  if (shared) {
    const int id = *used_cameras.begin();
    WriteIntrinsics(scene.cameras.at(id), root, fmt::format("camera {}", id));
  }
  json frames = json::array();
  for (const View& view : scene.views) {
    json frame = json::object();
    frame["file_path"] = PathRelativeTo(view.image_path, base_dir);
    if (view.mask_path) {
      frame["mask_path"] = PathRelativeTo(*view.mask_path, base_dir);
    }
    if (!shared) {
      WriteIntrinsics(scene.cameras.at(view.camera_id), frame,
                      fmt::format("camera {}", view.camera_id));
    }
    view.cam_from_world.Validate(fmt::format("view '{}'", view.name));
    frame["transform_matrix"] = TransformMatrixFromPose(view.cam_from_world);
    frames.push_back(std::move(frame));
  }
  root["frames"] = std::move(frames);
  return root.dump(2) + "\n";
}

void WriteTransformsJson(const Scene& scene, const fs::path& path) {
  const fs::path base_dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  WriteTextFileAtomically(path, TransformsJsonFromScene(scene, base_dir));
}

}  // namespace rephoto::scene
