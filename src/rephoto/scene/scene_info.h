// A summary of a scene for people (`rephoto scene info`) and scripts (--json): how many
// images and cameras, which camera models, the resolution range, where the cameras and points
// are, where the optical axes meet, and which photos are missing on disk.
//
// Thread safety: reentrant (reads the scene and probes image files; no shared state).
#pragma once

#include <Eigen/Core>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "rephoto/scene/scene.h"

namespace rephoto::scene {

struct BoundingBox {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
};

struct SceneInfo {
  std::string source;  // what was read (path), as given by the caller
  std::string format;  // format name, as given by the caller
  std::filesystem::path image_root;
  int num_views = 0;
  int num_cameras = 0;
  std::map<std::string, int> views_per_model;    // COLMAP model name -> number of views
  std::map<std::string, int> cameras_per_model;  // COLMAP model name -> number of cameras
  // Smallest and largest image (by pixel count; ties by width) over the views; 0x0 when empty.
  int min_width = 0, min_height = 0, max_width = 0, max_height = 0;
  // Camera centres (world frame, scene units); std::nullopt without views.
  std::optional<BoundingBox> camera_centers;
  size_t num_points = 0;
  size_t num_observations = 0;        // sum of track lengths
  std::optional<BoundingBox> points;  // std::nullopt without points
  // The point with the least sum of squared distances to all optical axes (see
  // PointNearestToOpticalAxes), and how many cameras have it in front of them.
  std::optional<Eigen::Vector3d> axes_meeting_point;
  int cameras_facing_meeting_point = 0;
  std::vector<std::string> missing_images;  // view names whose image_path does not exist
};

// The least-squares point nearest to all optical axes (lines through each camera centre along
// its viewing direction): solves sum_i (I - d_i d_i^T) (x - c_i) = 0. std::nullopt with fewer
// than two views or when the axes are (nearly) parallel (condition number above 1e8), as in a
// forward-facing capture with one viewing direction.
std::optional<Eigen::Vector3d> PointNearestToOpticalAxes(const Scene& scene);

// Gathers the summary; checks which images exist on disk (no image is read).
SceneInfo ComputeSceneInfo(const Scene& scene, std::string source, std::string format);

// Multi-line human summary (ends with a newline). Lists at most `max_missing` missing names.
std::string FormatSceneInfo(const SceneInfo& info, size_t max_missing = 20);

// Machine-readable form: {"source", "format", "image_root", "views", "cameras",
// "views_per_model", "cameras_per_model", "resolution": {"min": [w,h], "max": [w,h]},
// "camera_centers": {"min": [x,y,z], "max": [...]}|null, "points", "observations",
// "points_bbox": {...}|null, "axes_meeting_point": [x,y,z]|null, "cameras_facing_meeting_point",
// "missing_images": [names]}.
nlohmann::json SceneInfoToJson(const SceneInfo& info);

}  // namespace rephoto::scene
