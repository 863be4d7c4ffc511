#include "rephoto/live/sidecar.h"

#include <cmath>

#include "rephoto/core/error.h"

namespace rephoto::live {

PoseSidecar ParseSidecar(std::string_view text, std::string_view where) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw Error(fmt::format("{}: not valid JSON: {}", where, e.what()));
  }
  REPHOTO_CHECK(j.is_object(), "{}: a pose sidecar must be a JSON object", where);
  auto numbers = [&](const nlohmann::json& parent, const char* key, size_t count) {
    REPHOTO_CHECK(parent.contains(key) && parent[key].is_array(), "{}: '{}' must be an array",
                  where, key);
    const nlohmann::json& a = parent[key];
    REPHOTO_CHECK(count == 0 || a.size() == count, "{}: '{}' must have {} numbers, not {}", where,
                  key, count, a.size());
    std::vector<double> v;
    for (const nlohmann::json& x : a) {
      REPHOTO_CHECK(x.is_number(), "{}: '{}' must hold numbers", where, key);
      v.push_back(x.get<double>());
      REPHOTO_CHECK(std::isfinite(v.back()), "{}: '{}' holds a non-finite number", where, key);
    }
    return v;
  };
  REPHOTO_CHECK(j.contains("camera") && j["camera"].is_object(), "{}: 'camera' must be an object",
                where);
  const nlohmann::json& c = j["camera"];
  REPHOTO_CHECK(c.contains("model") && c["model"].is_string(), "{}: camera 'model' must be a string",
                where);
  const std::string model_name = c["model"].get<std::string>();
  const std::optional<camera::CameraModel> model = camera::ParseCameraModel(model_name);
  REPHOTO_CHECK(model.has_value(), "{}: unknown camera model '{}'", where, model_name);
  PoseSidecar s;
  s.camera.model = *model;
  for (const char* key : {"width", "height"}) {
    REPHOTO_CHECK(c.contains(key) && c[key].is_number_integer() && c[key].get<int64_t>() > 0 &&
                      c[key].get<int64_t>() <= 1000000,
                  "{}: camera '{}' must be a positive integer", where, key);
  }
  s.camera.width = c["width"].get<int>();
  s.camera.height = c["height"].get<int>();
  s.camera.params = numbers(c, "params", camera::CameraModelParamCount(*model));
  s.camera.Validate(std::string(where) + ": camera");
  const std::vector<double> q = numbers(j, "qvec", 4);
  const std::vector<double> t = numbers(j, "tvec", 3);
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  REPHOTO_CHECK(std::abs(norm - 1) <= 1e-3, "{}: 'qvec' must be a unit quaternion (norm {})",
                where, norm);
  s.cam_from_world = camera::Pose::FromQuaternion(q[0], q[1], q[2], q[3], {t[0], t[1], t[2]});
  s.cam_from_world.Validate(std::string(where) + ": pose");
  return s;
}

nlohmann::json SidecarJson(const camera::Camera& camera, const camera::Pose& cam_from_world) {
  const Eigen::Vector4d q = cam_from_world.Quaternion();
  const Eigen::Vector3d& t = cam_from_world.translation;
  return {{"camera",
           {{"model", std::string(camera::CameraModelName(camera.model))},
            {"width", camera.width},
            {"height", camera.height},
            {"params", camera.params}}},
          {"qvec", {q[0], q[1], q[2], q[3]}},
          {"tvec", {t[0], t[1], t[2]}}};
}

}  // namespace rephoto::live
