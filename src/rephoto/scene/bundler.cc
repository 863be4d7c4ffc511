#include "rephoto/scene/bundler.h"

#include <fstream>

#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/scene/image_name.h"

namespace rephoto::scene {

namespace fs = std::filesystem;

namespace {

// Counts larger than this are certainly corrupt (and would only make us allocate).
constexpr long long kMaxCount = 100'000'000;

}  // namespace

std::vector<std::string> ReadBundlerImageList(std::istream& list, std::string_view name) {
  LineReader reader(list, std::string(name));
  std::vector<std::string> names;
  std::string line;
  while (reader.NextContentLine(line)) {
    const auto tokens = SplitTokens(line);
    REPHOTO_CHECK(tokens.size() == 1 || tokens.size() == 3,
                  "{}: expected 'image_name' or 'image_name 0 focal', got {} values",
                  reader.Where(), tokens.size());
    if (tokens.size() == 3) {
      ParseFiniteDouble(tokens[1], reader.Where(), "list field 2");
      ParseFiniteDouble(tokens[2], reader.Where(), "focal length");
    }
    names.push_back(CheckedImageName(tokens[0], reader.Where()));
  }
  return names;
}

Scene ReadBundler(std::istream& bundle, std::string_view name,
                  const std::vector<std::string>& image_names, const ImageSizeLookup& image_sizes,
                  const fs::path& image_root) {
  LineReader reader(bundle, std::string(name));
  std::string line;
  REPHOTO_CHECK(reader.NextContentLine(line), "{}: empty file, expected a Bundler bundle.out",
                name);
  if (line.rfind("#", 0) == 0) {
    const std::string_view header = "# Bundle file v";
    REPHOTO_CHECK(line.rfind(header, 0) == 0, "{}: not a Bundler file (first line '{}')",
                  reader.Where(), line.substr(0, 80));
    const std::string version = line.substr(header.size());
    REPHOTO_CHECK(version == "0.3", "{}: unsupported Bundler version '{}' (supported: 0.3)",
                  reader.Where(), version.substr(0, 20));
    REPHOTO_CHECK(reader.NextContentLine(line), "{}: unexpected end of file, expected counts",
                  name);
  }
  auto tokens = SplitTokens(line);
  RequireTokenCount(tokens, 2, reader.Where(), "num_cameras num_points");
  const int num_cameras =
      static_cast<int>(ParseInteger(tokens[0], reader.Where(), "num_cameras", 0, kMaxCount));
  const long long num_points = ParseInteger(tokens[1], reader.Where(), "num_points", 0, kMaxCount);
  REPHOTO_CHECK(static_cast<size_t>(num_cameras) == image_names.size(),
                "{}: {} cameras but the image list has {} entries", reader.Where(), num_cameras,
                image_names.size());

  Scene scene;
  scene.image_root = image_root;
  std::vector<int> view_of_camera(num_cameras, -1);
  for (int index = 0; index < num_cameras; ++index) {
    const std::string what = fmt::format("camera {} (f k1 k2)", index);
    tokens = reader.RequireTokens(what);
    const std::string where = reader.Where();
    RequireTokenCount(tokens, 3, where, what);
    const Eigen::Vector3d intrinsics = ParseVector<3>(tokens, 0, where, "f k1 k2");
    Eigen::Matrix3d rotation;
    for (int row = 0; row < 3; ++row) {
      tokens = reader.RequireTokens(fmt::format("camera {} rotation row {}", index, row));
      RequireTokenCount(tokens, 3, reader.Where(), "rotation row");
      rotation.row(row) = ParseVector<3>(tokens, 0, reader.Where(), "rotation").transpose();
    }
    tokens = reader.RequireTokens(fmt::format("camera {} translation", index));
    RequireTokenCount(tokens, 3, reader.Where(), "translation");
    const Eigen::Vector3d translation = ParseVector<3>(tokens, 0, reader.Where(), "translation");

    const double focal = intrinsics[0];
    if (focal == 0.0) {
      LogWarning(fmt::format("{}: camera {} ({}) is not registered (f = 0); skipped", where, index,
                             image_names[index]));
      continue;
    }
    REPHOTO_CHECK(focal > 0.0, "{}: camera {}: focal length {} is negative", where, index, focal);
    const std::string context = fmt::format("{}: camera {} ({})", where, index, image_names[index]);
    const Eigen::Matrix3d flip = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
    camera::Pose pose = MakePose(flip * rotation, flip * translation, context);

    const ImageSize size = image_sizes(image_names[index]);
    camera::Camera camera;
    camera.model = camera::CameraModel::kRadial;
    camera.width = size.width;
    camera.height = size.height;
    camera.params = {focal, 0.5 * size.width, 0.5 * size.height, intrinsics[1], intrinsics[2]};
    camera.Validate(context);

    View view;
    view.name = image_names[index];
    view.image_path = image_root / view.name;
    view.camera_id = AddOrReuseCamera(scene, camera);
    view.cam_from_world = pose;
    view_of_camera[index] = static_cast<int>(scene.views.size());
    scene.views.push_back(std::move(view));
  }

  for (long long index = 0; index < num_points; ++index) {
    Point3D point;
    tokens = reader.RequireTokens(fmt::format("point {} position", index));
    RequireTokenCount(tokens, 3, reader.Where(), "point position x y z");
    point.position = ParseVector<3>(tokens, 0, reader.Where(), "point position");
    tokens = reader.RequireTokens(fmt::format("point {} colour", index));
    RequireTokenCount(tokens, 3, reader.Where(), "point colour r g b");
    for (int c = 0; c < 3; ++c) {
      point.color[c] =
          static_cast<uint8_t>(ParseInteger(tokens[c], reader.Where(), "colour", 0, 255));
    }
    tokens = reader.RequireTokens(fmt::format("point {} view list", index));
    const std::string where = reader.Where();
    RequireTokenCount(tokens, 1, where, "view list length", /*allow_more=*/true);
    const long long count = ParseInteger(tokens[0], where, "view list length", 0, kMaxCount);
    REPHOTO_CHECK(tokens.size() == static_cast<size_t>(1 + 4 * count),
                  "{}: view list of {} entries needs {} values (cam key x y each), got {}", where,
                  count, 1 + 4 * count, tokens.size());
    for (long long k = 0; k < count; ++k) {
      const size_t base = 1 + 4 * k;
      const int camera_index =
          static_cast<int>(ParseInteger(tokens[base], where, "camera index", 0, num_cameras - 1));
      ParseInteger(tokens[base + 1], where, "key index", -1, kMaxCount);
      const double x = ParseFiniteDouble(tokens[base + 2], where, "keypoint x");
      const double y = ParseFiniteDouble(tokens[base + 3], where, "keypoint y");
      const int view_index = view_of_camera[camera_index];
      if (view_index < 0) continue;  // observation in an unregistered camera
      const camera::Camera& camera = scene.CameraOf(scene.views[view_index]);
      point.track.push_back(
          {view_index, Eigen::Vector2d(0.5 * camera.width + x, 0.5 * camera.height - y)});
    }
    scene.points.push_back(std::move(point));
  }
  return scene;
}

fs::path FindBundlerImageList(const fs::path& bundle_path) {
  const fs::path folder = bundle_path.parent_path();
  for (const fs::path& candidate : {folder / "list.txt", folder.parent_path() / "list.txt"}) {
    if (fs::is_regular_file(candidate)) return candidate;
  }
  ThrowError("{}: no image list (list.txt) beside it or in its parent folder",
             bundle_path.string());
}

Scene ReadBundlerScene(const fs::path& bundle_path, const fs::path& list_path) {
  const fs::path list = list_path.empty() ? FindBundlerImageList(bundle_path) : list_path;
  std::ifstream list_stream(list);
  REPHOTO_CHECK(list_stream, "{}: cannot open", list.string());
  const std::vector<std::string> names = ReadBundlerImageList(list_stream, list.string());
  const fs::path image_root = list.parent_path();
  std::ifstream bundle_stream(bundle_path);
  REPHOTO_CHECK(bundle_stream, "{}: cannot open", bundle_path.string());
  return ReadBundler(bundle_stream, bundle_path.string(), names, ImageSizesFromDisk(image_root),
                     image_root);
}

}  // namespace rephoto::scene
