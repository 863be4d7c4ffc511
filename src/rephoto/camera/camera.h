// Cameras: intrinsics with distortion (COLMAP's models, names and parameter order) and poses.
//
// Conventions (one set, everywhere in rephoto; readers convert at the I/O boundary):
// - Camera frame: x right, y down, z forward (the camera looks along +z), as OpenCV/COLMAP.
// - Pose: cam_from_world, x_cam = rotation * x_world + translation. The camera centre in world
//   coordinates is -rotation^T * translation.
// - Pixel coordinates: (0,0) is the top-left corner of the top-left pixel; that pixel's centre is
//   (0.5, 0.5) (COLMAP's convention). Principal points are given in this convention.
// - Parameter order per model exactly as COLMAP's cameras.txt:
//   SIMPLE_PINHOLE f,cx,cy | PINHOLE fx,fy,cx,cy | SIMPLE_RADIAL f,cx,cy,k | RADIAL f,cx,cy,k1,k2 |
//   OPENCV fx,fy,cx,cy,k1,k2,p1,p2 | OPENCV_FISHEYE fx,fy,cx,cy,k1,k2,k3,k4 |
//   FULL_OPENCV fx,fy,cx,cy,k1,k2,p1,p2,k3,k4,k5,k6 | FOV fx,fy,cx,cy,omega |
//   SIMPLE_RADIAL_FISHEYE f,cx,cy,k | RADIAL_FISHEYE f,cx,cy,k1,k2 |
//   THIN_PRISM_FISHEYE fx,fy,cx,cy,k1,k2,p1,p2,k3,k4,sx1,sy1
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rephoto::camera {

// Values are COLMAP's model ids (as stored in cameras.bin).
enum class CameraModel : int {
  kSimplePinhole = 0,
  kPinhole = 1,
  kSimpleRadial = 2,
  kRadial = 3,
  kOpenCv = 4,
  kOpenCvFisheye = 5,
  kFullOpenCv = 6,
  kFov = 7,
  kSimpleRadialFisheye = 8,
  kRadialFisheye = 9,
  kThinPrismFisheye = 10,
};

// "PINHOLE" etc. (COLMAP spelling).
std::string_view CameraModelName(CameraModel model);
// Parses a COLMAP model name (exact, upper case); std::nullopt if unknown.
std::optional<CameraModel> ParseCameraModel(std::string_view name);
// From a COLMAP model id; std::nullopt if unknown.
std::optional<CameraModel> CameraModelFromId(int id);
// Number of parameters the model takes.
int CameraModelParamCount(CameraModel model);

// Intrinsics. ImgFromCam/CamFromImg/Scaled throw Error when `params` has the wrong length for
// `model` (call Validate once after reading); all other failures are std::nullopt. They are
// const, allocate nothing and are safe to call from many threads.
struct Camera {
  CameraModel model = CameraModel::kPinhole;
  int width = 0;  // image size in pixels the intrinsics refer to
  int height = 0;
  std::vector<double> params;  // COLMAP order, see above

  // Projects a point given in camera coordinates to pixel coordinates, applying distortion
  // with COLMAP's formulas (sensor/models.h): normalized (u, v) = (x/z, y/z); fisheye models
  // first map (u, v) to (u, v) * theta / r with r = |(u, v)|, theta = atan(r); then the model's
  // distortion; then pixel = (fx * u' + cx, fy * v' + cy).
  // std::nullopt when z < machine epsilon (at or behind the camera plane, or NaN) or the
  // result is not finite. Does not check that the pixel lies inside the image, nor that the
  // point lies in the usable field of view (where the distortion is still one-to-one).
  std::optional<Eigen::Vector2d> ImgFromCam(const Eigen::Vector3d& point_in_cam) const;

  // The unit viewing ray (camera coordinates, z > 0) through a pixel position: the inverse of
  // ImgFromCam. Distortion is inverted by Newton's method with an exact Jacobian (forward-mode
  // derivatives of the distortion) and a trust region, started at the distorted position; FOV
  // is inverted in closed form. std::nullopt when the residual does not fall below 1e-10
  // normalized units within 100 iterations, when the solution lies where the distortion folds
  // over (Jacobian determinant <= 0, i.e. outside the usable field of view), or when the ray
  // would not point forward (fisheye theta >= pi/2, FOV angle >= pi/2).
  std::optional<Eigen::Vector3d> CamFromImg(const Eigen::Vector2d& pixel) const;

  // The same camera for an image of another resolution (e.g. a downsampled photo): with
  // sx = new_width / width, sy = new_height / height, fx *= sx, fy *= sy (a single focal
  // length scales by (sx + sy) / 2, as COLMAP's Rescale), cx *= sx, cy *= sy. Scaling about
  // the origin is right because pixel coordinates use the corner convention: the image corner
  // (width, height) maps to (new_width, new_height) and the centre to the centre. Distortion
  // coefficients act on normalized coordinates and stay. Throws Error when a size is <= 0.
  Camera Scaled(int new_width, int new_height) const;

  // Focal lengths in pixels along x and y (equal for single-focal models).
  double FocalLengthX() const;
  double FocalLengthY() const;
  // Mean focal length in pixels (for fields of view, splat radii, ...).
  double MeanFocalLength() const;
  double PrincipalPointX() const;
  double PrincipalPointY() const;
  bool IsPinhole() const;  // no distortion (SIMPLE_PINHOLE, PINHOLE)
  // Fisheye models (OPENCV_FISHEYE, SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE, THIN_PRISM_FISHEYE):
  // distortion acts on the angle theta = atan(r) instead of r = |(x/z, y/z)|.
  bool IsFisheye() const;

  bool operator==(const Camera&) const = default;

  // Throws Error (prefixed with `context`) when the size is not positive, the parameter count
  // does not match the model, a value is NaN/inf, or a focal length is <= 0.
  void Validate(std::string_view context) const;
};

// The part of a camera's view where its lens model is one-to-one: the disc around the optical
// axis, in the distortion's input coordinates (normalized x/z, y/z; for fisheye models the angle
// theta from the axis), inside which the distortion's Jacobian determinant stays positive along
// every direction. Farther out the distortion folds points that the lens never images back into
// the picture (strong barrel distortion: a point at 80 degrees can project next to the centre),
// so visibility tests reject them. Found by marching 64 directions outward in steps of 0.5 %
// from 0.001 to 20 (87 degrees; fisheye: theta up to pi/2); the radius is the last step before
// the first non-positive determinant, so it errs on the inside by at most 0.5 %.
// Pinhole models and FOV: the whole forward half-space. Immutable after construction:
// thread-safe.
class UsableField {
 public:
  explicit UsableField(const Camera& camera);
  // True when `point_in_cam` lies in front of the camera (z > 0) inside the disc.
  [[gnu::always_inline]] bool Contains(const Eigen::Vector3d& point_in_cam) const {
    if (!(point_in_cam.z() > 0)) return false;
    if (radius_ == std::numeric_limits<double>::infinity()) return true;
    const double u = point_in_cam.x() / point_in_cam.z(), v = point_in_cam.y() / point_in_cam.z();
    const double r = std::sqrt(u * u + v * v);
    return (fisheye_ ? std::atan(r) : r) < radius_;
  }
  // The disc's radius (+inf: no limit).
  double radius() const { return radius_; }

 private:
  bool fisheye_ = false;
  double radius_ = 0;
};

// cam_from_world rigid transform.
struct Pose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d CamFromWorld(const Eigen::Vector3d& world) const {
    return rotation * world + translation;
  }
  Eigen::Vector3d Center() const { return -rotation.transpose() * translation; }
  // Viewing direction (+z of the camera) in world coordinates.
  Eigen::Vector3d ViewDirection() const { return rotation.row(2).transpose(); }
  // The unit quaternion (w, x, y, z) of `rotation`, w >= 0 (COLMAP's storage order).
  Eigen::Vector4d Quaternion() const;
  // From a unit quaternion (w, x, y, z) as COLMAP stores it (Hamilton convention, rotating
  // world into camera coordinates), and a translation. The quaternion is normalized first;
  // readers check beforehand that its norm is 1 within their file's precision. A zero
  // quaternion gives a NaN rotation, which Validate rejects.
  static Pose FromQuaternion(double qw, double qx, double qy, double qz,
                             const Eigen::Vector3d& translation);
  // Throws Error (prefixed with `context`) when a value is NaN/inf or rotation is not a proper
  // rotation: some entry of R^T R - I above 1e-6 in magnitude, or determinant <= 0. Readers of
  // files that print rotations with few digits repair them with NearestRotation first.
  void Validate(std::string_view context) const;

  bool operator==(const Pose&) const = default;
};

// The rotation closest to `matrix` (Frobenius norm, via SVD), for rotations read from files
// that print few digits. Throws Error (prefixed with `context`) when a value is NaN/inf, when
// some entry of matrix^T * matrix - I exceeds `tolerance` in magnitude (not a rotation), or
// when the determinant is negative (a reflection).
Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& matrix, double tolerance,
                                std::string_view context);

// The image size whose shorter side is `short_side`, the other side scaled in proportion and
// rounded (never larger than width x height; short_side <= 0 = unchanged): what
// `--eval-short-side`/`--train-short-side` resize photos and cameras (Camera::Scaled) to.
std::pair<int, int> ScaledSize(int width, int height, int short_side);

// The pose of a camera at `center` looking at `target` (COLMAP's frame: x right, y down, z
// forward), without roll: the image's y axis points along -up. When the view direction is
// within 1e-6 of parallel to `up`, up is replaced by the x axis (or the y axis when the view
// is along x). `center` must differ from `target`.
Pose LookAt(const Eigen::Vector3d& center, const Eigen::Vector3d& target,
            Eigen::Vector3d up = Eigen::Vector3d::UnitZ());

}  // namespace rephoto::camera
