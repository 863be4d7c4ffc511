// Pose sidecars: `<stem>.json` beside `<stem>.png|jpg` gives a photo's known pose, so that
// `rephoto live` skips registration (tracked rigs, synthetic captures, tests), and the same
// shape is what `rephoto live` suggests (a script or a drone can take a suggestion as it is):
//   {"camera": {"model": "PINHOLE", "width": W, "height": H, "params": [fx, fy, cx, cy]},
//    "qvec": [w, x, y, z], "tvec": [x, y, z]}
// Camera models and parameter order are COLMAP's (camera/camera.h); qvec/tvec are COLMAP's
// world-to-camera rotation (unit quaternion, Hamilton) and translation, in scene units.
// Extra members are ignored (a suggestion carries its score, centre, ...).
//
// Thread safety: pure functions.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "rephoto/camera/camera.h"

namespace rephoto::live {

struct PoseSidecar {
  camera::Camera camera;
  camera::Pose cam_from_world;
};

// Parses a sidecar. Throws Error "<where>: <what is wrong>" for invalid JSON, a missing or
// mistyped member, an unknown camera model, a wrong parameter count, a quaternion whose norm is
// not 1 within 1e-3, or an invalid camera or pose.
PoseSidecar ParseSidecar(std::string_view text, std::string_view where);

// The sidecar's JSON for a camera and pose (qvec with w >= 0).
nlohmann::json SidecarJson(const camera::Camera& camera, const camera::Pose& cam_from_world);

}  // namespace rephoto::live
