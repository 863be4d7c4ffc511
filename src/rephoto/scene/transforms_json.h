// transforms.json, the camera file of NeRF-synthetic (Blender), instant-ngp and nerfstudio.
//
// Reading accepts all three forms:
// - Intrinsics at the top level, overridden per frame by the same keys inside a frame:
//   fl_x, fl_y (pixels) or camera_angle_x, camera_angle_y (full field of view in radians,
//   fl = 0.5 * w / tan(0.5 * angle)); fl_x wins over camera_angle_x; without fl_y, fy comes
//   from camera_angle_y when fx came from camera_angle_x, else fy = fx. cx, cy default to w/2, h/2.
//   w, h: when absent (NeRF- synthetic), the size of the first frame's image whose file exists
//   (image header).
// - Distortion k1, k2, k3, k4, p1, p2 (absent = 0) and the model: "camera_model" "OPENCV"
//   -> COLMAP OPENCV (k1, k2, p1, p2; with k3 != 0 FULL_OPENCV, whose k3 is the same r^6
//   term; k4 != 0 is rejected: it has no COLMAP equivalent), "OPENCV_FISHEYE" (or instant-ngp's
//   "is_fisheye": true) -> OPENCV_FISHEYE (k1..k4; p1/p2 != 0 rejected), "PINHOLE" /
//   "SIMPLE_PINHOLE" -> PINHOLE (any distortion rejected); nerfstudio's "SIMPLE_RADIAL" and
//   "RADIAL" read the same keys as "OPENCV" and are handled like it. Without "camera_model": OPENCV
//   if a coefficient is non-zero, else PINHOLE. These are the same formulas in all three tools.
// - Pixel centres: cx, cy are taken as they are in rephoto's pixel-corner convention. That is
//   what colmap2nerf (copying COLMAP's cx, cy), instant-ngp and nerfstudio (rays through pixel
//   centres at +0.5) mean. NeRF-synthetic has no cx/cy; the Blender renders have the principal
//   point at the true image centre, which is w/2 in the corner convention, so the default w/2
//   is exact. (The original NeRF code casts rays through integer pixel coordinates, half a
//   pixel off; that is a property of that renderer, not of the data.)
// - frames[]: "file_path" relative to the JSON file's folder, with or without extension: a
//   path without extension (NeRF-synthetic "./train/r_0") gets the first of .png, .jpg, .jpeg,
//   .exr that exists on disk, else .png. "mask_path" likewise (optional). "transform_matrix":
//   4x4 (or 3x4) camera-to-world with OpenGL axes (x right, y up, looking along -z); it is
//   converted to cam_from_world with rephoto's axes by negating its y and z columns. A matrix
//   whose 3x3 part is not a rotation within 1e-4, a last row other than (0 0 0 1), NaN/inf: Error.
// - instant-ngp's "aabb_scale", "scale", "offset" are NOT applied (nor written): instant-ngp
//   applies scale/offset (default 0.33 / 0.5) and an axis permutation only to its internal
//   training frame; the file's transform_matrix values are the poses in the dataset's world
//   frame, and meshes exported from that world frame line up with them. Likewise nerfstudio's
//   "applied_transform" (what ns-process-data already applied to COLMAP's poses to get the
//   file's matrices) is informational. Other keys ("sharpness", "rotation", "colmap_im_id",
//   "ply_file_path", ...) are ignored.
// Views are in frame order; cameras are shared where intrinsics are identical (ids 1, 2, ...).
// View::name is file_path as resolved (leading "./" removed); Scene::image_root is the JSON
// file's folder. Errors name the file and the JSON field: "transforms.json: frames[3].fl_x: ...".
//
// Writing: one shared camera goes to the top level, otherwise every frame gets its intrinsics.
// Keys written: camera_model, fl_x, fl_y, cx, cy, w, h, camera_angle_x, camera_angle_y (for
// NeRF-synthetic loaders), the model's distortion keys, and per frame file_path (with extension;
// note the original NeRF-synthetic loader appends ".png" itself), mask_path, transform_matrix.
// SIMPLE_PINHOLE/PINHOLE are written as "PINHOLE", SIMPLE_RADIAL/RADIAL/OPENCV and FULL_OPENCV
// with k4 = k5 = k6 = 0 as "OPENCV", OPENCV_FISHEYE/SIMPLE_RADIAL_FISHEYE/RADIAL_FISHEYE as
// "OPENCV_FISHEYE" (identical projections); FOV, THIN_PRISM_FISHEYE and rational FULL_OPENCV
// cannot be written (Error). file_path is image_path relative to the JSON file's folder
// (absolute when there is no relative path, e.g. another drive).
//
// Thread safety: reentrant; concurrent writes must go to different paths.
#pragma once

#include <filesystem>
#include <istream>
#include <string>
#include <string_view>

#include "rephoto/scene/reader_util.h"
#include "rephoto/scene/scene.h"

namespace rephoto::scene {

// Reads `path`; image sizes (when w/h are absent) from the image files next to it.
//
// Image names (scene/image_name.h): file_path and mask_path are relative to the folder of
// transforms.json, as the format defines, and must stay inside the image root: that folder
// itself, or `image_root` when given (--image-root), which lets a transforms.json in a subfolder
// name photos beside it ("../images/a.png", as `rephoto split` writes). View names are then
// relative to `image_root`. Absolute paths are refused either way.
Scene ReadTransformsJson(const std::filesystem::path& path,
                         const std::filesystem::path& image_root = {});

// Reads from a stream. `name` is used in messages; file_path entries are relative to
// `base_dir`; `image_size` is asked for the size of the first frame's image (by its resolved
// name) when w/h are absent; extensionless file_path entries are resolved against files under
// `base_dir` as described above.
Scene ReadTransformsJson(std::istream& in, std::string_view name,
                         const std::filesystem::path& base_dir, const ImageSizeLookup& image_size,
                         const std::filesystem::path& image_root = {});

// The JSON text for `scene` with file paths relative to `base_dir` (see above).
std::string TransformsJsonFromScene(const Scene& scene, const std::filesystem::path& base_dir);

// Writes TransformsJsonFromScene(scene, path.parent_path()) to `path` atomically.
void WriteTransformsJson(const Scene& scene, const std::filesystem::path& path);

}  // namespace rephoto::scene
