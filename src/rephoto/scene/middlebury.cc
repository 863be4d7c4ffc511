#include "rephoto/scene/middlebury.h"

#include <cmath>
#include <fstream>
#include <set>

#include "rephoto/core/error.h"
#include "rephoto/scene/image_name.h"

namespace rephoto::scene {

namespace fs = std::filesystem;

Scene ReadMiddlebury(std::istream& in, std::string_view name, const ImageSizeLookup& image_sizes,
                     const fs::path& image_root) {
  LineReader reader(in, std::string(name));
  auto tokens = reader.RequireTokens("the number of images");
  RequireTokenCount(tokens, 1, reader.Where(), "number of images");
  const long long count =
      ParseInteger(tokens[0], reader.Where(), "number of images", 0, 10'000'000);

  Scene scene;
  scene.image_root = image_root;
  std::set<std::string, std::less<>> names;
  for (long long index = 0; index < count; ++index) {
    tokens = reader.RequireTokens(fmt::format("image {} of {}", index + 1, count));
    const std::string where = reader.Where();
    RequireTokenCount(tokens, 22, where, "name, K (9), R (9), t (3)");
    View view;
    view.name = CheckedImageName(tokens[0], where);
    REPHOTO_CHECK(names.insert(view.name).second, "{}: image '{}' is listed twice", where,
                  view.name);
    const auto k = ParseVector<9>(tokens, 1, where, "K");
    const auto r = ParseVector<9>(tokens, 10, where, "R");
    const auto t = ParseVector<3>(tokens, 19, where, "t");
    const std::string context = fmt::format("{} ({})", where, view.name);
    REPHOTO_CHECK(k[8] != 0.0, "{}: K[2][2] is zero", context);
    const auto kn = k / k[8];
    const double scale = std::max(std::abs(kn[0]), std::abs(kn[4]));
    const double tiny = 1e-9 * std::max(scale, 1.0);
    REPHOTO_CHECK(std::abs(kn[3]) <= tiny && std::abs(kn[6]) <= tiny && std::abs(kn[7]) <= tiny,
                  "{}: K is not upper triangular (k21 k31 k32 = {} {} {})", context, kn[3], kn[6],
                  kn[7]);
    REPHOTO_CHECK(std::abs(kn[1]) <= tiny, "{}: K has skew k12 = {}, which no camera model holds",
                  context, kn[1]);
    const Eigen::Matrix3d rotation =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(r.data());
    view.cam_from_world = MakePose(rotation, t, context);

    const ImageSize size = image_sizes(view.name);
    camera::Camera camera;
    camera.model = camera::CameraModel::kPinhole;
    camera.width = size.width;
    camera.height = size.height;
    camera.params = {kn[0], kn[4], kn[2] + 0.5, kn[5] + 0.5};
    camera.Validate(context);
    view.camera_id = AddOrReuseCamera(scene, camera);
    view.image_path = image_root / view.name;
    scene.views.push_back(std::move(view));
  }
  std::string line;
  REPHOTO_CHECK(!reader.NextContentLine(line), "{}: more lines than the {} images announced",
                reader.Where(), count);
  return scene;
}

Scene ReadMiddleburyScene(const fs::path& par_path) {
  std::ifstream in(par_path);
  REPHOTO_CHECK(in, "{}: cannot open", par_path.string());
  const fs::path root = par_path.parent_path();
  return ReadMiddlebury(in, par_path.string(), ImageSizesFromDisk(root), root);
}

}  // namespace rephoto::scene
