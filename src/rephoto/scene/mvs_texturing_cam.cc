#include "rephoto/scene/mvs_texturing_cam.h"

#include <algorithm>
#include <fstream>

#include "rephoto/core/error.h"
#include "rephoto/io/image_io.h"
#include "rephoto/scene/reader_util.h"

namespace rephoto::scene {

namespace fs = std::filesystem;

MvsTexturingCam ReadMvsTexturingCam(std::istream& in, std::string_view name) {
  LineReader reader(in, std::string(name));
  auto tokens = reader.RequireTokens("the extrinsics line (tx ty tz R00 .. R22)");
  const std::string extrinsics_where = reader.Where();
  RequireTokenCount(tokens, 12, extrinsics_where, "tx ty tz R00 .. R22");
  const Eigen::Vector3d translation = ParseVector<3>(tokens, 0, extrinsics_where, "translation");
  const auto r = ParseVector<9>(tokens, 3, extrinsics_where, "rotation");
  const Eigen::Matrix3d rotation =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(r.data());

  tokens = reader.RequireTokens("the intrinsics line (f d0 d1 paspect ppx ppy)");
  const std::string where = reader.Where();
  RequireTokenCount(tokens, 6, where, "f d0 d1 paspect ppx ppy");
  const auto values = ParseVector<6>(tokens, 0, where, "intrinsics");
  std::string line;
  REPHOTO_CHECK(!reader.NextContentLine(line), "{}: unexpected data after the intrinsics line",
                reader.Where());

  MvsTexturingCam cam;
  cam.cam_from_world = MakePose(rotation, translation, extrinsics_where);
  cam.intrinsics.focal_length = values[0];
  cam.intrinsics.radial_distortion = {values[1], values[2]};
  cam.intrinsics.pixel_aspect = values[3];
  cam.intrinsics.principal_point = {values[4], values[5]};
  REPHOTO_CHECK(values[0] > 0.0, "{}: focal length {} is not positive", where, values[0]);
  REPHOTO_CHECK(values[3] > 0.0, "{}: pixel aspect {} is not positive", where, values[3]);
  return cam;
}

Scene ReadMvsTexturingScene(const fs::path& folder) {
  std::vector<fs::path> cam_files;
  std::vector<fs::path> images;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    if (!entry.is_regular_file()) continue;
    if (entry.path().extension() == ".cam") cam_files.push_back(entry.path());
    if (io::IsImageFile(entry.path())) images.push_back(entry.path());
  }
  REPHOTO_CHECK(!ec, "{}: cannot list folder: {}", folder.string(), ec.message());
  REPHOTO_CHECK(!cam_files.empty(), "{}: no .cam files", folder.string());
  std::sort(cam_files.begin(), cam_files.end());
  std::sort(images.begin(), images.end());

  Scene scene;
  scene.image_root = folder;
  for (const fs::path& cam_file : cam_files) {
    const auto image = std::find_if(images.begin(), images.end(), [&](const fs::path& path) {
      return path.stem() == cam_file.stem();
    });
    REPHOTO_CHECK(image != images.end(), "{}: no image named {}.* beside it", cam_file.string(),
                  cam_file.stem().string());
    std::ifstream in(cam_file);
    REPHOTO_CHECK(in, "{}: cannot open", cam_file.string());
    const MvsTexturingCam cam = ReadMvsTexturingCam(in, cam_file.string());
    const io::ImageHeader header = io::ReadImageHeader(*image);
    View view;
    view.name = image->filename().string();
    view.image_path = *image;
    view.camera_id =
        AddOrReuseCamera(scene, MveCamera(cam.intrinsics, header.width, header.height,
                                          /*with_distortion=*/true, cam_file.string()));
    view.cam_from_world = cam.cam_from_world;
    scene.views.push_back(std::move(view));
  }
  return scene;
}

}  // namespace rephoto::scene
