#include "rephoto/scene/read_scene.h"

#include <algorithm>
#include <set>

#include "rephoto/core/error.h"
#include "rephoto/io/image_io.h"
#include "rephoto/scene/bundler.h"
#include "rephoto/scene/cameras_json.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/middlebury.h"
#include "rephoto/scene/mve.h"
#include "rephoto/scene/mvs_texturing_cam.h"
#include "rephoto/scene/strecha.h"
#include "rephoto/scene/transforms_json.h"

namespace rephoto::scene {

namespace fs = std::filesystem;

namespace {

constexpr SceneFormat kAllFormats[] = {SceneFormat::kColmap,      SceneFormat::kTransforms,
                                       SceneFormat::kCamerasJson, SceneFormat::kBundler,
                                       SceneFormat::kMiddlebury,  SceneFormat::kStrecha,
                                       SceneFormat::kMve,         SceneFormat::kMvsTexturing};

// Regular files in `folder` whose name ends with `suffix`, sorted.
std::vector<fs::path> FilesEndingWith(const fs::path& folder, std::string_view suffix) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    std::error_code type_ec;
    if (name.size() > suffix.size() && name.ends_with(suffix) && entry.is_regular_file(type_ec)) {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

std::vector<fs::path> Subfolders(const fs::path& folder) {
  std::vector<fs::path> folders;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    std::error_code type_ec;
    if (entry.is_directory(type_ec)) folders.push_back(entry.path());
  }
  std::sort(folders.begin(), folders.end());
  return folders;
}

bool IsFile(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}
bool IsFolder(const fs::path& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

// Each Try* returns the reader's input for `path` if it holds that format, std::nullopt if
// not, and throws when it is that format but ambiguous.
std::optional<fs::path> TryColmap(const fs::path& path) {
  if (IsFile(path)) {
    const std::string name = path.filename().string();
    for (const char* file : {"cameras", "images", "points3D"}) {
      if (name == std::string(file) + ".txt" || name == std::string(file) + ".bin") {
        return path.parent_path();
      }
    }
    return std::nullopt;
  }
  for (const fs::path& folder : {path, path / "sparse" / "0", path / "sparse"}) {
    if (IsFolder(folder) && DetectColmapFormat(folder)) return folder;
  }
  return std::nullopt;
}

std::optional<fs::path> TryTransforms(const fs::path& path) {
  if (IsFile(path)) {
    // A JSON array is a 3DGS cameras.json, not a transforms.json object.
    if (path.extension() == ".json" && !IsCamerasJsonFile(path)) return path;
    return std::nullopt;
  }
  if (IsFile(path / "transforms.json")) return path / "transforms.json";
  return std::nullopt;
}

std::optional<fs::path> TryCamerasJson(const fs::path& path) {
  if (IsFile(path)) {
    if (IsCamerasJsonFile(path)) return path;
    return std::nullopt;
  }
  if (IsCamerasJsonFile(path / "cameras.json")) return path / "cameras.json";
  return std::nullopt;
}

std::optional<fs::path> TryBundler(const fs::path& path) {
  if (IsFile(path)) {
    if (path.extension() == ".out") return path;
    return std::nullopt;
  }
  for (const fs::path& file : {path / "bundle.out", path / "bundle" / "bundle.out"}) {
    if (IsFile(file)) return file;
  }
  if (IsFile(path / "list.txt")) {
    std::vector<fs::path> bundles;
    for (const fs::path& folder : Subfolders(path)) {
      if (IsFile(folder / "bundle.out")) bundles.push_back(folder / "bundle.out");
    }
    if (bundles.size() == 1) return bundles.front();
    REPHOTO_CHECK(bundles.size() < 2, "{}: several bundle.out files ({} and {}); pass one of them",
                  path.string(), bundles[0].string(), bundles[1].string());
  }
  return std::nullopt;
}

std::optional<fs::path> TryMiddlebury(const fs::path& path) {
  if (IsFile(path)) {
    if (path.filename().string().ends_with("_par.txt")) return path;
    return std::nullopt;
  }
  const std::vector<fs::path> files = FilesEndingWith(path, "_par.txt");
  REPHOTO_CHECK(files.size() < 2, "{}: several Middlebury camera files ({}, {}); pass one of them",
                path.string(), files.size() > 0 ? files[0].filename().string() : "",
                files.size() > 1 ? files[1].filename().string() : "");
  if (files.size() == 1) return files.front();
  return std::nullopt;
}

std::optional<fs::path> TryStrecha(const fs::path& path) {
  if (IsFile(path)) {
    if (path.extension() == ".camera") return path.parent_path();
    return std::nullopt;
  }
  if (!FilesEndingWith(path, ".camera").empty()) return path;
  std::vector<fs::path> folders;
  for (const fs::path& folder : Subfolders(path)) {
    if (!FilesEndingWith(folder, ".camera").empty()) folders.push_back(folder);
  }
  REPHOTO_CHECK(folders.size() < 2, "{}: several folders of .camera files ({}, {}); pass one",
                path.string(), folders.size() > 0 ? folders[0].string() : "",
                folders.size() > 1 ? folders[1].string() : "");
  if (folders.size() == 1) return folders.front();
  return std::nullopt;
}

bool HasMveViews(const fs::path& views) {
  for (const fs::path& folder : Subfolders(views)) {
    if (folder.extension() == ".mve") return true;
  }
  return false;
}

std::optional<fs::path> TryMve(const fs::path& path) {
  fs::path folder = path;
  if (IsFile(path)) {
    if (path.filename() != "meta.ini") return std::nullopt;
    folder = path.parent_path();
  }
  if (folder.extension() == ".mve" && IsFile(folder / "meta.ini")) folder = folder.parent_path();
  if (IsFolder(folder / "views") && HasMveViews(folder / "views")) return folder;
  if (folder.filename() == "views" && HasMveViews(folder)) return folder.parent_path();
  return std::nullopt;
}

std::optional<fs::path> TryMvsTexturing(const fs::path& path) {
  if (IsFile(path)) {
    if (path.extension() == ".cam") return path.parent_path();
    return std::nullopt;
  }
  if (!FilesEndingWith(path, ".cam").empty()) return path;
  return std::nullopt;
}

std::optional<fs::path> TryFormat(SceneFormat format, const fs::path& path) {
  switch (format) {
    case SceneFormat::kColmap:
      return TryColmap(path);
    case SceneFormat::kTransforms:
      return TryTransforms(path);
    case SceneFormat::kCamerasJson:
      return TryCamerasJson(path);
    case SceneFormat::kBundler:
      return TryBundler(path);
    case SceneFormat::kMiddlebury:
      return TryMiddlebury(path);
    case SceneFormat::kStrecha:
      return TryStrecha(path);
    case SceneFormat::kMve:
      return TryMve(path);
    case SceneFormat::kMvsTexturing:
      return TryMvsTexturing(path);
  }
  return std::nullopt;
}

std::string_view LookedFor(SceneFormat format) {
  switch (format) {
    case SceneFormat::kColmap:
      return "cameras/images/points3D .txt or .bin (also in sparse/0, sparse)";
    case SceneFormat::kTransforms:
      return "transforms.json";
    case SceneFormat::kCamerasJson:
      return "cameras.json (a 3D Gaussian splatting output folder)";
    case SceneFormat::kBundler:
      return "bundle.out (also bundle/bundle.out, */bundle.out next to list.txt)";
    case SceneFormat::kMiddlebury:
      return "*_par.txt";
    case SceneFormat::kStrecha:
      return "*.camera (also in one subfolder)";
    case SceneFormat::kMve:
      return "views/view_XXXX.mve";
    case SceneFormat::kMvsTexturing:
      return "*.cam";
  }
  return "";
}

}  // namespace

std::string_view SceneFormatName(SceneFormat format) {
  switch (format) {
    case SceneFormat::kColmap:
      return "colmap";
    case SceneFormat::kTransforms:
      return "transforms";
    case SceneFormat::kCamerasJson:
      return "cameras-json";
    case SceneFormat::kBundler:
      return "bundler";
    case SceneFormat::kMiddlebury:
      return "middlebury";
    case SceneFormat::kStrecha:
      return "strecha";
    case SceneFormat::kMve:
      return "mve";
    case SceneFormat::kMvsTexturing:
      return "mvs-texturing";
  }
  return "unknown";
}

std::optional<SceneFormat> ParseSceneFormat(std::string_view name) {
  for (SceneFormat format : kAllFormats) {
    if (name == SceneFormatName(format)) return format;
  }
  if (name == "transforms.json" || name == "nerf") return SceneFormat::kTransforms;
  if (name == "cameras.json" || name == "3dgs") return SceneFormat::kCamerasJson;
  if (name == "mvs_texturing" || name == "cam") return SceneFormat::kMvsTexturing;
  return std::nullopt;
}

std::string SceneFormatList() {
  std::string list;
  for (SceneFormat format : kAllFormats) {
    if (!list.empty()) list += ", ";
    list += SceneFormatName(format);
  }
  return list;
}

SceneSource DetectSceneFormat(const fs::path& path) {
  std::error_code ec;
  REPHOTO_CHECK(fs::exists(path, ec), "{}: no such file or folder", path.string());
  for (SceneFormat format : kAllFormats) {
    if (auto source = TryFormat(format, path)) return {format, *source};
  }
  std::string looked_for;
  for (SceneFormat format : kAllFormats) {
    looked_for += fmt::format("{}{}: {}", looked_for.empty() ? "" : "; ", SceneFormatName(format),
                              LookedFor(format));
  }
  ThrowError("{}: cannot detect the scene format (looked for {}); pass --format with one of: {}",
             path.string(), looked_for, SceneFormatList());
}

SceneSource ResolveSceneSource(const fs::path& path, SceneFormat format) {
  std::error_code ec;
  REPHOTO_CHECK(fs::exists(path, ec), "{}: no such file or folder", path.string());
  if (auto source = TryFormat(format, path)) return {format, *source};
  ThrowError("{}: no {} scene here (looked for {})", path.string(), SceneFormatName(format),
             LookedFor(format));
}

void ValidateScene(const Scene& scene, std::string_view context) {
  for (const auto& [id, camera] : scene.cameras) {
    camera.Validate(fmt::format("{}: camera {}", context, id));
  }
  std::set<std::string_view> names;
  for (size_t i = 0; i < scene.views.size(); ++i) {
    const View& view = scene.views[i];
    const std::string where = fmt::format("{}: view {} ({})", context, i, view.name);
    REPHOTO_CHECK(!view.name.empty(), "{}: empty image name", where);
    REPHOTO_CHECK(CheckedImageName(view.name, where) == view.name,
                  "{}: image name is not in normal form", where);
    REPHOTO_CHECK(names.insert(view.name).second, "{}: image name used by two views", where);
    REPHOTO_CHECK(scene.cameras.count(view.camera_id) == 1, "{}: camera id {} does not exist",
                  where, view.camera_id);
    view.cam_from_world.Validate(where);
  }
  for (size_t i = 0; i < scene.points.size(); ++i) {
    const Point3D& point = scene.points[i];
    REPHOTO_CHECK(point.position.allFinite(), "{}: point {} is not finite", context, i);
    for (const Observation& observation : point.track) {
      REPHOTO_CHECK(observation.view_index >= 0 &&
                        static_cast<size_t>(observation.view_index) < scene.views.size(),
                    "{}: point {} is observed in view {}, which does not exist", context, i,
                    observation.view_index);
      REPHOTO_CHECK(observation.pixel.allFinite(), "{}: point {}: observation not finite", context,
                    i);
    }
  }
}

std::vector<std::string> MissingImages(const Scene& scene) {
  std::vector<std::string> missing;
  for (const View& view : scene.views) {
    std::error_code ec;
    if (!fs::exists(view.image_path, ec)) missing.push_back(view.name);
  }
  return missing;
}

void CheckImageSizes(const Scene& scene, std::string_view context) {
  for (const View& view : scene.views) {
    std::error_code ec;
    if (!fs::is_regular_file(view.image_path, ec)) continue;
    const io::ImageHeader header = io::ReadImageHeader(view.image_path);
    const camera::Camera& camera = scene.CameraOf(view);
    REPHOTO_CHECK(header.width == camera.width && header.height == camera.height,
                  "{}: image is {}x{} but camera {} of {} says {}x{}", view.image_path.string(),
                  header.width, header.height, view.camera_id, context, camera.width,
                  camera.height);
  }
}

Scene ReadScene(const fs::path& path, const ReadSceneOptions& options, SceneSource* detected) {
  const SceneSource source =
      options.format ? ResolveSceneSource(path, *options.format) : DetectSceneFormat(path);
  if (detected != nullptr) *detected = source;
  Scene scene;
  switch (source.format) {
    case SceneFormat::kColmap: {
      ColmapReadOptions colmap_options;
      colmap_options.image_root = options.image_root;
      scene = ReadColmap(source.path, colmap_options);
      break;
    }
    case SceneFormat::kTransforms:
      scene = ReadTransformsJson(source.path, options.image_root.value_or(fs::path()));
      break;
    case SceneFormat::kCamerasJson:
      scene = ReadCamerasJson(source.path);
      break;
    case SceneFormat::kBundler:
      scene = ReadBundlerScene(source.path);
      break;
    case SceneFormat::kMiddlebury:
      scene = ReadMiddleburyScene(source.path);
      break;
    case SceneFormat::kStrecha:
      scene = ReadStrechaScene(source.path);
      break;
    case SceneFormat::kMve:
      scene = ReadMveScene(source.path);
      break;
    case SceneFormat::kMvsTexturing:
      scene = ReadMvsTexturingScene(source.path);
      break;
  }
  if (options.image_root && source.format != SceneFormat::kColmap &&
      source.format != SceneFormat::kTransforms) {
    scene.image_root = *options.image_root;
    for (View& view : scene.views) view.image_path = scene.image_root / view.name;
  }
  const std::string context = source.path.string();
  ValidateScene(scene, context);
  if (options.check_image_sizes) CheckImageSizes(scene, context);
  return scene;
}

}  // namespace rephoto::scene
