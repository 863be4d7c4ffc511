#include "rephoto/scene/strecha.h"

#include <algorithm>
#include <cmath>
#include <fstream>

#include "rephoto/core/error.h"
#include "rephoto/scene/reader_util.h"

namespace rephoto::scene {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kExtension = ".camera";

std::vector<fs::path> ListCameraFiles(const fs::path& folder) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string file_name = entry.path().filename().string();
    if (entry.is_regular_file() && file_name.size() > kExtension.size() &&
        file_name.ends_with(kExtension)) {
      files.push_back(entry.path());
    }
  }
  REPHOTO_CHECK(!ec, "{}: cannot list folder: {}", folder.string(), ec.message());
  std::sort(files.begin(), files.end());
  return files;
}

std::string ImageNameOf(const fs::path& camera_file) {
  const std::string file_name = camera_file.filename().string();
  return file_name.substr(0, file_name.size() - kExtension.size());
}

}  // namespace

CameraAndPose ReadStrechaCamera(std::istream& in, std::string_view name) {
  LineReader reader(in, std::string(name));
  Eigen::Matrix3d k;
  for (int row = 0; row < 3; ++row) {
    const auto tokens = reader.RequireTokens(fmt::format("K row {}", row + 1));
    RequireTokenCount(tokens, 3, reader.Where(), "K row");
    k.row(row) = ParseVector<3>(tokens, 0, reader.Where(), "K").transpose();
  }
  const std::string k_where = reader.Where();
  auto tokens = reader.RequireTokens("the distortion line");
  RequireTokenCount(tokens, 1, reader.Where(), "distortion", /*allow_more=*/true);
  for (size_t i = 0; i < tokens.size(); ++i) {
    const double value = ParseFiniteDouble(tokens[i], reader.Where(), "distortion");
    REPHOTO_CHECK(value == 0.0,
                  "{}: non-zero distortion {} is not supported (the format does not define its "
                  "model)",
                  reader.Where(), value);
  }
  Eigen::Matrix3d world_from_cam;
  for (int row = 0; row < 3; ++row) {
    tokens = reader.RequireTokens(fmt::format("R row {}", row + 1));
    RequireTokenCount(tokens, 3, reader.Where(), "R row");
    world_from_cam.row(row) = ParseVector<3>(tokens, 0, reader.Where(), "R").transpose();
  }
  const std::string r_where = reader.Where();
  tokens = reader.RequireTokens("the camera centre");
  RequireTokenCount(tokens, 3, reader.Where(), "camera centre");
  const Eigen::Vector3d centre = ParseVector<3>(tokens, 0, reader.Where(), "camera centre");
  tokens = reader.RequireTokens("the image size");
  RequireTokenCount(tokens, 2, reader.Where(), "width height");
  const int width = static_cast<int>(ParseInteger(tokens[0], reader.Where(), "width", 1, 1 << 20));
  const int height =
      static_cast<int>(ParseInteger(tokens[1], reader.Where(), "height", 1, 1 << 20));
  std::string line;
  REPHOTO_CHECK(!reader.NextContentLine(line), "{}: unexpected data after the image size",
                reader.Where());

  REPHOTO_CHECK(k(2, 2) != 0.0, "{}: K[2][2] is zero", k_where);
  k /= k(2, 2);
  const double tiny = 1e-9 * std::max({std::abs(k(0, 0)), std::abs(k(1, 1)), 1.0});
  REPHOTO_CHECK(std::abs(k(1, 0)) <= tiny && std::abs(k(2, 0)) <= tiny && std::abs(k(2, 1)) <= tiny,
                "{}: K is not upper triangular", k_where);
  REPHOTO_CHECK(std::abs(k(0, 1)) <= tiny, "{}: K has skew {}, which no camera model holds",
                k_where, k(0, 1));
  CameraAndPose result;
  result.camera.model = camera::CameraModel::kPinhole;
  result.camera.width = width;
  result.camera.height = height;
  result.camera.params = {k(0, 0), k(1, 1), k(0, 2) + 0.5, k(1, 2) + 0.5};
  result.camera.Validate(k_where);
  const Eigen::Matrix3d cam_from_world =
      camera::NearestRotation(world_from_cam, 1e-4, r_where).transpose();
  result.cam_from_world = MakePose(cam_from_world, -cam_from_world * centre, r_where);
  return result;
}

fs::path FindStrechaImageRoot(const fs::path& camera_folder) {
  const std::vector<fs::path> files = ListCameraFiles(camera_folder);
  REPHOTO_CHECK(!files.empty(), "{}: no .camera files", camera_folder.string());
  const std::string image = ImageNameOf(files.front());
  const fs::path parent = camera_folder.parent_path();
  for (const fs::path& candidate : {camera_folder, parent / "images", parent}) {
    if (fs::is_regular_file(candidate / image)) return candidate;
  }
  ThrowError("{}: image {} of {} not found in this folder, ../images or ..", camera_folder.string(),
             image, files.front().filename().string());
}

Scene ReadStrechaScene(const fs::path& camera_folder, const fs::path& image_root) {
  const std::vector<fs::path> files = ListCameraFiles(camera_folder);
  REPHOTO_CHECK(!files.empty(), "{}: no .camera files", camera_folder.string());
  Scene scene;
  scene.image_root = image_root.empty() ? FindStrechaImageRoot(camera_folder) : image_root;
  for (const fs::path& file : files) {
    std::ifstream in(file);
    REPHOTO_CHECK(in, "{}: cannot open", file.string());
    CameraAndPose camera_and_pose = ReadStrechaCamera(in, file.string());
    View view;
    view.name = ImageNameOf(file);
    view.image_path = scene.image_root / view.name;
    view.camera_id = AddOrReuseCamera(scene, camera_and_pose.camera);
    view.cam_from_world = camera_and_pose.cam_from_world;
    scene.views.push_back(std::move(view));
  }
  return scene;
}

}  // namespace rephoto::scene
