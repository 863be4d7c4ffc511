// Strecha et al. 2008 benchmark cameras ("fountain-P11", "Herz-Jesu-P8", ...): one text file
// "<image name>.camera" per photo, e.g. gt_dense_cameras/0000.jpg.camera for images/0000.jpg.
//
// Layout (9 lines):
//   K (3 lines, 3x3)
//   distortion (1 line; all zero in the published data)
//   R (3 lines): camera-to-world rotation (its columns are the camera axes in world coordinates)
//   C (1 line): camera centre in world coordinates
//   width height (1 line)
// projection: x ~ K R^T (X - C); camera axes x right, y down, looking along +z (as rephoto).
//
// Conversions to rephoto (camera/camera.h):
// - cam_from_world: rotation = R^T, translation = -R^T C. R is printed with 6 digits and is
//   replaced by the nearest rotation (deviation up to 1e-4 accepted).
// - Pixel convention: we read K as a computer-vision matrix with integer coordinates at pixel
//   centres (as OpenMVG, which distributes this data, uses it), so the principal point gets
//   +0.5. An assumption: the data cannot confirm it at sub-pixel level.
// - PINHOLE camera (fx, fy, cx + 0.5, cy + 0.5). A non-zero distortion line is rejected: the
//   benchmark does not document its model, and its published files hold zeros.
//
// Thread safety: reentrant (no shared state).
#pragma once

#include <filesystem>
#include <istream>
#include <string_view>

#include "rephoto/camera/camera.h"
#include "rephoto/scene/scene.h"

namespace rephoto::scene {

struct CameraAndPose {
  camera::Camera camera;
  camera::Pose cam_from_world;
};

// Parses one .camera stream (named `name` in errors). Throws Error "<name>:<line>: ..." on
// missing lines, NaN/inf, skew, non-rotations, non-positive sizes, trailing data.
CameraAndPose ReadStrechaCamera(std::istream& in, std::string_view name);

// The folder that holds the photos of a folder of .camera files: the camera folder itself if
// the first camera's image is there, else a sibling "images" folder, else the parent folder.
// Throws when none holds it.
std::filesystem::path FindStrechaImageRoot(const std::filesystem::path& camera_folder);

// Reads every "*.camera" file of `camera_folder` (sorted by name; view name = file name
// without ".camera"). `image_root` defaults to FindStrechaImageRoot. Throws when the folder
// has no .camera file.
Scene ReadStrechaScene(const std::filesystem::path& camera_folder,
                       const std::filesystem::path& image_root = {});

}  // namespace rephoto::scene
