// MVE scenes (Fuhrmann et al., https://github.com/simonfuhrmann/mve): a folder with
// views/view_XXXX.mve/, each holding meta.ini and the view's images.
//
// meta.ini (INI file; '#' starts a comment):
//   [camera]
//   focal_length = 0.9            f normalized by max(width, height)
//   pixel_aspect = 1              fy / fx
//   principal_point = 0.5 0.5     normalized by (width, height)
//   radial_distortion = 0 0       k1 k2 (optional)
//   rotation = r00 r01 ... r22    world-to-camera, row-major
//   translation = tx ty tz        world-to-camera
//   [view]
//   id = 0
//   name = IMG_0001.JPG
// MVE's camera frame is rephoto's (x right, y down, looking along +z), and its calibration
// matrix (mve::CameraInfo::fill_calibration) maps to pixel-corner coordinates (mvs-texturing
// subtracts 0.5 to index pixel centres), so no shift is applied:
//   landscape (width * pixel_aspect >= height): fx = f * width,  fy = fx * pixel_aspect
//   portrait:                                   fy = f * height, fx = fy / pixel_aspect
//   cx = principal_point.x * width, cy = principal_point.y * height
// Image: "undistorted.{png,jpg,jpeg}" if present (PINHOLE, distortion already removed), else
// "original.{jpg,jpeg,png}" with the radial distortion applied as COLMAP's RADIAL (k1, k2 on
// normalized coordinates, as MVE's k2k4 undistortion; OPENCV with p1 = p2 = 0 when
// pixel_aspect != 1). Views without a camera (no [camera] section or focal_length = 0, MVE's
// mark for an unregistered view) are skipped with a warning.
// The view name is "view_XXXX.mve/<image file>" relative to image_root = <scene>/views: the
// file stem ("undistorted"/"original") is therefore not unique across MVE views.
//
// Thread safety: reentrant (no shared state; warnings go through the thread-safe log).
#pragma once

#include <array>
#include <filesystem>
#include <istream>
#include <optional>
#include <string>
#include <string_view>

#include "rephoto/camera/camera.h"
#include "rephoto/scene/scene.h"

namespace rephoto::scene {

// MVE's normalized intrinsics (mve::CameraInfo), shared with the mvs-texturing .cam format.
struct MveIntrinsics {
  double focal_length = 0.0;  // normalized by max(width, height)
  double pixel_aspect = 1.0;
  std::array<double, 2> principal_point = {0.5, 0.5};  // normalized
  std::array<double, 2> radial_distortion = {0.0, 0.0};
};

// The camera for an image of width x height pixels (see above). `with_distortion` false gives
// PINHOLE and ignores radial_distortion. Throws "<context>: ..." when invalid.
camera::Camera MveCamera(const MveIntrinsics& intrinsics, int width, int height,
                         bool with_distortion, std::string_view context);

struct MveViewMeta {
  std::optional<MveIntrinsics> intrinsics;  // std::nullopt: no camera (unregistered view)
  camera::Pose cam_from_world;
  int id = -1;       // [view] id, -1 when absent
  std::string name;  // [view] name, may be empty
};

// Parses a meta.ini stream (named `name` in errors). Throws Error "<name>:<line>: ..." on
// malformed lines, wrong value counts, NaN/inf, non-rotations, pixel_aspect <= 0.
MveViewMeta ReadMveMetaIni(std::istream& in, std::string_view name);

// Reads an MVE scene folder (the one holding views/; the views folder itself is accepted).
// Image sizes come from the image headers. Throws when there is no view folder.
Scene ReadMveScene(const std::filesystem::path& scene_folder);

}  // namespace rephoto::scene
