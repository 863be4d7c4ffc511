// One entry point for every scene format rephoto reads, with the format detection in one place.
//
// Formats (name for --format: what the path may be):
//   colmap        COLMAP sparse model: a folder with cameras/images/points3D .bin or .txt, or a
//                 project folder with sparse/0 or sparse/, or one of the model files.
//   transforms    transforms.json (NeRF-synthetic, instant-ngp, nerfstudio), or a folder with it.
//   cameras-json  cameras.json of a 3D Gaussian splatting output folder (a JSON array, see
//                 cameras_json.h), or the folder with it.
//   bundler       bundle.out (+ list.txt beside it or in its parent folder), or a folder with
//                 bundle.out, bundle/bundle.out, or list.txt and exactly one */bundle.out.
//   middlebury    a *_par.txt file, or a folder with exactly one *_par.txt.
//   strecha       a folder of <image>.camera files (or one of them), or a folder with exactly
//                 one subfolder holding .camera files (e.g. gt_dense_cameras/).
//   mve           an MVE scene folder (with views/view_XXXX.mve/), the views folder, a view
//                 folder or its meta.ini.
//   mvs-texturing a folder of <image>.cam files next to their images, or one .cam file.
// Detection tries the formats in this order and takes the first that matches; --format skips
// detection. When nothing matches, the Error lists what was looked for and the format names.
//
// Every scene returned has passed ValidateScene. Images missing on disk are not an error here
// (MissingImages lists them); an image that exists but whose size differs from its camera's
// is (CheckImageSizes), unless disabled.
//
// Thread safety: reentrant (no shared state; warnings go through the thread-safe log).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/scene/scene.h"

namespace rephoto::scene {

enum class SceneFormat {
  kColmap,
  kTransforms,
  kCamerasJson,
  kBundler,
  kMiddlebury,
  kStrecha,
  kMve,
  kMvsTexturing
};

// "colmap", "transforms", "cameras-json", "bundler", "middlebury", "strecha", "mve",
// "mvs-texturing".
std::string_view SceneFormatName(SceneFormat format);
// Parses a name above (also accepts "transforms.json", "nerf", "cameras.json", "3dgs",
// "mvs_texturing", "cam"); nullopt
// if unknown.
std::optional<SceneFormat> ParseSceneFormat(std::string_view name);
// "colmap, transforms, bundler, ..." for messages and --help.
std::string SceneFormatList();

// A format and the file or folder its reader takes.
struct SceneSource {
  SceneFormat format = SceneFormat::kColmap;
  std::filesystem::path path;
};

// Detects the format of `path` (see above). Throws Error "<path>: ..." when the path does not
// exist, is ambiguous within a format (two *_par.txt), or matches no format.
SceneSource DetectSceneFormat(const std::filesystem::path& path);

// The file or folder the reader of `format` takes for `path` (a user-given --format). Throws
// Error naming the path and the format when `path` has no such scene.
SceneSource ResolveSceneSource(const std::filesystem::path& path, SceneFormat format);

struct ReadSceneOptions {
  std::optional<SceneFormat> format;  // skip detection
  // Folder the image names are relative to, instead of the format's default (COLMAP: the
  // project's images/ folder). For formats whose reader needs the images (to learn their
  // size) the images are still read at the default place; only the paths are re-rooted.
  // transforms.json is the exception: its file paths stay relative to its own folder, as the
  // format defines, and the image root is the folder they must stay inside (see
  // ReadTransformsJson). Every format's names follow scene/image_name.h.
  std::optional<std::filesystem::path> image_root;
  // Check that every image that exists on disk has its camera's size (CheckImageSizes).
  bool check_image_sizes = true;
};

// Reads a scene of any supported format. `detected` (optional) receives the format and path.
Scene ReadScene(const std::filesystem::path& path, const ReadSceneOptions& options = {},
                SceneSource* detected = nullptr);

// Throws Error "<context>: ..." when a camera or pose is invalid (Validate), a view refers to
// a camera id that does not exist, two views share a name, a view name is empty, a point is
// not finite, or an observation refers to a view index out of range or is not finite.
void ValidateScene(const Scene& scene, std::string_view context);

// Names of the views whose image_path does not exist.
std::vector<std::string> MissingImages(const Scene& scene);

// For every view whose image exists, reads the image header and throws Error
// "<image path>: image is WxH but camera <id> (<context>) is wxh" when the sizes differ.
void CheckImageSizes(const Scene& scene, std::string_view context);

}  // namespace rephoto::scene
