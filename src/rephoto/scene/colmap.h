// COLMAP sparse models: cameras, images and points3D, in COLMAP's text (cameras.txt,
// images.txt, points3D.txt) and binary (cameras.bin, images.bin, points3D.bin) layouts, exactly
// as colmap/scene/reconstruction_io_{text,binary}.cc read and write them (the legacy model
// without rigs.* and frames.*; those files, when present, are ignored).
//
// Two levels:
// - Records (ColmapModel): the files' content with COLMAP's ids, read from and written to
//   streams, so tests parse strings. Each reader checks what a single file can check (syntax,
//   NaN/inf, parameter counts, unknown models, unit quaternions, duplicate ids, truncation).
// - Scene: SceneFromColmap links the records (camera ids, track image ids, POINT2D indices) and
//   converts to rephoto's Scene; ReadColmap/WriteColmap do everything for a model folder.
//
// Conventions: COLMAP already uses rephoto's (cam_from_world, x right, y down, z forward,
// pixel (0,0) = corner of the top-left pixel), so poses and pixels are taken as they are.
// Every error is a rephoto::Error naming the file and the line (text: "images.txt:12: ...")
// or the record (binary: "images.bin: record 3 (byte 812): ...").
//
// Thread safety: reentrant; concurrent reads are fine, concurrent writes must go to different
// folders.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <istream>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/scene/scene.h"

namespace rephoto::scene {

// One line pair of images.txt / one record of images.bin.
struct ColmapImage {
  uint32_t image_id = 0;
  Eigen::Vector4d quaternion = {1, 0, 0, 0};  // cam_from_world rotation (w, x, y, z), unit
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // cam_from_world translation
  uint32_t camera_id = 0;
  std::string name;  // relative to the image folder
  // POINTS2D: keypoint positions (pixel-corner convention) and the 3D point each one
  // observes, kNoPoint3D for none (-1 in text).
  std::vector<Eigen::Vector2d> points2d;
  std::vector<uint64_t> point3d_ids;
  std::string where;  // "images.txt:12" / "images.bin: record 3", for later error messages

  static constexpr uint64_t kNoPoint3D = UINT64_MAX;
};

// One line of points3D.txt / one record of points3D.bin.
struct ColmapPoint3D {
  uint64_t point3d_id = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix<uint8_t, 3, 1> color = Eigen::Matrix<uint8_t, 3, 1>::Zero();
  double error = -1;  // mean reprojection error in pixels as stored (-1: unknown)
  // (image_id, point2D_idx): the POINTS2D entry of that image observing this point.
  std::vector<std::pair<uint32_t, uint32_t>> track;
  std::string where;
};

struct ColmapModel {
  std::map<uint32_t, camera::Camera> cameras;  // by camera_id, each Validate()d
  std::vector<ColmapImage> images;             // in file order
  std::vector<ColmapPoint3D> points;           // in file order
};

enum class ColmapFormat { kText, kBinary };

// Stream readers. `name` is used in error messages (usually the file path). They accept
// exactly what COLMAP writes: '#' comment lines and blank lines between records (text); in
// images.txt the line after an image line is always its POINTS2D line, even when empty. An
// image name is the rest of its line (COLMAP itself stops at the first space).
std::map<uint32_t, camera::Camera> ReadColmapCamerasText(std::istream& in, std::string_view name);
std::vector<ColmapImage> ReadColmapImagesText(std::istream& in, std::string_view name);
std::vector<ColmapPoint3D> ReadColmapPoints3DText(std::istream& in, std::string_view name);
std::map<uint32_t, camera::Camera> ReadColmapCamerasBinary(std::istream& in, std::string_view name);
std::vector<ColmapImage> ReadColmapImagesBinary(std::istream& in, std::string_view name);
std::vector<ColmapPoint3D> ReadColmapPoints3DBinary(std::istream& in, std::string_view name);

// Stream writers, COLMAP's layout (text: COLMAP's header comments, numbers printed in the
// shortest form that reads back to the same double; binary: little-endian). Cameras are
// written sorted by id, images and points in the given order.
void WriteColmapCamerasText(std::ostream& out, const std::map<uint32_t, camera::Camera>& cameras);
void WriteColmapImagesText(std::ostream& out, const std::vector<ColmapImage>& images);
void WriteColmapPoints3DText(std::ostream& out, const std::vector<ColmapPoint3D>& points);
void WriteColmapCamerasBinary(std::ostream& out, const std::map<uint32_t, camera::Camera>& cameras);
void WriteColmapImagesBinary(std::ostream& out, const std::vector<ColmapImage>& images);
void WriteColmapPoints3DBinary(std::ostream& out, const std::vector<ColmapPoint3D>& points);

// Reads cameras/images/points3D from a model folder: binary when all three .bin files exist
// (COLMAP's preference), otherwise text when all three .txt files exist; otherwise throws,
// naming what is missing.
ColmapModel ReadColmapModel(const std::filesystem::path& model_dir);
// Which format ReadColmapModel would read; std::nullopt when neither is complete.
std::optional<ColmapFormat> DetectColmapFormat(const std::filesystem::path& model_dir);

// Links and converts records into a Scene. View i is images[i] (file order); its image_path is
// image_root / name; cameras keep their ids. Points keep file order; each track element
// becomes an Observation with the view index and the pixel of POINTS2D[point2D_idx] of that
// image. Throws (naming the record) when an image refers to a missing camera id, a track to a
// missing image id or to a POINT2D index past that image's POINTS2D, a camera id does not fit
// in an int, or two images share an id or a name. The POINTS2D entries' own point3D ids are
// not cross-checked (the track is authoritative).
Scene SceneFromColmap(const ColmapModel& model, const std::filesystem::path& image_root);

// The records for a scene: camera ids kept, image_id = view index + 1, point3D_id = point
// index + 1, error = -1 (unknown). Each view's POINTS2D lists its observations in point order,
// so tracks refer to them by index. Throws when a view refers to a missing camera, an
// observation to a missing view, or a camera id is not positive.
ColmapModel ColmapFromScene(const Scene& scene);

// COLMAP's project layout is <project>/images with the model in <project>/sparse/<N> or
// <project>/sparse: the default image folder is <model_dir>/../../images when the model folder's
// name is a number (sparse/0), otherwise <model_dir>/../images. Paths are made absolute.
std::filesystem::path DefaultColmapImageRoot(const std::filesystem::path& model_dir);

struct ColmapReadOptions {
  // Folder the image names are relative to; DefaultColmapImageRoot(model_dir) if unset.
  std::optional<std::filesystem::path> image_root;
};

// ReadColmapModel + SceneFromColmap.
Scene ReadColmap(const std::filesystem::path& model_dir, const ColmapReadOptions& options = {});

// ColmapFromScene, then cameras/images/points3D.{txt|bin} into `model_dir` (created if
// missing), each written atomically.
void WriteColmap(const Scene& scene, const std::filesystem::path& model_dir, ColmapFormat format);

}  // namespace rephoto::scene
