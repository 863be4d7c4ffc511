#include "rephoto/scene/mve.h"

#include <algorithm>
#include <fstream>

#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/io/image_io.h"
#include "rephoto/scene/reader_util.h"

namespace rephoto::scene {

namespace fs = std::filesystem;

namespace {

std::string_view Trim(std::string_view text) {
  const size_t first = text.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const size_t last = text.find_last_not_of(" \t\r");
  return text.substr(first, last - first + 1);
}

}  // namespace

camera::Camera MveCamera(const MveIntrinsics& intrinsics, int width, int height,
                         bool with_distortion, std::string_view context) {
  REPHOTO_CHECK(width > 0 && height > 0, "{}: image size {}x{} is not positive", context, width,
                height);
  REPHOTO_CHECK(intrinsics.focal_length > 0.0, "{}: focal length {} is not positive", context,
                intrinsics.focal_length);
  REPHOTO_CHECK(intrinsics.pixel_aspect > 0.0, "{}: pixel aspect {} is not positive", context,
                intrinsics.pixel_aspect);
  const double image_aspect = static_cast<double>(width) / height * intrinsics.pixel_aspect;
  double fx = 0.0;
  double fy = 0.0;
  if (image_aspect < 1.0) {  // portrait, as mve::CameraInfo::fill_calibration
    fy = intrinsics.focal_length * height;
    fx = fy / intrinsics.pixel_aspect;
  } else {
    fx = intrinsics.focal_length * width;
    fy = fx * intrinsics.pixel_aspect;
  }
  const double cx = intrinsics.principal_point[0] * width;
  const double cy = intrinsics.principal_point[1] * height;
  const double k1 = intrinsics.radial_distortion[0];
  const double k2 = intrinsics.radial_distortion[1];
  camera::Camera camera;
  camera.width = width;
  camera.height = height;
  if (!with_distortion || (k1 == 0.0 && k2 == 0.0)) {
    camera.model = camera::CameraModel::kPinhole;
    camera.params = {fx, fy, cx, cy};
  } else if (fx == fy) {
    camera.model = camera::CameraModel::kRadial;
    camera.params = {fx, cx, cy, k1, k2};
  } else {
    camera.model = camera::CameraModel::kOpenCv;
    camera.params = {fx, fy, cx, cy, k1, k2, 0.0, 0.0};
  }
  camera.Validate(context);
  return camera;
}

MveViewMeta ReadMveMetaIni(std::istream& in, std::string_view name) {
  LineReader reader(in, std::string(name));
  MveViewMeta meta;
  MveIntrinsics intrinsics;
  bool has_camera_section = false;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  std::string rotation_where;
  bool has_rotation = false;
  bool has_translation = false;
  std::string section;
  std::string line;
  while (reader.NextContentLine(line, '#')) {
    const std::string where = reader.Where();
    const std::string_view text = Trim(line);
    if (text.front() == '[') {
      REPHOTO_CHECK(text.back() == ']' && text.size() >= 2, "{}: malformed section header '{}'",
                    where, text.substr(0, 80));
      section = std::string(Trim(text.substr(1, text.size() - 2)));
      if (section == "camera") has_camera_section = true;
      continue;
    }
    const size_t equals = text.find('=');
    REPHOTO_CHECK(equals != std::string_view::npos, "{}: expected 'key = value', got '{}'", where,
                  text.substr(0, 80));
    const std::string_view key = Trim(text.substr(0, equals));
    const std::string_view value = Trim(text.substr(equals + 1));
    const auto values = SplitTokens(value);
    const std::string field = fmt::format("{}.{}", section, key);
    if (section == "camera") {
      if (key == "focal_length") {
        RequireTokenCount(values, 1, where, field);
        intrinsics.focal_length = ParseFiniteDouble(values[0], where, field);
        REPHOTO_CHECK(intrinsics.focal_length >= 0.0, "{}: {} = {} is negative", where, field,
                      intrinsics.focal_length);
      } else if (key == "pixel_aspect") {
        RequireTokenCount(values, 1, where, field);
        intrinsics.pixel_aspect = ParseFiniteDouble(values[0], where, field);
        REPHOTO_CHECK(intrinsics.pixel_aspect > 0.0, "{}: {} = {} is not positive", where, field,
                      intrinsics.pixel_aspect);
      } else if (key == "principal_point") {
        RequireTokenCount(values, 2, where, field);
        intrinsics.principal_point = {ParseFiniteDouble(values[0], where, field),
                                      ParseFiniteDouble(values[1], where, field)};
      } else if (key == "radial_distortion") {
        RequireTokenCount(values, 2, where, field);
        intrinsics.radial_distortion = {ParseFiniteDouble(values[0], where, field),
                                        ParseFiniteDouble(values[1], where, field)};
      } else if (key == "rotation") {
        RequireTokenCount(values, 9, where, field);
        const auto r = ParseVector<9>(values, 0, where, field);
        rotation = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(r.data());
        rotation_where = where;
        has_rotation = true;
      } else if (key == "translation") {
        RequireTokenCount(values, 3, where, field);
        translation = ParseVector<3>(values, 0, where, field);
        has_translation = true;
      }
      // Other keys (e.g. MVE's "camera" entries of future versions) are ignored.
    } else if (section == "view") {
      if (key == "id") {
        RequireTokenCount(values, 1, where, field);
        meta.id = static_cast<int>(ParseInteger(values[0], where, field, 0, 1 << 30));
      } else if (key == "name") {
        meta.name = std::string(value);
      }
    }
  }
  if (has_camera_section && intrinsics.focal_length > 0.0) {
    REPHOTO_CHECK(has_rotation, "{}: [camera] has no rotation", name);
    REPHOTO_CHECK(has_translation, "{}: [camera] has no translation", name);
    meta.cam_from_world = MakePose(rotation, translation, rotation_where);
    meta.intrinsics = intrinsics;
  }
  return meta;
}

Scene ReadMveScene(const fs::path& scene_folder) {
  fs::path views = scene_folder / "views";
  if (!fs::is_directory(views) && scene_folder.filename() == "views") views = scene_folder;
  REPHOTO_CHECK(fs::is_directory(views), "{}: not an MVE scene (no views/ folder)",
                scene_folder.string());
  std::vector<fs::path> view_folders;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(views, ec)) {
    const std::string file_name = entry.path().filename().string();
    if (entry.is_directory() && file_name.ends_with(".mve")) view_folders.push_back(entry.path());
  }
  REPHOTO_CHECK(!ec, "{}: cannot list folder: {}", views.string(), ec.message());
  REPHOTO_CHECK(!view_folders.empty(), "{}: no view_XXXX.mve folders", views.string());
  std::sort(view_folders.begin(), view_folders.end());

  Scene scene;
  scene.image_root = views;
  for (const fs::path& folder : view_folders) {
    const fs::path meta_path = folder / "meta.ini";
    std::ifstream in(meta_path);
    REPHOTO_CHECK(in, "{}: cannot open", meta_path.string());
    const MveViewMeta meta = ReadMveMetaIni(in, meta_path.string());
    if (!meta.intrinsics) {
      LogWarning(fmt::format("{}: view has no camera (focal_length 0 or no [camera]); skipped",
                             meta_path.string()));
      continue;
    }
    fs::path image;
    bool undistorted = false;
    for (const char* candidate : {"undistorted.png", "undistorted.jpg", "undistorted.jpeg"}) {
      if (fs::is_regular_file(folder / candidate)) {
        image = folder / candidate;
        undistorted = true;
        break;
      }
    }
    if (image.empty()) {
      for (const char* candidate : {"original.jpg", "original.jpeg", "original.png"}) {
        if (fs::is_regular_file(folder / candidate)) {
          image = folder / candidate;
          break;
        }
      }
    }
    REPHOTO_CHECK(!image.empty(), "{}: no undistorted.png/jpg or original.jpg/png image",
                  folder.string());
    const io::ImageHeader header = io::ReadImageHeader(image);
    View view;
    view.name = (folder.filename() / image.filename()).generic_string();
    view.image_path = image;
    view.camera_id = AddOrReuseCamera(
        scene,
        MveCamera(*meta.intrinsics, header.width, header.height, !undistorted, meta_path.string()));
    view.cam_from_world = meta.cam_from_world;
    scene.views.push_back(std::move(view));
  }
  return scene;
}

}  // namespace rephoto::scene
