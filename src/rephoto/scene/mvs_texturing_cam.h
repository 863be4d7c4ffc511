// mvs-texturing (texrecon, Waechter et al. 2014) .cam files: one per image, same stem
// ("IMG_0001.cam" next to "IMG_0001.jpg"), two lines:
//   tx ty tz R00 R01 R02 R10 R11 R12 R20 R21 R22    world-to-camera translation and rotation
//   f d0 d1 paspect ppx ppy                          MVE-normalized intrinsics
// f is normalized by max(width, height), (ppx, ppy) by (width, height); the camera frame is
// rephoto's (x right, y down, looking along +z). The intrinsics are converted exactly as MVE's
// (see rephoto/scene/mve.h, MveCamera): no pixel shift, d0 d1 as radial k1 k2 (RADIAL, or
// OPENCV when paspect != 1; PINHOLE when both are zero). texrecon itself ignores d0 d1 and
// expects undistorted photos, which then carry zeros.
// The image size comes from the image file.
//
// Thread safety: reentrant (no shared state).
#pragma once

#include <filesystem>
#include <istream>
#include <string_view>

#include "rephoto/scene/mve.h"
#include "rephoto/scene/scene.h"

namespace rephoto::scene {

struct MvsTexturingCam {
  camera::Pose cam_from_world;
  MveIntrinsics intrinsics;
};

// Parses one .cam stream (named `name` in errors). Throws Error "<name>:<line>: ..." on wrong
// value counts, NaN/inf, non-rotations, f <= 0, paspect <= 0, trailing data.
MvsTexturingCam ReadMvsTexturingCam(std::istream& in, std::string_view name);

// Reads every "*.cam" file of `folder` (sorted) with the image of the same stem beside it
// (.jpg .jpeg .png .JPG ..., any extension io::IsImageFile accepts); image sizes from the
// headers. Throws when there is no .cam file or an image is missing.
Scene ReadMvsTexturingScene(const std::filesystem::path& folder);

}  // namespace rephoto::scene
