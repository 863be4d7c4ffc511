#include "rephoto/scene/scene_info.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <filesystem>

namespace rephoto::scene {

namespace {

void Extend(std::optional<BoundingBox>& box, const Eigen::Vector3d& point) {
  if (!box) {
    box = BoundingBox{point, point};
  } else {
    box->min = box->min.cwiseMin(point);
    box->max = box->max.cwiseMax(point);
  }
}

nlohmann::json ToJson(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json ToJson(const std::optional<BoundingBox>& box) {
  if (!box) return nullptr;
  return {{"min", ToJson(box->min)}, {"max", ToJson(box->max)}};
}

std::string FormatVector(const Eigen::Vector3d& v) {
  return fmt::format("({:.6g}, {:.6g}, {:.6g})", v.x(), v.y(), v.z());
}

std::string FormatBox(const std::optional<BoundingBox>& box) {
  if (!box) return "none";
  return fmt::format("{} .. {}, size {}", FormatVector(box->min), FormatVector(box->max),
                     FormatVector(box->max - box->min));
}

}  // namespace

std::optional<Eigen::Vector3d> PointNearestToOpticalAxes(const Scene& scene) {
  if (scene.views.size() < 2) return std::nullopt;
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const View& view : scene.views) {
    const Eigen::Vector3d direction = view.cam_from_world.ViewDirection().normalized();
    const Eigen::Matrix3d projector =
        Eigen::Matrix3d::Identity() - direction * direction.transpose();
    a += projector;
    b += projector * view.cam_from_world.Center();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d singular = svd.singularValues();
  if (!(singular[2] > singular[0] * 1e-8)) return std::nullopt;
  return svd.solve(b);
}

SceneInfo ComputeSceneInfo(const Scene& scene, std::string source, std::string format) {
  SceneInfo info;
  info.source = std::move(source);
  info.format = std::move(format);
  info.image_root = scene.image_root;
  info.num_views = static_cast<int>(scene.views.size());
  info.num_cameras = static_cast<int>(scene.cameras.size());
  for (const auto& [id, camera] : scene.cameras) {
    ++info.cameras_per_model[std::string(camera::CameraModelName(camera.model))];
  }
  long long min_pixels = -1;
  long long max_pixels = -1;
  for (const View& view : scene.views) {
    const camera::Camera& camera = scene.CameraOf(view);
    ++info.views_per_model[std::string(camera::CameraModelName(camera.model))];
    const long long pixels = static_cast<long long>(camera.width) * camera.height;
    if (min_pixels < 0 || pixels < min_pixels ||
        (pixels == min_pixels && camera.width < info.min_width)) {
      min_pixels = pixels;
      info.min_width = camera.width;
      info.min_height = camera.height;
    }
    if (pixels > max_pixels || (pixels == max_pixels && camera.width > info.max_width)) {
      max_pixels = pixels;
      info.max_width = camera.width;
      info.max_height = camera.height;
    }
    Extend(info.camera_centers, view.cam_from_world.Center());
    std::error_code ec;
    if (!std::filesystem::exists(view.image_path, ec)) info.missing_images.push_back(view.name);
  }
  info.num_points = scene.points.size();
  for (const Point3D& point : scene.points) {
    Extend(info.points, point.position);
    info.num_observations += point.track.size();
  }
  info.axes_meeting_point = PointNearestToOpticalAxes(scene);
  if (info.axes_meeting_point) {
    for (const View& view : scene.views) {
      if (view.cam_from_world.CamFromWorld(*info.axes_meeting_point).z() > 0.0) {
        ++info.cameras_facing_meeting_point;
      }
    }
  }
  return info;
}

std::string FormatSceneInfo(const SceneInfo& info, size_t max_missing) {
  std::string text;
  auto line = [&text](const std::string& s) { text += s + "\n"; };
  line(fmt::format("scene:        {} ({})", info.source, info.format));
  line(fmt::format("image root:   {}", info.image_root.string()));
  line(fmt::format("images:       {}", info.num_views));
  std::string models;
  for (const auto& [model, count] : info.cameras_per_model) {
    if (!models.empty()) models += ", ";
    models += fmt::format("{} {} ({} views)", count, model,
                          info.views_per_model.count(model) ? info.views_per_model.at(model) : 0);
  }
  line(fmt::format("cameras:      {}{}{}", info.num_cameras, models.empty() ? "" : ": ", models));
  if (info.num_views > 0) {
    line(fmt::format("resolution:   {}x{} .. {}x{}", info.min_width, info.min_height,
                     info.max_width, info.max_height));
  }
  line(fmt::format("camera box:   {}", FormatBox(info.camera_centers)));
  line(fmt::format("points:       {} ({} observations)", info.num_points, info.num_observations));
  line(fmt::format("point box:    {}", FormatBox(info.points)));
  if (info.axes_meeting_point) {
    line(fmt::format("axes meet at: {} (in front of {} of {} cameras)",
                     FormatVector(*info.axes_meeting_point), info.cameras_facing_meeting_point,
                     info.num_views));
  } else {
    line("axes meet at: nowhere (fewer than 2 views or parallel axes)");
  }
  line(fmt::format("missing:      {} of {} images not found on disk", info.missing_images.size(),
                   info.num_views));
  for (size_t i = 0; i < info.missing_images.size() && i < max_missing; ++i) {
    line("  " + info.missing_images[i]);
  }
  if (info.missing_images.size() > max_missing) {
    line(fmt::format("  ... and {} more", info.missing_images.size() - max_missing));
  }
  return text;
}

nlohmann::json SceneInfoToJson(const SceneInfo& info) {
  nlohmann::json json;
  json["source"] = info.source;
  json["format"] = info.format;
  json["image_root"] = info.image_root.string();
  json["views"] = info.num_views;
  json["cameras"] = info.num_cameras;
  json["views_per_model"] = info.views_per_model;
  json["cameras_per_model"] = info.cameras_per_model;
  json["resolution"] = {{"min", {info.min_width, info.min_height}},
                        {"max", {info.max_width, info.max_height}}};
  json["camera_centers"] = ToJson(info.camera_centers);
  json["points"] = info.num_points;
  json["observations"] = info.num_observations;
  json["points_bbox"] = ToJson(info.points);
  json["axes_meeting_point"] =
      info.axes_meeting_point ? ToJson(*info.axes_meeting_point) : nlohmann::json(nullptr);
  json["cameras_facing_meeting_point"] = info.cameras_facing_meeting_point;
  json["missing_images"] = info.missing_images;
  return json;
}

}  // namespace rephoto::scene
