#include "rephoto/scene/cameras_json.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>

#include "rephoto/core/error.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/reader_util.h"

namespace rephoto::scene {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

double Number(const json& entry, const char* key, const std::string& where) {
  const auto it = entry.find(key);
  REPHOTO_CHECK(it != entry.end(), "{}: missing \"{}\"", where, key);
  REPHOTO_CHECK(it->is_number(), "{}.{}: expected a number", where, key);
  const double value = it->get<double>();
  REPHOTO_CHECK(std::isfinite(value), "{}.{}: not finite", where, key);
  return value;
}

int Size(const json& entry, const char* key, const std::string& where) {
  const double value = Number(entry, key, where);
  REPHOTO_CHECK(value >= 1 && value <= 1e6 && value == std::floor(value),
                "{}.{}: expected a positive integer, got {}", where, key, value);
  return static_cast<int>(value);
}

// source_path/images from train.py's cfg_args (a Python Namespace repr), if that folder exists.
std::optional<fs::path> ImageFolderFromCfgArgs(const fs::path& cfg_args) {
  std::ifstream in(cfg_args);
  if (!in) return std::nullopt;
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::smatch source, images;
  static const std::regex source_re(R"(source_path=['"]([^'"]*)['"])");
  static const std::regex images_re(R"(images=['"]([^'"]*)['"])");
  if (!std::regex_search(text, source, source_re)) return std::nullopt;
  fs::path folder = source[1].str();
  folder /= std::regex_search(text, images, images_re) ? images[1].str() : "images";
  std::error_code ec;
  if (fs::is_directory(folder, ec)) return folder;
  return std::nullopt;
}

// The name checked by the rule of scene/image_name.h before any file is looked at, then with the
// extension 3DGS drops found on disk.
std::string ResolveImageName(const std::string& raw_name, const fs::path& image_root,
                             std::string_view where) {
  const std::string img_name = CheckedImageName(raw_name, where);
  std::error_code ec;
  if (fs::path(img_name).has_extension() && fs::is_regular_file(image_root / img_name, ec)) {
    return img_name;
  }
  for (const char* extension : {".png", ".jpg", ".JPG", ".jpeg", ".JPEG", ".exr"}) {
    if (fs::is_regular_file(image_root / (img_name + extension), ec)) return img_name + extension;
  }
  return img_name;
}

}  // namespace

Scene ReadCamerasJson(std::istream& in, std::string_view name, const fs::path& image_root) {
  json root;
  try {
    root = json::parse(in);
  } catch (const json::exception& error) {
    ThrowError("{}: invalid JSON: {}", name, error.what());
  }
  REPHOTO_CHECK(root.is_array(), "{}: expected a JSON array of cameras (3DGS cameras.json)", name);
  Scene scene;
  scene.image_root = image_root;
  for (size_t i = 0; i < root.size(); ++i) {
    const json& entry = root[i];
    const std::string where = fmt::format("{}: [{}]", name, i);
    REPHOTO_CHECK(entry.is_object(), "{}: expected an object", where);
    const auto img_name = entry.find("img_name");
    REPHOTO_CHECK(
        img_name != entry.end() && img_name->is_string() && !img_name->get<std::string>().empty(),
        "{}: missing \"img_name\" string", where);
    camera::Camera camera;
    camera.model = camera::CameraModel::kPinhole;
    camera.width = Size(entry, "width", where);
    camera.height = Size(entry, "height", where);
    const double cx = entry.contains("cx") ? Number(entry, "cx", where) : camera.width / 2.0;
    const double cy = entry.contains("cy") ? Number(entry, "cy", where) : camera.height / 2.0;
    camera.params = {Number(entry, "fx", where), Number(entry, "fy", where), cx, cy};

    const auto position = entry.find("position");
    REPHOTO_CHECK(position != entry.end() && position->is_array() && position->size() == 3,
                  "{}.position: expected 3 numbers", where);
    Eigen::Vector3d center;
    for (int r = 0; r < 3; ++r) {
      REPHOTO_CHECK((*position)[r].is_number(), "{}.position: expected 3 numbers", where);
      center[r] = (*position)[r].get<double>();
    }
    const auto rotation = entry.find("rotation");
    REPHOTO_CHECK(rotation != entry.end() && rotation->is_array() && rotation->size() == 3,
                  "{}.rotation: expected 3 rows of 3 numbers", where);
    Eigen::Matrix3d world_from_cam;
    for (int r = 0; r < 3; ++r) {
      const json& row = (*rotation)[r];
      REPHOTO_CHECK(row.is_array() && row.size() == 3, "{}.rotation: expected 3 rows of 3 numbers",
                    where);
      for (int c = 0; c < 3; ++c) {
        REPHOTO_CHECK(row[c].is_number(), "{}.rotation: expected 3 rows of 3 numbers", where);
        world_from_cam(r, c) = row[c].get<double>();
      }
    }
    REPHOTO_CHECK(center.allFinite(), "{}.position: not finite", where);
    const Eigen::Matrix3d rotation_cw = world_from_cam.transpose();
    const camera::Pose pose = MakePose(rotation_cw, -rotation_cw * center, where);
    ValidateCameraAndPose(camera, pose, where);

    View view;
    view.name = ResolveImageName(img_name->get<std::string>(), image_root, where + ".img_name");
    view.image_path = image_root / view.name;
    view.camera_id = AddOrReuseCamera(scene, camera);
    view.cam_from_world = pose;
    scene.views.push_back(std::move(view));
  }
  REPHOTO_CHECK(!scene.views.empty(), "{}: no cameras", name);
  return scene;
}

Scene ReadCamerasJson(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  REPHOTO_CHECK(in.good(), "{}: cannot open", path.string());
  const fs::path folder = path.parent_path();
  const fs::path image_root =
      ImageFolderFromCfgArgs(folder / "cfg_args").value_or(folder.empty() ? "." : folder);
  return ReadCamerasJson(in, path.string(), image_root);
}

bool IsCamerasJsonFile(const fs::path& path) {
  if (path.extension() != ".json") return false;
  std::ifstream in(path, std::ios::binary);
  char c = 0;
  while (in.get(c)) {
    if (!std::isspace(static_cast<unsigned char>(c))) return c == '[';
  }
  return false;
}

}  // namespace rephoto::scene
