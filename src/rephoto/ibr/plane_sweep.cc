#include "rephoto/ibr/plane_sweep.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/ibr/image_ops.h"

namespace rephoto::ibr {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr int kBandRows = 32;

// A view prepared for matching: an undistorted grey image with a pinhole camera.
struct WorkingView {
  Image grey;                // 1 channel, NaN where the original photo has no data
  Eigen::Matrix3d K;         // pinhole intrinsics of `grey` (pixel-corner convention)
  camera::Camera distorted;  // the original camera scaled to grey's size
  camera::Pose cam_from_world;
};

// Bilinear sample with pixel centres at i + 0.5; NaN outside [0.5, w - 0.5] x [0.5, h - 0.5].
inline float SampleOrNaN(const Image& image, float px, float py) {
  const float x = px - 0.5f, y = py - 0.5f;
  if (!(x >= 0 && y >= 0 && x <= image.width() - 1 && y <= image.height() - 1)) return kNaN;
  const int x0 = std::min(static_cast<int>(x), image.width() - 2 < 0 ? 0 : image.width() - 2);
  const int y0 = std::min(static_cast<int>(y), image.height() - 2 < 0 ? 0 : image.height() - 2);
  const int x1 = std::min(x0 + 1, image.width() - 1), y1 = std::min(y0 + 1, image.height() - 1);
  const float ax = x - x0, ay = y - y0;
  const float* r0 = image.row(y0);
  const float* r1 = image.row(y1);
  const float top = r0[x0] + ax * (r0[x1] - r0[x0]);
  const float bottom = r1[x0] + ax * (r1[x1] - r1[x0]);
  return top + ay * (bottom - top);
}

WorkingView Prepare(const PlaneSweepView& view, int max_width, const char* role) {
  REPHOTO_CHECK(view.photo != nullptr && !view.photo->empty(), "plane sweep: {} photo is empty",
                role);
  const Image& photo = *view.photo;
  camera::Camera camera = view.camera;
  camera.Validate(std::string("plane sweep: ") + role + " camera");
  view.cam_from_world.Validate(std::string("plane sweep: ") + role + " pose");
  if (camera.width != photo.width() || camera.height != photo.height()) {
    camera = camera.Scaled(photo.width(), photo.height());
  }
  int width = photo.width(), height = photo.height();
  if (max_width > 0 && width > max_width) {
    height =
        std::max(1, static_cast<int>(std::lround(static_cast<double>(height) * max_width / width)));
    width = max_width;
  }
  WorkingView out;
  out.cam_from_world = view.cam_from_world;
  out.distorted = camera.Scaled(width, height);
  const Image grey = internal::ShrinkArea(internal::Luma(photo), width, height);
  out.K = Eigen::Matrix3d::Identity();
  out.K(0, 0) = out.distorted.FocalLengthX();
  out.K(1, 1) = out.distorted.FocalLengthY();
  out.K(0, 2) = out.distorted.PrincipalPointX();
  out.K(1, 2) = out.distorted.PrincipalPointY();
  if (out.distorted.IsPinhole()) {
    out.grey = grey;
    return out;
  }
  // Undistort: each pinhole pixel looks up where the real lens put its ray.
  out.grey = Image(width, height, 1);
  const double fx = out.K(0, 0), fy = out.K(1, 1), cx = out.K(0, 2), cy = out.K(1, 2);
  ParallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      for (int x = 0; x < width; ++x) {
        const Eigen::Vector3d ray((x + 0.5 - cx) / fx, (y + 0.5 - cy) / fy, 1.0);
        const auto p = out.distorted.ImgFromCam(ray);
        out.grey.at(x, static_cast<int>(y)) =
            p ? SampleOrNaN(grey, static_cast<float>(p->x()), static_cast<float>(p->y())) : kNaN;
      }
    }
  });
  return out;
}

// Window sums along a row: out[x] = sum of in[x - r .. x + r]; NaN where the window leaves
// [0, n).
inline void RowWindowSum(const float* in, int n, int r, float* out) {
  for (int x = 0; x < n; ++x) {
    if (x < r || x + r >= n) {
      out[x] = kNaN;
      continue;
    }
    float s = 0;
    for (int k = -r; k <= r; ++k) s += in[x + k];
    out[x] = s;
  }
}

}  // namespace

PlaneSweepResult ComputePlaneSweepDepth(const PlaneSweepView& reference,
                                        std::span<const PlaneSweepView> neighbors,
                                        const PlaneSweepOptions& options) {
  REPHOTO_CHECK(!neighbors.empty() && neighbors.size() <= 16,
                "plane sweep: {} neighbour views (1 to 16 are supported)", neighbors.size());
  REPHOTO_CHECK(options.min_depth > 0 && options.max_depth > options.min_depth &&
                    std::isfinite(options.max_depth),
                "plane sweep: invalid depth range [{}, {}]", options.min_depth, options.max_depth);
  REPHOTO_CHECK(options.num_planes >= 2 && options.num_planes <= 4096,
                "plane sweep: plane count {} must be in [2, 4096]", options.num_planes);
  REPHOTO_CHECK(options.window >= 3 && options.window % 2 == 1 && options.window <= 31,
                "plane sweep: window {} must be odd and in [3, 31]", options.window);
  REPHOTO_CHECK(options.max_width >= 0, "plane sweep: max width {} < 0", options.max_width);

  const WorkingView ref = Prepare(reference, options.max_width, "reference");
  std::vector<WorkingView> others;
  for (const PlaneSweepView& n : neighbors)
    others.push_back(Prepare(n, options.max_width, "neighbour"));
  const int width = ref.grey.width(), height = ref.grey.height();
  const int r = options.window / 2;
  const float n_window = static_cast<float>(options.window * options.window);
  const int J = static_cast<int>(others.size());
  const int best_m = std::clamp(options.best_neighbors, 1, J);

  // Reference window statistics: sum and centred sum of squares (NaN when the window leaves
  // the image or holds invalid pixels).
  Image ref_sum(width, height, 1), ref_var(width, height, 1);
  ParallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
    std::vector<float> col_s(width), col_ss(width), row_s(width), row_ss(width);
    for (int64_t y = y0; y < y1; ++y) {
      if (y < r || y + r >= height) {
        std::fill(ref_sum.row(static_cast<int>(y)), ref_sum.row(static_cast<int>(y)) + width, kNaN);
        std::fill(ref_var.row(static_cast<int>(y)), ref_var.row(static_cast<int>(y)) + width, kNaN);
        continue;
      }
      std::fill(col_s.begin(), col_s.end(), 0.f);
      std::fill(col_ss.begin(), col_ss.end(), 0.f);
      for (int k = -r; k <= r; ++k) {
        const float* g = ref.grey.row(static_cast<int>(y) + k);
        for (int x = 0; x < width; ++x) {
          col_s[x] += g[x];
          col_ss[x] += g[x] * g[x];
        }
      }
      RowWindowSum(col_s.data(), width, r, row_s.data());
      RowWindowSum(col_ss.data(), width, r, row_ss.data());
      for (int x = 0; x < width; ++x) {
        ref_sum.at(x, static_cast<int>(y)) = row_s[x];
        ref_var.at(x, static_cast<int>(y)) =
            std::max(0.f, row_ss[x] - row_s[x] * row_s[x] / n_window);
      }
    }
  });

  // Plane homographies: reference pinhole pixel -> neighbour pinhole pixel for plane depth d:
  // H = K_j (R_rel + t_rel (0, 0, 1/d)) K_ref^-1.
  const double inv_far = 1.0 / options.max_depth, inv_near = 1.0 / options.min_depth;
  auto inverse_depth = [&](double plane) {
    return inv_far + (inv_near - inv_far) * plane / (options.num_planes - 1);
  };
  const Eigen::Matrix3d K_ref_inv = ref.K.inverse();
  std::vector<Eigen::Matrix3d> rel_rotation(J);
  std::vector<Eigen::Vector3d> rel_translation(J);
  for (int j = 0; j < J; ++j) {
    const camera::Pose& a = ref.cam_from_world;
    const camera::Pose& b = others[j].cam_from_world;
    rel_rotation[j] = b.rotation * a.rotation.transpose();
    rel_translation[j] = b.translation - rel_rotation[j] * a.translation;
  }

  PlaneSweepResult result;
  Image depth_pinhole(width, height, 1, kNaN);
  result.score = Image(width, height, 1, kNaN);
  const int bands = (height + kBandRows - 1) / kBandRows;
  const float min_var = static_cast<float>(options.min_texture * options.min_texture) * n_window;
  ParallelFor(0, bands, 1, [&](int64_t band_begin, int64_t band_end) {
    for (int64_t band = band_begin; band < band_end; ++band) {
      const int y0 = static_cast<int>(band) * kBandRows;
      const int y1 = std::min(height, y0 + kBandRows);
      const int rows = y1 - y0;
      const int wy0 = std::max(0, y0 - r), wy1 = std::min(height, y1 + r);
      const size_t cells = static_cast<size_t>(rows) * width;
      std::vector<float> best(cells, -std::numeric_limits<float>::infinity());
      std::vector<int> best_plane(cells, -1);
      std::vector<float> before(cells, kNaN), after(cells, kNaN), prev(cells, kNaN);
      std::vector<float> ncc(cells * J);
      std::vector<float> warped(static_cast<size_t>(wy1 - wy0) * width);
      std::vector<float> product(warped.size());
      std::vector<float> col_w(width), col_ww(width), col_rw(width), row_w(width), row_ww(width),
          row_rw(width);
      float top[16];
      for (int plane = 0; plane < options.num_planes; ++plane) {
        const double inv_depth = inverse_depth(plane);
        for (int j = 0; j < J; ++j) {
          const Eigen::Matrix3d H =
              others[j].K *
              (rel_rotation[j] + rel_translation[j] * Eigen::RowVector3d(0, 0, inv_depth)) *
              K_ref_inv;
          const Image& grey = others[j].grey;
          for (int y = wy0; y < wy1; ++y) {
            const Eigen::Vector3d h0 = H * Eigen::Vector3d(0.5, y + 0.5, 1.0);
            const Eigen::Vector3d hx = H.col(0);
            float* out = warped.data() + static_cast<size_t>(y - wy0) * width;
            float* prod = product.data() + static_cast<size_t>(y - wy0) * width;
            const float* g = ref.grey.row(y);
            for (int x = 0; x < width; ++x) {
              const double w = h0.z() + x * hx.z();
              float v = kNaN;
              if (w > 1e-12) {
                v = SampleOrNaN(grey, static_cast<float>((h0.x() + x * hx.x()) / w),
                                static_cast<float>((h0.y() + x * hx.y()) / w));
              }
              out[x] = v;
              prod[x] = v * g[x];
            }
          }
          for (int y = y0; y < y1; ++y) {
            float* score = ncc.data() + (static_cast<size_t>(y - y0) * width) * J;
            if (y < r || y + r >= height) {
              for (int x = 0; x < width; ++x) score[x * J + j] = -1.f;
              continue;
            }
            std::fill(col_w.begin(), col_w.end(), 0.f);
            std::fill(col_ww.begin(), col_ww.end(), 0.f);
            std::fill(col_rw.begin(), col_rw.end(), 0.f);
            for (int k = -r; k <= r; ++k) {
              const float* wv = warped.data() + static_cast<size_t>(y + k - wy0) * width;
              const float* pv = product.data() + static_cast<size_t>(y + k - wy0) * width;
              for (int x = 0; x < width; ++x) {
                col_w[x] += wv[x];
                col_ww[x] += wv[x] * wv[x];
                col_rw[x] += pv[x];
              }
            }
            RowWindowSum(col_w.data(), width, r, row_w.data());
            RowWindowSum(col_ww.data(), width, r, row_ww.data());
            RowWindowSum(col_rw.data(), width, r, row_rw.data());
            const float* rs = ref_sum.row(y);
            const float* rv = ref_var.row(y);
            for (int x = 0; x < width; ++x) {
              const float var_w = row_ww[x] - row_w[x] * row_w[x] / n_window;
              const float cov = row_rw[x] - rs[x] * row_w[x] / n_window;
              const float denom = var_w * rv[x];
              // NaN (invalid pixels) fails the comparison too.
              score[x * J + j] = denom > 1e-12f && var_w > 1e-9f ? cov / std::sqrt(denom) : -1.f;
            }
          }
        }
        // Plane score: mean of the best_m neighbour scores; winner-take-all bookkeeping.
        for (size_t cell = 0; cell < cells; ++cell) {
          const float* s = ncc.data() + cell * J;
          for (int j = 0; j < J; ++j) top[j] = s[j];
          std::partial_sort(top, top + best_m, top + J, std::greater<float>());
          float score = 0;
          for (int j = 0; j < best_m; ++j) score += top[j];
          score /= static_cast<float>(best_m);
          if (best_plane[cell] == plane - 1) after[cell] = score;
          if (score > best[cell]) {
            best[cell] = score;
            best_plane[cell] = plane;
            before[cell] = plane > 0 ? prev[cell] : kNaN;
            after[cell] = kNaN;
          }
          prev[cell] = score;
        }
      }
      for (int y = y0; y < y1; ++y) {
        for (int x = 0; x < width; ++x) {
          const size_t cell = static_cast<size_t>(y - y0) * width + x;
          const float var_r = ref_var.at(x, y);
          if (best_plane[cell] < 0 || best[cell] <= -1.f) continue;
          result.score.at(x, y) = best[cell];
          if (!(best[cell] >= options.min_ncc) || !(var_r >= min_var)) continue;
          double offset = 0;
          const float a = before[cell], c = after[cell], b = best[cell];
          if (std::isfinite(a) && std::isfinite(c)) {
            const double curvature = a - 2.0 * b + c;
            if (curvature < 0) offset = std::clamp(0.5 * (a - c) / curvature, -0.5, 0.5);
          }
          depth_pinhole.at(x, y) =
              static_cast<float>(1.0 / inverse_depth(best_plane[cell] + offset));
        }
      }
    }
  });

  result.camera = ref.distorted;
  if (ref.distorted.IsPinhole()) {
    result.depth = std::move(depth_pinhole);
    return result;
  }
  // Back to the distorted grid: each pixel takes the undistorted estimate along its ray.
  result.depth = Image(width, height, 1, kNaN);
  Image score(width, height, 1, kNaN);
  ParallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      for (int x = 0; x < width; ++x) {
        const auto ray = ref.distorted.CamFromImg(Eigen::Vector2d(x + 0.5, y + 0.5));
        if (!ray) continue;
        const Eigen::Vector3d p = ref.K * (*ray / ray->z());
        const int px = static_cast<int>(std::floor(p.x())),
                  py = static_cast<int>(std::floor(p.y()));
        if (px < 0 || py < 0 || px >= width || py >= height) continue;
        result.depth.at(x, static_cast<int>(y)) = depth_pinhole.at(px, py);
        score.at(x, static_cast<int>(y)) = result.score.at(px, py);
      }
    }
  });
  result.score = std::move(score);
  return result;
}

void FilterInconsistentDepths(std::span<const DepthView> views,
                              const std::vector<std::vector<size_t>>& neighbors, double tolerance,
                              int min_consistent) {
  REPHOTO_CHECK(neighbors.size() == views.size(),
                "FilterInconsistentDepths: {} neighbour lists for {} views", neighbors.size(),
                views.size());
  std::vector<Mask> keep(views.size());
  for (size_t i = 0; i < views.size(); ++i) {
    const DepthView& v = views[i];
    REPHOTO_CHECK(v.depth != nullptr && v.depth->channels() == 1 &&
                      v.depth->width() == v.camera.width && v.depth->height() == v.camera.height,
                  "FilterInconsistentDepths: depth map {} does not match its camera", i);
    for (size_t n : neighbors[i]) {
      REPHOTO_CHECK(n < views.size() && n != i,
                    "FilterInconsistentDepths: bad neighbour index {} of view {}", n, i);
    }
    const int width = v.depth->width(), height = v.depth->height();
    keep[i] = Mask(width, height, 1, 0);
    const Eigen::Matrix3d world_from_cam = v.cam_from_world.rotation.transpose();
    ParallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
      for (int64_t y = y0; y < y1; ++y) {
        for (int x = 0; x < width; ++x) {
          const float d = v.depth->at(x, static_cast<int>(y));
          if (!std::isfinite(d)) continue;
          const auto ray = v.camera.CamFromImg(Eigen::Vector2d(x + 0.5, y + 0.5));
          if (!ray) continue;
          const Eigen::Vector3d X =
              world_from_cam * ((*ray / ray->z()) * d - v.cam_from_world.translation);
          int consistent = 0;
          for (size_t n : neighbors[i]) {
            const DepthView& o = views[n];
            const Eigen::Vector3d p = o.cam_from_world.CamFromWorld(X);
            const auto pixel = o.camera.ImgFromCam(p);
            if (!pixel || !(pixel->x() >= 0 && pixel->y() >= 0 && pixel->x() < o.camera.width &&
                            pixel->y() < o.camera.height)) {
              continue;
            }
            const float other =
                o.depth->at(static_cast<int>(pixel->x()), static_cast<int>(pixel->y()));
            if (std::abs(other - p.z()) <= tolerance * p.z()) ++consistent;
          }
          keep[i].at(x, static_cast<int>(y)) = consistent >= min_consistent;
        }
      }
    });
  }
  for (size_t i = 0; i < views.size(); ++i) {
    Image& depth = *views[i].depth;
    for (size_t p = 0; p < depth.pixel_count(); ++p) {
      if (!keep[i].data()[p]) depth.data()[p] = kNaN;
    }
  }
}

std::vector<size_t> SelectNeighbors(std::span<const camera::Pose> views, size_t reference,
                                    double scene_depth, int count, double min_angle_degrees) {
  REPHOTO_CHECK(reference < views.size(), "SelectNeighbors: reference {} out of range ({} views)",
                reference, views.size());
  const camera::Pose& ref = views[reference];
  const Eigen::Vector3d centre = ref.Center();
  const Eigen::Vector3d target = centre + scene_depth * ref.ViewDirection();
  const double min_angle = min_angle_degrees * std::numbers::pi / 180.0;
  const double max_direction_angle = 60.0 * std::numbers::pi / 180.0;
  std::vector<std::pair<double, size_t>> candidates;
  for (size_t i = 0; i < views.size(); ++i) {
    if (i == reference) continue;
    const double direction_cos = ref.ViewDirection().dot(views[i].ViewDirection());
    if (direction_cos < std::cos(max_direction_angle)) continue;
    const Eigen::Vector3d a = (centre - target).normalized();
    const Eigen::Vector3d b = (views[i].Center() - target).normalized();
    const double angle = std::acos(std::clamp(a.dot(b), -1.0, 1.0));
    if (!(angle >= min_angle)) continue;
    candidates.emplace_back(angle, i);
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<size_t> out;
  for (const auto& [angle, i] : candidates) {
    if (static_cast<int>(out.size()) >= count) break;
    out.push_back(i);
  }
  return out;
}

}  // namespace rephoto::ibr
