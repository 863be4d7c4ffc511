// A calibrated scene: cameras (intrinsics), views (one per photo: image file, camera, pose),
// and optionally sparse 3D points, all in one world frame with rephoto's conventions (see
// rephoto/camera/camera.h). Readers for every supported format produce this type.
//
// Thread safety: plain value types without synchronization: a Scene may be read by several threads
// at once, not modified while another thread uses it.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "rephoto/camera/camera.h"

namespace rephoto::scene {

struct View {
  // Image name as the format stores it (relative to image_root), unique within the scene;
  // also the key by which photos and rephotos are paired (its file stem).
  std::string name;
  // Where the photo is on disk (image_root / name, resolved by the reader).
  std::filesystem::path image_path;
  // Optional per-view mask (0 = ignore pixel), e.g. transforms.json mask_path.
  std::optional<std::filesystem::path> mask_path;
  int camera_id = 0;  // key into Scene::cameras
  camera::Pose cam_from_world;
};

struct Observation {
  int view_index = 0;     // index into Scene::views
  Eigen::Vector2d pixel;  // pixel position (pixel-corner convention)
};

struct Point3D {
  Eigen::Vector3d position;
  Eigen::Matrix<uint8_t, 3, 1> color = Eigen::Matrix<uint8_t, 3, 1>::Zero();
  std::vector<Observation> track;  // may be empty when the format stores none
};

struct Scene {
  std::map<int, camera::Camera> cameras;
  std::vector<View> views;  // in the order of the source file
  std::vector<Point3D> points;
  std::filesystem::path image_root;  // folder the view names are relative to

  const camera::Camera& CameraOf(const View& view) const { return cameras.at(view.camera_id); }
};

}  // namespace rephoto::scene
