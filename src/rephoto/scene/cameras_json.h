// cameras.json of a graphdeco 3D Gaussian splatting output folder (train.py's
// scene/__init__.py, camera_to_JSON), also written by forks that keep its layout.
//
// The file is a JSON array, one object per camera (train and test):
//   {"id": 0, "img_name": "DSC0001", "width": 1959, "height": 1090,
//    "position": [x, y, z], "rotation": [[r00, r01, r02], [r10, ...], [...]],
//    "fx": 1159.5, "fy": 1164.7}
// - rotation is camera-to-world (its columns are the camera axes in the world) and position the
//   camera centre, in COLMAP/OpenCV camera axes (x right, y down, z forward): 3DGS converts
//   Blender/NeRF-synthetic poses to those axes before writing. So cam_from_world has rotation
//   R = rotation^T and translation -R * position.
// - fx, fy in pixels at width x height, the original image resolution (3DGS writes the
//   cameras before its -r downscaling). 3DGS assumes the principal point at the image centre:
//   cx = width / 2, cy = height / 2 in rephoto's corner convention (optional "cx", "cy" keys,
//   written by some forks, are used when present). The camera model is PINHOLE (3DGS trains on
//   undistorted images).
// - img_name has no extension. Images are looked up in the image folder: --image-root when given,
//   else source_path/images from the cfg_args file next to cameras.json (train.py writes it:
//   "Namespace(... source_path='/data/garden', ... images='images', ...)") when that folder
//   exists, else the folder of cameras.json. View::name is img_name plus the extension of the
//   first of img_name, .png, .jpg, .JPG, .jpeg, .JPEG, .exr that exists there (img_name alone
//   when none does: photos and rephotos are paired by file stem).
// Views are in file order; cameras are shared where intrinsics are identical. Errors name the
// file and the entry: "cameras.json: [3].rotation: expected 3 rows of 3 numbers".
//
// Thread safety: reentrant (no shared state; warnings go through the thread-safe log).
#pragma once

#include <filesystem>
#include <istream>
#include <string_view>

#include "rephoto/scene/scene.h"

namespace rephoto::scene {

Scene ReadCamerasJson(const std::filesystem::path& path);

// From a stream: `name` prefixes errors, `image_root` is the image folder (see above).
Scene ReadCamerasJson(std::istream& in, std::string_view name,
                      const std::filesystem::path& image_root);

// True when `path` is a .json file whose first non-blank character is '[' (a cameras.json
// array; transforms.json files are objects).
bool IsCamerasJsonFile(const std::filesystem::path& path);

}  // namespace rephoto::scene
