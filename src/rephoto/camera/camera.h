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
#include <optional>
#include <string>
#include <string_view>
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

struct Camera {
  CameraModel model = CameraModel::kPinhole;
  int width = 0;   // image size in pixels the intrinsics refer to
  int height = 0;
  std::vector<double> params;  // COLMAP order, see above

  // Projects a point given in camera coordinates to pixel coordinates, applying distortion.
  // std::nullopt when the point is at or behind the camera plane (z <= 0) or the model cannot
  // represent it. Does not check that the pixel lies inside the image.
  std::optional<Eigen::Vector2d> ImgFromCam(const Eigen::Vector3d& point_in_cam) const;

  // The unit viewing ray (camera coordinates, z > 0) through a pixel position, undistorting
  // iteratively. std::nullopt when the undistortion does not converge to 1e-10 normalized
  // units (e.g. outside the model's usable field of view).
  std::optional<Eigen::Vector3d> CamFromImg(const Eigen::Vector2d& pixel) const;

  // The same camera for an image of another resolution: focal lengths and principal point
  // scale with the image (pixel-corner convention), distortion coefficients stay.
  Camera Scaled(int new_width, int new_height) const;

  // Mean focal length in pixels (for fields of view, splat radii, ...).
  double MeanFocalLength() const;
  double PrincipalPointX() const;
  double PrincipalPointY() const;
  bool IsPinhole() const;  // no distortion (SIMPLE_PINHOLE, PINHOLE)

  // Throws Error (prefixed with `context`) when the size is not positive, the parameter count
  // does not match the model, a value is NaN/inf, or a focal length is <= 0.
  void Validate(std::string_view context) const;
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
  // From a unit quaternion (w, x, y, z) as COLMAP stores it, and a translation.
  static Pose FromQuaternion(double qw, double qx, double qy, double qz,
                             const Eigen::Vector3d& translation);
  // Throws Error (prefixed with `context`) when a value is NaN/inf or rotation is not a proper
  // rotation (orthonormal to 1e-6 after the file's precision, determinant +1).
  void Validate(std::string_view context) const;
};

}  // namespace rephoto::camera
