// Bundler (Snavely et al.) sparse reconstructions: bundle.out (v0.3) plus the image list.
//
// Format (https://www.cs.cornell.edu/~snavely/bundler/bundler-v0.4-manual.html):
//   # Bundle file v0.3
//   <num_cameras> <num_points>
//   per camera:  f k1 k2 / R (3 rows) / t        (5 lines)
//   per point:   x y z / r g b / n cam key x y cam key x y ...   (3 lines)
// The image list (list.txt) has one line per camera, in the same order: "name [0 f]"; names
// are relative to the folder of the list file ("./" prefixes are dropped).
//
// Bundler's conventions and how they are converted to rephoto's (camera/camera.h):
// - X_cam = R X + t, the camera looks down -z with y up. rephoto's camera frame is Bundler's
//   rotated by 180 degrees about x: rotation = diag(1,-1,-1) R, translation = diag(1,-1,-1) t.
// - Projection: p = -X_cam.xy / X_cam.z, p' = f (1 + k1 |p|^2 + k2 |p|^4) p, relative to the
//   image centre with y up. This is COLMAP's RADIAL model (f, cx, cy, k1, k2) with the
//   principal point at the image centre: cx = width / 2, cy = height / 2 in the pixel-corner
//   convention (Bundle2PMVS writes 0.5 w - 0.5 for integer pixel centres, the same point).
// - Keypoint positions of the tracks are relative to the image centre with y up:
//   pixel = (width / 2 + x, height / 2 - y).
// - Bundler stores no image size: it comes from the image files (ImageSizeLookup).
// - Unregistered cameras (f = 0, typically with all-zero R and t) get no view; each is reported
//   with LogWarning. Track observations in them are dropped.
// One camera per registered view (identical intrinsics share one camera id).
//
// Thread safety: reentrant (no shared state; warnings go through the thread-safe log); the
// ImageSizeLookup given is called from the calling thread only.
#pragma once

#include <filesystem>
#include <istream>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/scene/reader_util.h"
#include "rephoto/scene/scene.h"

namespace rephoto::scene {

// Parses an image list; `name` is used in error messages. Throws on an empty name or a line
// with a malformed focal length.
std::vector<std::string> ReadBundlerImageList(std::istream& list, std::string_view name);

// Parses bundle.out from `bundle` (named `name` in errors). `image_names` come from the image
// list and must have one entry per camera; `image_sizes` gives each registered image's size.
// View image paths are image_root / name. Throws Error "<name>:<line>: ..." on malformed
// input (wrong counts, NaN/inf, non-rotations, camera index out of range, truncation).
Scene ReadBundler(std::istream& bundle, std::string_view name,
                  const std::vector<std::string>& image_names, const ImageSizeLookup& image_sizes,
                  const std::filesystem::path& image_root);

// The image list that belongs to a bundle.out: list.txt beside it, else in its parent folder
// (Bundler writes bundle/bundle.out next to list.txt). Throws when there is none.
std::filesystem::path FindBundlerImageList(const std::filesystem::path& bundle_path);

// Reads bundle.out and its list (found with FindBundlerImageList unless given); images are
// resolved relative to the list's folder and their sizes read from the image headers.
Scene ReadBundlerScene(const std::filesystem::path& bundle_path,
                       const std::filesystem::path& list_path = {});

}  // namespace rephoto::scene
