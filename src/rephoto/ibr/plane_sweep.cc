#include "rephoto/ibr/plane_sweep.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "rephoto/camera/cam_to_image.h"
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
  const camera::CamToImage to_image(out.distorted);
  ParallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      for (int x = 0; x < width; ++x) {
        const Eigen::Vector3d ray((x + 0.5 - cx) / fx, (y + 0.5 - cy) / fy, 1.0);
        const auto p = to_image(ray);
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

namespace {

void CheckSweepOptions(size_t neighbors, const PlaneSweepOptions& options) {
  REPHOTO_CHECK(neighbors > 0 && neighbors <= 16,
                "plane sweep: {} neighbour views (1 to 16 are supported)", neighbors);
  REPHOTO_CHECK(options.min_depth > 0 && options.max_depth > options.min_depth &&
                    std::isfinite(options.max_depth),
                "plane sweep: invalid depth range [{}, {}]", options.min_depth, options.max_depth);
  REPHOTO_CHECK(options.num_planes >= 2 && options.num_planes <= 4096,
                "plane sweep: plane count {} must be in [2, 4096]", options.num_planes);
  REPHOTO_CHECK(options.window >= 3 && options.window % 2 == 1 && options.window <= 31,
                "plane sweep: window {} must be odd and in [3, 31]", options.window);
  REPHOTO_CHECK(options.max_width >= 0, "plane sweep: max width {} < 0", options.max_width);
}

// Everything the sweep of one band of rows reads.
struct Sweep {
  const PlaneSweepOptions& options;
  const WorkingView& ref;
  const std::vector<WorkingView>& others;
  int width = 0, height = 0, r = 0, J = 0, best_m = 0;
  float n_window = 0;
  float min_var = 0;
  // Reference window statistics: sum and centred sum of squares (NaN when the window leaves
  // the image or holds invalid pixels).
  Image ref_sum, ref_var;
  Eigen::Matrix3d K_ref_inv;
  std::vector<Eigen::Matrix3d> rel_rotation;
  std::vector<Eigen::Vector3d> rel_translation;
  double inv_far = 0, inv_near = 0;

  double InverseDepth(double plane) const {
    return inv_far + (inv_near - inv_far) * plane / (options.num_planes - 1);
  }
  // Plane homography: reference pinhole pixel -> neighbour j's pinhole pixel for plane depth d:
  // H = K_j (R_rel + t_rel (0, 0, 1/d)) K_ref^-1.
  Eigen::Matrix3d Homography(int j, double inv_depth) const {
    return others[j].K *
           (rel_rotation[j] + rel_translation[j] * Eigen::RowVector3d(0, 0, inv_depth)) * K_ref_inv;
  }
};

void ReferenceWindowStats(Sweep& s) {
  const int width = s.width, height = s.height, r = s.r;
  s.ref_sum = Image(width, height, 1);
  s.ref_var = Image(width, height, 1);
  ParallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
    std::vector<float> col_s(width), col_ss(width), row_s(width), row_ss(width);
    for (int64_t y = y0; y < y1; ++y) {
      float* sum = s.ref_sum.row(static_cast<int>(y));
      float* var = s.ref_var.row(static_cast<int>(y));
      if (y < r || y + r >= height) {
        std::fill(sum, sum + width, kNaN);
        std::fill(var, var + width, kNaN);
        continue;
      }
      std::fill(col_s.begin(), col_s.end(), 0.f);
      std::fill(col_ss.begin(), col_ss.end(), 0.f);
      for (int k = -r; k <= r; ++k) {
        const float* g = s.ref.grey.row(static_cast<int>(y) + k);
        for (int x = 0; x < width; ++x) {
          col_s[x] += g[x];
          col_ss[x] += g[x] * g[x];
        }
      }
      RowWindowSum(col_s.data(), width, r, row_s.data());
      RowWindowSum(col_ss.data(), width, r, row_ss.data());
      for (int x = 0; x < width; ++x) {
        sum[x] = row_s[x];
        var[x] = std::max(0.f, row_ss[x] - row_s[x] * row_s[x] / s.n_window);
      }
    }
  });
}

// Buffers of one band, reused from plane to plane.
struct BandBuffers {
  std::vector<float> best, before, after, prev, ncc, warped, product;
  std::vector<int> best_plane;
  std::vector<float> col_w, col_ww, col_rw, row_w, row_ww, row_rw;
};

// Neighbour j warped onto the reference rows [wy0, wy1) by plane homography H, and its product
// with the reference (NaN outside the neighbour).
void WarpNeighbour(const Sweep& s, int j, const Eigen::Matrix3d& H, int wy0, int wy1,
                   BandBuffers& b) {
  const Image& grey = s.others[j].grey;
  const int width = s.width;
  for (int y = wy0; y < wy1; ++y) {
    const Eigen::Vector3d h0 = H * Eigen::Vector3d(0.5, y + 0.5, 1.0);
    const Eigen::Vector3d hx = H.col(0);
    float* out = b.warped.data() + static_cast<size_t>(y - wy0) * width;
    float* prod = b.product.data() + static_cast<size_t>(y - wy0) * width;
    const float* g = s.ref.grey.row(y);
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
}

// NCC of the reference and the warped neighbour j over each window of rows [y0, y1), into
// b.ncc[cell * J + j] (-1 where undefined).
void NeighbourScores(const Sweep& s, int j, int y0, int y1, int wy0, BandBuffers& b) {
  const int width = s.width, r = s.r, J = s.J;
  for (int y = y0; y < y1; ++y) {
    float* score = b.ncc.data() + (static_cast<size_t>(y - y0) * width) * J;
    if (y < r || y + r >= s.height) {
      for (int x = 0; x < width; ++x) score[x * J + j] = -1.f;
      continue;
    }
    std::fill(b.col_w.begin(), b.col_w.end(), 0.f);
    std::fill(b.col_ww.begin(), b.col_ww.end(), 0.f);
    std::fill(b.col_rw.begin(), b.col_rw.end(), 0.f);
    for (int k = -r; k <= r; ++k) {
      const float* wv = b.warped.data() + static_cast<size_t>(y + k - wy0) * width;
      const float* pv = b.product.data() + static_cast<size_t>(y + k - wy0) * width;
      for (int x = 0; x < width; ++x) {
        b.col_w[x] += wv[x];
        b.col_ww[x] += wv[x] * wv[x];
        b.col_rw[x] += pv[x];
      }
    }
    RowWindowSum(b.col_w.data(), width, r, b.row_w.data());
    RowWindowSum(b.col_ww.data(), width, r, b.row_ww.data());
    RowWindowSum(b.col_rw.data(), width, r, b.row_rw.data());
    const float* rs = s.ref_sum.row(y);
    const float* rv = s.ref_var.row(y);
    for (int x = 0; x < width; ++x) {
      const float var_w = b.row_ww[x] - b.row_w[x] * b.row_w[x] / s.n_window;
      const float cov = b.row_rw[x] - rs[x] * b.row_w[x] / s.n_window;
      const float denom = var_w * rv[x];
      // NaN (invalid pixels) fails the comparison too.
      score[x * J + j] = denom > 1e-12f && var_w > 1e-9f ? cov / std::sqrt(denom) : -1.f;
    }
  }
}

// Plane score: mean of the best_m neighbour scores; winner-take-all bookkeeping.
void KeepBestPlane(const Sweep& s, int plane, size_t cells, BandBuffers& b) {
  float top[16];
  for (size_t cell = 0; cell < cells; ++cell) {
    const float* scores = b.ncc.data() + cell * s.J;
    for (int j = 0; j < s.J; ++j) top[j] = scores[j];
    std::partial_sort(top, top + s.best_m, top + s.J, std::greater<float>());
    float score = 0;
    for (int j = 0; j < s.best_m; ++j) score += top[j];
    score /= static_cast<float>(s.best_m);
    if (b.best_plane[cell] == plane - 1) b.after[cell] = score;
    if (score > b.best[cell]) {
      b.best[cell] = score;
      b.best_plane[cell] = plane;
      b.before[cell] = plane > 0 ? b.prev[cell] : kNaN;
      b.after[cell] = kNaN;
    }
    b.prev[cell] = score;
  }
}

// Sweeps every plane over the rows of one band; writes its depths (parabolic sub-plane
// refinement) and scores.
void SweepBand(const Sweep& s, int band, Image* depth_pinhole, Image* score_image) {
  const int width = s.width;
  const int y0 = band * kBandRows;
  const int y1 = std::min(s.height, y0 + kBandRows);
  const int wy0 = std::max(0, y0 - s.r), wy1 = std::min(s.height, y1 + s.r);
  const size_t cells = static_cast<size_t>(y1 - y0) * width;
  BandBuffers b;
  b.best.assign(cells, -std::numeric_limits<float>::infinity());
  b.best_plane.assign(cells, -1);
  b.before.assign(cells, kNaN);
  b.after.assign(cells, kNaN);
  b.prev.assign(cells, kNaN);
  b.ncc.resize(cells * s.J);
  b.warped.resize(static_cast<size_t>(wy1 - wy0) * width);
  b.product.resize(b.warped.size());
  for (auto* v : {&b.col_w, &b.col_ww, &b.col_rw, &b.row_w, &b.row_ww, &b.row_rw}) {
    v->resize(width);
  }
  for (int plane = 0; plane < s.options.num_planes; ++plane) {
    const double inv_depth = s.InverseDepth(plane);
    for (int j = 0; j < s.J; ++j) {
      WarpNeighbour(s, j, s.Homography(j, inv_depth), wy0, wy1, b);
      NeighbourScores(s, j, y0, y1, wy0, b);
    }
    KeepBestPlane(s, plane, cells, b);
  }
  for (int y = y0; y < y1; ++y) {
    for (int x = 0; x < width; ++x) {
      const size_t cell = static_cast<size_t>(y - y0) * width + x;
      const float var_r = s.ref_var.at(x, y);
      if (b.best_plane[cell] < 0 || b.best[cell] <= -1.f) continue;
      score_image->at(x, y) = b.best[cell];
      if (!(b.best[cell] >= s.options.min_ncc) || !(var_r >= s.min_var)) continue;
      double offset = 0;
      const float a = b.before[cell], c = b.after[cell], best = b.best[cell];
      if (std::isfinite(a) && std::isfinite(c)) {
        const double curvature = a - 2.0 * best + c;
        if (curvature < 0) offset = std::clamp(0.5 * (a - c) / curvature, -0.5, 0.5);
      }
      depth_pinhole->at(x, y) =
          static_cast<float>(1.0 / s.InverseDepth(b.best_plane[cell] + offset));
    }
  }
}

// Back to the distorted grid: each pixel takes the undistorted estimate along its ray.
void ToDistortedGrid(const WorkingView& ref, const Image& depth_pinhole, PlaneSweepResult* result) {
  const int width = depth_pinhole.width(), height = depth_pinhole.height();
  result->depth = Image(width, height, 1, kNaN);
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
        result->depth.at(x, static_cast<int>(y)) = depth_pinhole.at(px, py);
        score.at(x, static_cast<int>(y)) = result->score.at(px, py);
      }
    }
  });
  result->score = std::move(score);
}

}  // namespace

PlaneSweepResult ComputePlaneSweepDepth(const PlaneSweepView& reference,
                                        std::span<const PlaneSweepView> neighbors,
                                        const PlaneSweepOptions& options) {
  CheckSweepOptions(neighbors.size(), options);
  const WorkingView ref = Prepare(reference, options.max_width, "reference");
  std::vector<WorkingView> others;
  for (const PlaneSweepView& n : neighbors) {
    others.push_back(Prepare(n, options.max_width, "neighbour"));
  }
  Sweep s{options, ref, others};
  s.width = ref.grey.width();
  s.height = ref.grey.height();
  s.r = options.window / 2;
  s.n_window = static_cast<float>(options.window * options.window);
  s.J = static_cast<int>(others.size());
  s.best_m = std::clamp(options.best_neighbors, 1, s.J);
  s.min_var = static_cast<float>(options.min_texture * options.min_texture) * s.n_window;
  ReferenceWindowStats(s);
  s.inv_far = 1.0 / options.max_depth;
  s.inv_near = 1.0 / options.min_depth;
  s.K_ref_inv = ref.K.inverse();
  s.rel_rotation.resize(s.J);
  s.rel_translation.resize(s.J);
  for (int j = 0; j < s.J; ++j) {
    const camera::Pose& a = ref.cam_from_world;
    const camera::Pose& b = others[j].cam_from_world;
    s.rel_rotation[j] = b.rotation * a.rotation.transpose();
    s.rel_translation[j] = b.translation - s.rel_rotation[j] * a.translation;
  }

  PlaneSweepResult result;
  Image depth_pinhole(s.width, s.height, 1, kNaN);
  result.score = Image(s.width, s.height, 1, kNaN);
  const int bands = (s.height + kBandRows - 1) / kBandRows;
  ParallelFor(0, bands, 1, [&](int64_t band_begin, int64_t band_end) {
    for (int64_t band = band_begin; band < band_end; ++band) {
      SweepBand(s, static_cast<int>(band), &depth_pinhole, &result.score);
    }
  });
  result.camera = ref.distorted;
  if (ref.distorted.IsPinhole()) {
    result.depth = std::move(depth_pinhole);
    return result;
  }
  ToDistortedGrid(ref, depth_pinhole, &result);
  return result;
}

void FilterInconsistentDepths(std::span<const DepthView> views,
                              const std::vector<std::vector<size_t>>& neighbors, double tolerance,
                              int min_consistent) {
  REPHOTO_CHECK(neighbors.size() == views.size(),
                "FilterInconsistentDepths: {} neighbour lists for {} views", neighbors.size(),
                views.size());
  std::vector<Mask> keep(views.size());
  std::vector<camera::CamToImage> to_image;
  to_image.reserve(views.size());
  for (const DepthView& v : views) to_image.emplace_back(v.camera);
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
            const auto pixel = to_image[n](p);
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
