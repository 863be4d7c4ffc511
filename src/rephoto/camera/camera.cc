#include "rephoto/camera/camera.h"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <array>
#include <cmath>
#include <limits>

#include "rephoto/camera/cam_to_image.h"
#include "rephoto/core/error.h"
#include "rephoto/core/limits.h"

namespace rephoto::camera {
namespace {

struct ModelInfo {
  CameraModel model;
  std::string_view name;
  int num_params;
  int num_focal;  // 1: f, cx, cy, ...  2: fx, fy, cx, cy, ...
  bool fisheye;
};

constexpr std::array<ModelInfo, 11> kModels = {{
    {CameraModel::kSimplePinhole, "SIMPLE_PINHOLE", 3, 1, false},
    {CameraModel::kPinhole, "PINHOLE", 4, 2, false},
    {CameraModel::kSimpleRadial, "SIMPLE_RADIAL", 4, 1, false},
    {CameraModel::kRadial, "RADIAL", 5, 1, false},
    {CameraModel::kOpenCv, "OPENCV", 8, 2, false},
    {CameraModel::kOpenCvFisheye, "OPENCV_FISHEYE", 8, 2, true},
    {CameraModel::kFullOpenCv, "FULL_OPENCV", 12, 2, false},
    {CameraModel::kFov, "FOV", 5, 2, false},
    {CameraModel::kSimpleRadialFisheye, "SIMPLE_RADIAL_FISHEYE", 4, 1, true},
    {CameraModel::kRadialFisheye, "RADIAL_FISHEYE", 5, 1, true},
    {CameraModel::kThinPrismFisheye, "THIN_PRISM_FISHEYE", 12, 2, true},
}};

// Returns nullptr for a value outside the enum (e.g. a cast from a bad file id).
const ModelInfo* FindModel(CameraModel model) {
  const int id = static_cast<int>(model);
  if (id < 0 || id >= static_cast<int>(kModels.size())) {
    return nullptr;
  }
  return &kModels[id];
}

const ModelInfo& Info(CameraModel model) {
  const ModelInfo* info = FindModel(model);
  REPHOTO_CHECK(info != nullptr, "unknown camera model id {}", static_cast<int>(model));
  return *info;
}

// A number with its derivatives with respect to the two normalized coordinates: enough
// forward-mode differentiation for the polynomial/rational distortion models, so Newton's
// method gets their exact Jacobian from the same code that distorts.
struct Dual {
  double v = 0;
  double d0 = 0;
  double d1 = 0;
};
inline Dual operator+(Dual a, Dual b) { return {a.v + b.v, a.d0 + b.d0, a.d1 + b.d1}; }
inline Dual operator-(Dual a, Dual b) { return {a.v - b.v, a.d0 - b.d0, a.d1 - b.d1}; }
inline Dual operator*(Dual a, Dual b) {
  return {a.v * b.v, a.d0 * b.v + a.v * b.d0, a.d1 * b.v + a.v * b.d1};
}
inline Dual operator/(Dual a, Dual b) {
  const double inv = 1.0 / b.v;
  return {a.v * inv, (a.d0 - a.v * inv * b.d0) * inv, (a.d1 - a.v * inv * b.d1) * inv};
}
inline Dual operator*(double s, Dual a) { return {s * a.v, s * a.d0, s * a.d1}; }
inline Dual operator+(double s, Dual a) { return {s + a.v, a.d0, a.d1}; }

// Inverse of FovDistort (COLMAP's FOVCameraModel::Undistortion); std::nullopt where the
// undistorted ray would reach or pass 90 degrees off the optical axis.
std::optional<Eigen::Vector2d> FovUndistort(double omega, double u, double v) {
  constexpr double kEpsilon = 1e-4;
  const double radius2 = u * u + v * v;
  const double omega2 = omega * omega;
  double factor;
  if (omega2 < kEpsilon) {
    factor = (omega2 * radius2) / 3.0 - omega2 / 12.0 + 1.0;
  } else if (radius2 < kEpsilon) {
    factor = (omega * (omega * omega * radius2 + 3.0)) / (6.0 * std::tan(omega / 2.0));
  } else {
    const double radius = std::sqrt(radius2);
    if (std::abs(radius * omega) >= M_PI / 2.0) {
      return std::nullopt;
    }
    factor = std::tan(radius * omega) / (radius * 2.0 * std::tan(omega / 2.0));
  }
  if (!(factor > 0) || !std::isfinite(factor)) {
    return std::nullopt;
  }
  return Eigen::Vector2d(u * factor, v * factor);
}

// Solves x + distortion(x) = target for x with Newton's method. Mirrors COLMAP's
// IterativeUndistortion (start at the target, trust region |step| <= max(0.1 |x|, 0.1)) but
// stops on the residual rather than the step: once it is below `kTolerance` a last step is
// taken, so the answer is accurate to rounding level.
std::optional<Eigen::Vector2d> Undistort(CameraModel model, const double* k,
                                         const Eigen::Vector2d& target) {
  constexpr int kMaxIterations = 100;
  constexpr double kTolerance = 1e-10;
  constexpr double kRelStepRadius = 0.1;
  constexpr double kStepRadius = 0.1;
  Eigen::Vector2d x = target;
  for (int iteration = 0; iteration <= kMaxIterations; ++iteration) {
    const Dual u{x.x(), 1.0, 0.0};
    const Dual v{x.y(), 0.0, 1.0};
    Dual du, dv;
    internal::Distortion(model, k, u, v, &du, &dv);
    const Eigen::Vector2d residual(x.x() + du.v - target.x(), x.y() + dv.v - target.y());
    Eigen::Matrix2d jacobian;
    jacobian << 1.0 + du.d0, du.d1, dv.d0, 1.0 + dv.d1;
    const double det = jacobian.determinant();
    if (!std::isfinite(residual.x()) || !std::isfinite(residual.y()) || !std::isfinite(det)) {
      return std::nullopt;
    }
    if (residual.norm() <= kTolerance) {
      // A root where the map folds over is not on the usable, one-to-one part of the image.
      if (det <= 0) {
        return std::nullopt;
      }
      // One more Newton step costs little and takes the error from ~1e-10 (quadratic
      // convergence) to rounding level.
      return Eigen::Vector2d(x - jacobian.partialPivLu().solve(residual));
    }
    if (iteration == kMaxIterations || det == 0) {
      break;
    }
    Eigen::Vector2d step = jacobian.partialPivLu().solve(residual);
    const double radius2 =
        std::max(x.squaredNorm() * kRelStepRadius * kRelStepRadius, kStepRadius * kStepRadius);
    const double step2 = step.squaredNorm();
    if (step2 > radius2) {
      step *= std::sqrt(radius2 / step2);
    }
    x -= step;
  }
  return std::nullopt;
}

bool AllFinite(const std::vector<double>& values) {
  for (double value : values) {
    if (!std::isfinite(value)) {
      return false;
    }
  }
  return true;
}

}  // namespace

namespace internal {

// FOV model (Devernay & Faugeras), COLMAP's FOVCameraModel::Distortion: the distorted
// coordinates themselves (not an offset), with its series expansions near omega = 0 and r = 0.
Eigen::Vector2d FovDistort(double omega, double u, double v) {
  constexpr double kEpsilon = 1e-4;
  const double radius2 = u * u + v * v;
  const double omega2 = omega * omega;
  double factor;
  if (omega2 < kEpsilon) {
    factor = (omega2 * radius2) / 3.0 - omega2 / 12.0 + 1.0;
  } else if (radius2 < kEpsilon) {
    const double tan_half_omega = std::tan(omega / 2.0);
    factor = (-2.0 * tan_half_omega * (4.0 * radius2 * tan_half_omega * tan_half_omega - 3.0)) /
             (3.0 * omega);
  } else {
    const double radius = std::sqrt(radius2);
    factor = std::atan(radius * 2.0 * std::tan(omega / 2.0)) / (radius * omega);
  }
  return {u * factor, v * factor};
}

}  // namespace internal

std::string_view CameraModelName(CameraModel model) { return Info(model).name; }

std::optional<CameraModel> ParseCameraModel(std::string_view name) {
  for (const ModelInfo& info : kModels) {
    if (info.name == name) {
      return info.model;
    }
  }
  return std::nullopt;
}

std::optional<CameraModel> CameraModelFromId(int id) {
  if (id < 0 || id >= static_cast<int>(kModels.size())) {
    return std::nullopt;
  }
  return kModels[id].model;
}

int CameraModelParamCount(CameraModel model) { return Info(model).num_params; }

double Camera::FocalLengthX() const { return params.at(0); }

double Camera::FocalLengthY() const {
  return Info(model).num_focal == 1 ? params.at(0) : params.at(1);
}

double Camera::MeanFocalLength() const { return 0.5 * (FocalLengthX() + FocalLengthY()); }

double Camera::PrincipalPointX() const { return params.at(Info(model).num_focal); }

double Camera::PrincipalPointY() const { return params.at(Info(model).num_focal + 1); }

bool Camera::IsPinhole() const {
  return model == CameraModel::kSimplePinhole || model == CameraModel::kPinhole;
}

bool Camera::IsFisheye() const { return Info(model).fisheye; }

CamToImage::CamToImage(const Camera& camera) : model_(camera.model), fisheye_(camera.IsFisheye()) {
  const ModelInfo& info = Info(camera.model);
  REPHOTO_CHECK(static_cast<int>(camera.params.size()) == info.num_params,
                "{} camera has {} parameters, expected {}", info.name, camera.params.size(),
                info.num_params);
  const int nf = info.num_focal;
  REPHOTO_CHECK(info.num_params - nf - 2 <= static_cast<int>(extra_.size()),
                "{} camera: more distortion parameters than CamToImage holds", info.name);
  fx_ = camera.params[0];
  fy_ = camera.params[nf - 1];
  cx_ = camera.params[nf];
  cy_ = camera.params[nf + 1];
  for (int k = nf + 2; k < info.num_params; ++k) extra_[k - nf - 2] = camera.params[k];
}

std::optional<Eigen::Vector2d> Camera::ImgFromCam(const Eigen::Vector3d& point_in_cam) const {
  return CamToImage(*this)(point_in_cam);
}

std::optional<Eigen::Vector3d> Camera::CamFromImg(const Eigen::Vector2d& pixel) const {
  const ModelInfo& info = Info(model);
  REPHOTO_CHECK(static_cast<int>(params.size()) == info.num_params,
                "{} camera has {} parameters, expected {}", info.name, params.size(),
                info.num_params);
  const int nf = info.num_focal;
  const double fx = params[0];
  const double fy = params[nf - 1];
  const double cx = params[nf];
  const double cy = params[nf + 1];
  const double* extra = params.data() + nf + 2;
  const Eigen::Vector2d distorted((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  if (!distorted.allFinite()) {
    return std::nullopt;
  }

  Eigen::Vector2d normalized;
  if (IsPinhole()) {
    normalized = distorted;
  } else if (model == CameraModel::kFov) {
    const std::optional<Eigen::Vector2d> undistorted =
        FovUndistort(extra[0], distorted.x(), distorted.y());
    if (!undistorted) {
      return std::nullopt;
    }
    normalized = *undistorted;
  } else {
    const std::optional<Eigen::Vector2d> undistorted = Undistort(model, extra, distorted);
    if (!undistorted) {
      return std::nullopt;
    }
    normalized = *undistorted;
    if (info.fisheye) {
      // (u, v) holds theta * direction; the ray must stay in front of the camera.
      const double theta = normalized.norm();
      if (theta >= M_PI / 2.0) {
        return std::nullopt;
      }
      if (theta > std::numeric_limits<double>::epsilon()) {
        normalized *= std::tan(theta) / theta;
      }
    }
  }
  Eigen::Vector3d ray(normalized.x(), normalized.y(), 1.0);
  ray.normalize();
  if (!ray.allFinite()) {
    return std::nullopt;
  }
  return ray;
}

Camera Camera::Scaled(int new_width, int new_height) const {
  REPHOTO_CHECK(width > 0 && height > 0, "cannot scale a camera of size {}x{}", width, height);
  REPHOTO_CHECK(new_width > 0 && new_height > 0, "cannot scale a camera to size {}x{}", new_width,
                new_height);
  const ModelInfo& info = Info(model);
  REPHOTO_CHECK(static_cast<int>(params.size()) == info.num_params,
                "cannot scale a {} camera with {} parameters", info.name, params.size());
  const double sx = static_cast<double>(new_width) / width;
  const double sy = static_cast<double>(new_height) / height;
  Camera scaled = *this;
  scaled.width = new_width;
  scaled.height = new_height;
  if (info.num_focal == 1) {
    scaled.params[0] *= 0.5 * (sx + sy);
  } else {
    scaled.params[0] *= sx;
    scaled.params[1] *= sy;
  }
  scaled.params[info.num_focal] *= sx;
  scaled.params[info.num_focal + 1] *= sy;
  return scaled;
}

void Camera::Validate(std::string_view context) const {
  const ModelInfo* info = FindModel(model);
  REPHOTO_CHECK(info != nullptr, "{}: unknown camera model id {}", context,
                static_cast<int>(model));
  REPHOTO_CHECK(width > 0 && height > 0, "{}: image size {}x{} is not positive", context, width,
                height);
  // Every image rendered or read for this camera has its size: the same limit as image files
  // (core/limits.h), checked before anything the size drives is allocated.
  REPHOTO_CHECK(static_cast<uint64_t>(width) * static_cast<uint64_t>(height) <= MaxPixels(),
                "{}: image size {}x{} is more than --max-pixels ({} pixels)", context, width,
                height, MaxPixels());
  REPHOTO_CHECK(static_cast<int>(params.size()) == info->num_params,
                "{}: {} camera has {} parameters, expected {}", context, info->name, params.size(),
                info->num_params);
  REPHOTO_CHECK(AllFinite(params), "{}: {} camera has a NaN or infinite parameter", context,
                info->name);
  REPHOTO_CHECK(FocalLengthX() > 0 && FocalLengthY() > 0,
                "{}: focal length ({}, {}) is not positive", context, FocalLengthX(),
                FocalLengthY());
}

UsableField::UsableField(const Camera& camera) : fisheye_(camera.IsFisheye()) {
  const ModelInfo& info = Info(camera.model);
  REPHOTO_CHECK(static_cast<int>(camera.params.size()) == info.num_params,
                "{} camera has {} parameters, expected {}", info.name, camera.params.size(),
                info.num_params);
  radius_ = std::numeric_limits<double>::infinity();
  if (camera.IsPinhole() || camera.model == CameraModel::kFov) return;
  const double* k = camera.params.data() + info.num_focal + 2;
  const double limit = fisheye_ ? M_PI / 2 : 20.0;
  constexpr int kDirections = 64;
  for (int d = 0; d < kDirections; ++d) {
    const double angle = 2 * M_PI * d / kDirections;
    const double cx = std::cos(angle), cy = std::sin(angle);
    double last_good = 0;
    for (double r = 1e-3; r < std::min(limit, radius_); r *= 1.005) {
      const Dual u{r * cx, 1.0, 0.0};
      const Dual v{r * cy, 0.0, 1.0};
      Dual du, dv;
      internal::Distortion(camera.model, k, u, v, &du, &dv);
      const double det = (1.0 + du.d0) * (1.0 + dv.d1) - du.d1 * dv.d0;
      if (!(det > 0)) {
        radius_ = std::min(radius_, last_good);
        break;
      }
      last_good = r;
    }
  }
}

Pose Pose::FromQuaternion(double qw, double qx, double qy, double qz,
                          const Eigen::Vector3d& translation) {
  Pose pose;
  const Eigen::Quaterniond q(qw, qx, qy, qz);
  const double norm = q.norm();
  pose.rotation = norm > 0 ? Eigen::Matrix3d(Eigen::Quaterniond(q.coeffs() / norm))
                           : Eigen::Matrix3d::Constant(std::numeric_limits<double>::quiet_NaN());
  pose.translation = translation;
  return pose;
}

Pose LookAt(const Eigen::Vector3d& center, const Eigen::Vector3d& target, Eigen::Vector3d up) {
  const Eigen::Vector3d z = (target - center).normalized();
  if (z.cross(up).norm() < 1e-6) {
    up = std::abs(z.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  }
  const Eigen::Vector3d x = z.cross(up).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Pose pose;
  pose.rotation.row(0) = x.transpose();
  pose.rotation.row(1) = y.transpose();
  pose.rotation.row(2) = z.transpose();
  pose.translation = -pose.rotation * center;
  return pose;
}

Eigen::Vector4d Pose::Quaternion() const {
  Eigen::Quaterniond q(rotation);
  q.normalize();
  if (q.w() < 0) {
    q.coeffs() = -q.coeffs();
  }
  return {q.w(), q.x(), q.y(), q.z()};
}

void Pose::Validate(std::string_view context) const {
  REPHOTO_CHECK(rotation.allFinite() && translation.allFinite(),
                "{}: pose has a NaN or infinite value", context);
  const double orthonormality_error =
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  REPHOTO_CHECK(orthonormality_error <= 1e-6,
                "{}: rotation is not orthonormal (max |R^T R - I| = {:.3g})", context,
                orthonormality_error);
  REPHOTO_CHECK(rotation.determinant() > 0, "{}: rotation is a reflection (determinant {:.6g})",
                context, rotation.determinant());
}

Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& matrix, double tolerance,
                                std::string_view context) {
  REPHOTO_CHECK(matrix.allFinite(), "{}: rotation has a NaN or infinite value", context);
  const double orthonormality_error =
      (matrix.transpose() * matrix - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  REPHOTO_CHECK(orthonormality_error <= tolerance,
                "{}: matrix is not a rotation (max |R^T R - I| = {:.3g} > {:.3g})", context,
                orthonormality_error, tolerance);
  REPHOTO_CHECK(matrix.determinant() > 0, "{}: rotation is a reflection (determinant {:.6g})",
                context, matrix.determinant());
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(matrix, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

std::pair<int, int> ScaledSize(int width, int height, int short_side) {
  const int shorter = std::min(width, height);
  if (short_side <= 0 || shorter <= short_side) return {width, height};
  const double scale = static_cast<double>(short_side) / shorter;
  int w = std::max(1, static_cast<int>(std::lround(width * scale)));
  int h = std::max(1, static_cast<int>(std::lround(height * scale)));
  (width <= height ? w : h) = short_side;
  return {w, h};
}

}  // namespace rephoto::camera
