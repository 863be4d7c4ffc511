#include "rephoto/ibr/training_views.h"

#include "rephoto/core/error.h"

namespace rephoto::ibr {

std::vector<TrainingView> TrainingViewsFromScene(const scene::Scene& scene,
                                                 const std::vector<size_t>& indices,
                                                 const std::filesystem::path& depth_maps_dir) {
  std::vector<TrainingView> out;
  for (size_t i : indices) {
    REPHOTO_CHECK(i < scene.views.size(), "training view index {} out of range ({} views)", i,
                  scene.views.size());
    const scene::View& view = scene.views[i];
    TrainingView t{view.name, scene.CameraOf(view), view.cam_from_world, view.image_path, {}};
    if (!depth_maps_dir.empty()) {
      const std::string stem = std::filesystem::path(view.name).replace_extension("").string();
      for (const std::string& candidate :
           {view.name + ".geometric.bin", view.name + ".photometric.bin", view.name + ".bin",
            stem + ".pfm", stem + ".exr", stem + ".depth.exr"}) {
        if (std::filesystem::is_regular_file(depth_maps_dir / candidate)) {
          t.depth_map = depth_maps_dir / candidate;
          break;
        }
      }
    }
    out.push_back(std::move(t));
  }
  return out;
}

std::vector<Eigen::Vector3d> ScenePoints(const scene::Scene& scene) {
  std::vector<Eigen::Vector3d> points;
  points.reserve(scene.points.size());
  for (const scene::Point3D& p : scene.points) points.push_back(p.position);
  return points;
}

}  // namespace rephoto::ibr
