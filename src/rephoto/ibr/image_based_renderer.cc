#include "rephoto/ibr/image_based_renderer.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <numbers>
#include <optional>
#include <utility>

#include "rephoto/camera/cam_to_image.h"
#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/progress.h"
#include "rephoto/core/recent_cache.h"
#include "rephoto/ibr/depth_map_io.h"
#include "rephoto/ibr/image_ops.h"
#include "rephoto/io/image_io.h"
#include "rephoto/render/camera_rays.h"
#include "rephoto/render/render_model.h"
#include "rephoto/render/weighted_median.h"

namespace rephoto::ibr {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int kMaxK = 16;            // largest k_best
constexpr int kDepthLayers = 4;      // IBR: nearest surfaces kept per pixel
constexpr int kMaxCandidates = 32;   // training views considered per novel view
constexpr int kBandRows = 16;        // IBR rasterization bands
constexpr int kRasterViewsPerK = 3;  // IBR: the proxies of the 3 * k_best nearest views are warped

// A training view prepared for rendering.
struct ViewData {
  TrainingView info;
  camera::Camera camera;  // scaled to the photo
  std::optional<camera::CamToImage> to_image;  // camera's projection (set with camera)
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;          // 8-bit RGB, interleaved, top row first
  Image depth;                       // see depth_map_io.h
  float depth_sx = 1, depth_sy = 1;  // depth-map pixels per photo pixel
  Eigen::Matrix3f rotation;
  Eigen::Vector3f translation;
  Eigen::Vector3f center;
  bool pinhole = true;
  float fx = 1, fy = 1, cx = 0, cy = 0;
  // Normalized image-plane bounds (x/z, y/z) of the photo, widened by 20 %: projections of
  // distorted cameras outside them are rejected (the distortion polynomial folds back there).
  float min_xn = -kInf, max_xn = kInf, min_yn = -kInf, max_yn = kInf;
  // IBR proxy mesh: a grid of world points (NaN = no depth) and their depths.
  int grid_w = 0, grid_h = 0;
  std::vector<Eigen::Vector3f> grid_world;
  std::vector<float> grid_depth;
  // Per grid quad: bit 0 = triangle (a, b, c) kept, bit 1 = triangle (b, d, c) kept, for the
  // quad a b / c d (see BuildProxyGrids).
  std::vector<uint8_t> quad_triangles;

  // Projects world point X: photo pixel (u, v) and camera-frame depth z.
  bool Project(const Eigen::Vector3f& X, float* u, float* v, float* z) const {
    const Eigen::Vector3f p = rotation * X + translation;
    if (!(p.z() > 1e-6f)) return false;
    const float xn = p.x() / p.z(), yn = p.y() / p.z();
    *z = p.z();
    if (pinhole) {
      *u = fx * xn + cx;
      *v = fy * yn + cy;
      return true;
    }
    if (!(xn >= min_xn && xn <= max_xn && yn >= min_yn && yn <= max_yn)) return false;
    const auto pixel = (*to_image)(p.cast<double>());
    if (!pixel) return false;
    *u = static_cast<float>(pixel->x());
    *v = static_cast<float>(pixel->y());
    return true;
  }

  float Depth(int x, int y) const { return depth.at(x, y); }

  void Bilinear(float u, float v, float* out) const {
    const float x = u - 0.5f, y = v - 0.5f;
    int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    x0 = std::clamp(x0, 0, width - 1);
    y0 = std::clamp(y0, 0, height - 1);
    const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
    const float ax = std::clamp(x - x0, 0.f, 1.f), ay = std::clamp(y - y0, 0.f, 1.f);
    const uint8_t* p00 = rgb.data() + (static_cast<size_t>(y0) * width + x0) * 3;
    const uint8_t* p10 = rgb.data() + (static_cast<size_t>(y0) * width + x1) * 3;
    const uint8_t* p01 = rgb.data() + (static_cast<size_t>(y1) * width + x0) * 3;
    const uint8_t* p11 = rgb.data() + (static_cast<size_t>(y1) * width + x1) * 3;
    for (int c = 0; c < 3; ++c) {
      const float top = p00[c] + ax * (static_cast<float>(p10[c]) - p00[c]);
      const float bottom = p01[c] + ax * (static_cast<float>(p11[c]) - p01[c]);
      out[c] = (top + ay * (bottom - top)) * (1.0f / 255.0f);
    }
  }

  void Nearest(float u, float v, float* out) const {
    const int x = std::clamp(static_cast<int>(u), 0, width - 1);
    const int y = std::clamp(static_cast<int>(v), 0, height - 1);
    const uint8_t* p = rgb.data() + (static_cast<size_t>(y) * width + x) * 3;
    for (int c = 0; c < 3; ++c) out[c] = p[c] * (1.0f / 255.0f);
  }
};

// Per-pixel list of the nearest proxy surfaces of different views (IBR).
struct DepthLayers {
  float depth[kDepthLayers];
  uint16_t view[kDepthLayers];
  int count;
};

struct Scratch {
  render::Rephoto geometry;                             // VDT: the proxy's rendering
  Image novel_depth;                                    // IBR: the fused proxy depth
  std::vector<DepthLayers> layers;                      // IBR
  std::vector<std::vector<Eigen::Vector3f>> projected;  // IBR: per view (x, y, 1/z)
  std::vector<std::vector<Eigen::Vector2f>> row_range;  // IBR: per view, per grid row: y range
};

void ValidateOptions(const ImageBasedOptions& o) {
  REPHOTO_CHECK(o.k_best >= 1 && o.k_best <= kMaxK,
                "image-based rendering: k_best {} not in [1, {}]", o.k_best, kMaxK);
  REPHOTO_CHECK(o.epipole_epsilon > 0, "image-based rendering: epipole_epsilon must be > 0");
  REPHOTO_CHECK(o.depth_tolerance > 0 && o.depth_tolerance < 1,
                "image-based rendering: depth_tolerance {} not in (0, 1)", o.depth_tolerance);
  REPHOTO_CHECK(o.depth_penalty >= 0, "image-based rendering: depth_penalty must be >= 0");
  REPHOTO_CHECK(o.resolution_penalty >= 0,
                "image-based rendering: resolution_penalty must be >= 0");
  REPHOTO_CHECK(o.proxy_grid_spacing >= 1,
                "image-based rendering: proxy_grid_spacing must be >= 1");
  REPHOTO_CHECK(o.proxy_edge_angle >= 0 && o.proxy_edge_angle < 90,
                "image-based rendering: proxy_edge_angle {} not in [0, 90)", o.proxy_edge_angle);
  REPHOTO_CHECK(o.sweep_neighbors >= 1 && o.sweep_neighbors <= 16,
                "image-based rendering: sweep_neighbors {} not in [1, 16]", o.sweep_neighbors);
}

// Median of the finite values of a depth image (every 8th pixel in each direction); `fallback`
// when there are none.
double MedianDepth(const Image& depth, double fallback) {
  std::vector<float> values;
  for (int y = 0; y < depth.height(); y += 8) {
    for (int x = 0; x < depth.width(); x += 8) {
      if (std::isfinite(depth.at(x, y))) values.push_back(depth.at(x, y));
    }
  }
  if (values.empty()) return fallback;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

// Training views ordered by the angle between their camera centre and the novel camera centre
// seen from the novel view's central scene point (at `central_depth` on its optical axis),
// smallest first, at most kMaxCandidates.
std::vector<int> RankViews(const std::vector<ViewData>& views, const camera::Pose& pose,
                           double central_depth) {
  const Eigen::Vector3d target = pose.Center() + central_depth * pose.ViewDirection();
  const Eigen::Vector3d a = (pose.Center() - target).normalized();
  std::vector<std::pair<double, int>> ranked;
  for (size_t i = 0; i < views.size(); ++i) {
    const Eigen::Vector3d b = (views[i].info.cam_from_world.Center() - target).normalized();
    ranked.emplace_back(-a.dot(b), static_cast<int>(i));
  }
  std::sort(ranked.begin(), ranked.end());
  if (ranked.size() > kMaxCandidates) ranked.resize(kMaxCandidates);
  std::vector<int> out;
  for (const auto& r : ranked) out.push_back(r.second);
  return out;
}

}  // namespace

struct ImageBasedRenderer::State {
  ImageBasedOptions options;
  bool ibr = false;
  std::vector<ViewData> views;
  std::unique_ptr<render::RenderModel> proxy;  // VDT
  double typical_depth = 1;  // median over the training views of their median depth
  mutable std::mutex scratch_mutex;
  mutable std::unique_ptr<Scratch> scratch;

  std::shared_ptr<const render::CameraRays> RaysFor(const camera::Camera& camera) const {
    return render::SharedCameraRays(camera);
  }

  void LoadPhotos(std::vector<TrainingView> training);
  void BuildProxyGrids();
  void ComputeTypicalDepth() {
    std::vector<double> medians;
    for (const ViewData& v : views) {
      const double m = MedianDepth(v.depth, kNaN);
      if (std::isfinite(m)) medians.push_back(m);
    }
    if (medians.empty()) return;
    std::nth_element(medians.begin(), medians.begin() + medians.size() / 2, medians.end());
    typical_depth = medians[medians.size() / 2];
  }
  void RasterizeProxies(const camera::Camera& camera, const camera::Pose& pose,
                        const std::vector<int>& raster_views, Scratch* scratch) const;
  void Fuse(const render::CameraRays& rays, const camera::Pose& pose, const Image& depth,
            int depth_stride, render::Rephoto* out) const;
};

void ImageBasedRenderer::State::LoadPhotos(std::vector<TrainingView> training) {
  REPHOTO_CHECK(!training.empty(), "image-based rendering: no training views");
  REPHOTO_CHECK(training.size() < 65535, "image-based rendering: too many training views ({})",
                training.size());
  views.resize(training.size());
  for (size_t i = 0; i < training.size(); ++i) {
    training[i].camera.Validate(training[i].name + ": camera");
    training[i].cam_from_world.Validate(training[i].name + ": pose");
    views[i].info = std::move(training[i]);
  }
  std::unique_ptr<Progress> progress;
  if (options.show_progress) progress = std::make_unique<Progress>("loading photos", views.size());
  // Two photos at a time (decoding dominates; one core each).
  ParallelFor(0, static_cast<int64_t>(views.size()), 1, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      ViewData& v = views[i];
      const Image photo = io::ReadImage(v.info.photo);
      REPHOTO_CHECK(!photo.empty() && photo.channels() >= 1 && photo.channels() <= 4,
                    "{}: unsupported photo ({} channels)", v.info.photo.string(), photo.channels());
      v.width = photo.width();
      v.height = photo.height();
      v.camera = v.info.camera;
      if (v.camera.width != v.width || v.camera.height != v.height) {
        v.camera = v.camera.Scaled(v.width, v.height);
      }
      v.to_image.emplace(v.camera);
      const int c = photo.channels();
      v.rgb.resize(photo.pixel_count() * 3);
      for (size_t p = 0; p < photo.pixel_count(); ++p) {
        for (int k = 0; k < 3; ++k) {
          const float value = photo.data()[p * c + (c >= 3 ? k : 0)];
          v.rgb[p * 3 + k] = static_cast<uint8_t>(std::lround(std::clamp(value, 0.f, 1.f) * 255.f));
        }
      }
      const camera::Pose& pose = v.info.cam_from_world;
      v.rotation = pose.rotation.cast<float>();
      v.translation = pose.translation.cast<float>();
      v.center = pose.Center().cast<float>();
      v.pinhole = v.camera.IsPinhole();
      v.fx = static_cast<float>(v.camera.FocalLengthX());
      v.fy = static_cast<float>(v.camera.FocalLengthY());
      v.cx = static_cast<float>(v.camera.PrincipalPointX());
      v.cy = static_cast<float>(v.camera.PrincipalPointY());
      if (!v.pinhole) {
        float min_x = kInf, max_x = -kInf, min_y = kInf, max_y = -kInf;
        for (int s = 0; s <= 8; ++s) {
          const double t = s / 8.0;
          const Eigen::Vector2d border[4] = {{t * v.width, 0},
                                             {t * v.width, static_cast<double>(v.height)},
                                             {0, t * v.height},
                                             {static_cast<double>(v.width), t * v.height}};
          for (const auto& b : border) {
            const auto ray = v.camera.CamFromImg(b);
            if (!ray) continue;
            min_x = std::min(min_x, static_cast<float>(ray->x() / ray->z()));
            max_x = std::max(max_x, static_cast<float>(ray->x() / ray->z()));
            min_y = std::min(min_y, static_cast<float>(ray->y() / ray->z()));
            max_y = std::max(max_y, static_cast<float>(ray->y() / ray->z()));
          }
        }
        if (min_x < max_x && min_y < max_y) {
          const float mx = 0.2f * (max_x - min_x), my = 0.2f * (max_y - min_y);
          v.min_xn = min_x - mx;
          v.max_xn = max_x + mx;
          v.min_yn = min_y - my;
          v.max_yn = max_y + my;
        }
      }
      if (progress) progress->Advance(v.info.name);
    }
  });
  if (progress) progress->Finish();
}

namespace {

// The normalized rays (x/z, y/z, 1) of the proxy grid's pixels (column min(gx * step, width -
// 1), the same for rows) of a depth map of `camera` (none where it cannot unproject), from a
// process-wide cache of the last few: every renderer made for a photo of one camera (the live
// session makes one per prediction) shares them instead of undistorting each grid point again.
// Thread-safe.
using GridRayTable = std::vector<std::optional<Eigen::Vector3f>>;
std::shared_ptr<const GridRayTable> GridRays(const camera::Camera& camera, int step, int grid_w,
                                             int grid_h) {
  static RecentCache<std::pair<camera::Camera, int>, GridRayTable> cache(4);
  return cache.Get({camera, step}, [&] {
    GridRayTable rays(static_cast<size_t>(grid_w) * grid_h);
    for (int gy = 0; gy < grid_h; ++gy) {
      const int py = std::min(gy * step, camera.height - 1);
      for (int gx = 0; gx < grid_w; ++gx) {
        const int px = std::min(gx * step, camera.width - 1);
        const auto ray = camera.CamFromImg(Eigen::Vector2d(px + 0.5, py + 0.5));
        if (ray) rays[static_cast<size_t>(gy) * grid_w + gx] = (*ray / ray->z()).cast<float>();
      }
    }
    return rays;
  });
}

}  // namespace

void ImageBasedRenderer::State::BuildProxyGrids() {
  ParallelFor(0, static_cast<int64_t>(views.size()), 1, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      ViewData& v = views[i];
      const int dw = v.depth.width(), dh = v.depth.height();
      const int step =
          std::max(1, static_cast<int>(std::lround(options.proxy_grid_spacing * dw / v.width)));
      v.grid_w = (dw - 1 + step - 1) / step + 1;
      v.grid_h = (dh - 1 + step - 1) / step + 1;
      v.grid_world.assign(static_cast<size_t>(v.grid_w) * v.grid_h,
                          Eigen::Vector3f::Constant(kNaN));
      v.grid_depth.assign(v.grid_world.size(), kNaN);
      const camera::Camera depth_camera = v.camera.Scaled(dw, dh);
      const Eigen::Matrix3f world_from_cam = v.rotation.transpose();
      const std::shared_ptr<const GridRayTable> rays =
          GridRays(depth_camera, step, v.grid_w, v.grid_h);
      for (int gy = 0; gy < v.grid_h; ++gy) {
        const int py = std::min(gy * step, dh - 1);
        for (int gx = 0; gx < v.grid_w; ++gx) {
          const int px = std::min(gx * step, dw - 1);
          const float d = v.depth.at(px, py);
          if (!std::isfinite(d)) continue;
          const std::optional<Eigen::Vector3f>& ray =
              (*rays)[static_cast<size_t>(gy) * v.grid_w + gx];
          if (!ray) continue;
          const Eigen::Vector3f cam = *ray * d;
          const size_t g = static_cast<size_t>(gy) * v.grid_w + gx;
          v.grid_world[g] = world_from_cam * (cam - v.translation);
          v.grid_depth[g] = d;
        }
      }
      // Triangles seen from their own camera at a grazing angle below proxy_edge_angle join a
      // foreground to a background across an occlusion edge: cut them.
      const float min_sine =
          static_cast<float>(std::sin(options.proxy_edge_angle * std::numbers::pi / 180.0));
      v.quad_triangles.assign(
          static_cast<size_t>(std::max(0, v.grid_w - 1)) * std::max(0, v.grid_h - 1), 0);
      for (int gy = 0; gy + 1 < v.grid_h; ++gy) {
        for (int gx = 0; gx + 1 < v.grid_w; ++gx) {
          const size_t g = static_cast<size_t>(gy) * v.grid_w + gx;
          const size_t corners[4] = {g, g + 1, g + v.grid_w, g + v.grid_w + 1};
          const int tris[2][3] = {{0, 1, 2}, {1, 3, 2}};
          uint8_t flags = 0;
          for (int t = 0; t < 2; ++t) {
            const Eigen::Vector3f& a = v.grid_world[corners[tris[t][0]]];
            const Eigen::Vector3f& b = v.grid_world[corners[tris[t][1]]];
            const Eigen::Vector3f& c = v.grid_world[corners[tris[t][2]]];
            if (!std::isfinite(a.x()) || !std::isfinite(b.x()) || !std::isfinite(c.x())) continue;
            const Eigen::Vector3f normal = (b - a).cross(c - a);
            const Eigen::Vector3f ray = (a + b + c) / 3.0f - v.center;
            const float norms = normal.norm() * ray.norm();
            if (!(norms > 0) || std::abs(normal.dot(ray)) < min_sine * norms) continue;
            flags |= static_cast<uint8_t>(1 << t);
          }
          v.quad_triangles[static_cast<size_t>(gy) * (v.grid_w - 1) + gx] = flags;
        }
      }
    }
  });
}

namespace {

// Depth range of view `v` for plane sweep (see ImageBasedOptions).
std::pair<double, double> SweepRange(const std::vector<TrainingView>& views,
                                     const std::vector<camera::Camera>& cameras, size_t v,
                                     const ImageBasedOptions& options,
                                     const std::vector<size_t>& neighbors) {
  if (options.plane_sweep.min_depth > 0 && options.plane_sweep.max_depth > 0) {
    return {options.plane_sweep.min_depth, options.plane_sweep.max_depth};
  }
  const TrainingView& view = views[v];
  const camera::Camera& camera = cameras[v];
  const camera::CamToImage to_image(camera);
  std::vector<double> depths;
  for (const Eigen::Vector3d& point : options.scene_points) {
    const Eigen::Vector3d p = view.cam_from_world.CamFromWorld(point);
    const auto pixel = to_image(p);
    if (pixel && pixel->x() >= 0 && pixel->y() >= 0 && pixel->x() <= camera.width &&
        pixel->y() <= camera.height) {
      depths.push_back(p.z());
    }
  }
  if (depths.size() >= 10) {
    std::sort(depths.begin(), depths.end());
    const double low = depths[static_cast<size_t>(0.02 * (depths.size() - 1))];
    const double high = depths[static_cast<size_t>(0.98 * (depths.size() - 1))];
    return {low / 1.25, high * 1.25};
  }
  // Closest approach of the optical axes.
  std::vector<double> axis_depths;
  const Eigen::Vector3d c0 = view.cam_from_world.Center();
  const Eigen::Vector3d d0 = view.cam_from_world.ViewDirection();
  for (size_t n : neighbors) {
    const Eigen::Vector3d c1 = views[n].cam_from_world.Center();
    const Eigen::Vector3d d1 = views[n].cam_from_world.ViewDirection();
    const Eigen::Vector3d w0 = c0 - c1;
    const double b = d0.dot(d1), d = d0.dot(w0), e = d1.dot(w0);
    const double denom = 1 - b * b;
    if (denom < 1e-6) continue;
    const double s = (b * e - d) / denom;
    if (s > 0) axis_depths.push_back(s);
  }
  REPHOTO_CHECK(!axis_depths.empty(),
                "{}: cannot estimate a depth range for plane sweep (no converging neighbour; "
                "give scene points or a depth range)",
                view.name);
  std::nth_element(axis_depths.begin(), axis_depths.begin() + axis_depths.size() / 2,
                   axis_depths.end());
  const double median = axis_depths[axis_depths.size() / 2];
  return {median / 2.5, median * 2.5};
}

}  // namespace

std::vector<Image> EstimateDepthMaps(const std::vector<TrainingView>& views,
                                     const std::vector<bool>& estimate,
                                     const ImageBasedOptions& options) {
  ValidateOptions(options);
  REPHOTO_CHECK(estimate.size() == views.size(), "EstimateDepthMaps: {} flags for {} views",
                estimate.size(), views.size());
  REPHOTO_CHECK(views.size() >= 2, "plane sweep needs at least 2 views");
  // Photos reduced to the sweep's working width (decoded two at a time).
  const int max_width = options.plane_sweep.max_width;
  std::vector<Image> photos(views.size());
  std::vector<camera::Camera> cameras(views.size());
  std::vector<camera::Pose> poses(views.size());
  ParallelFor(0, static_cast<int64_t>(views.size()), 1, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      views[i].camera.Validate(views[i].name + ": camera");
      views[i].cam_from_world.Validate(views[i].name + ": pose");
      const Image photo = io::ReadImage(views[i].photo);
      REPHOTO_CHECK(!photo.empty() && photo.channels() >= 1 && photo.channels() <= 4,
                    "{}: unsupported photo ({} channels)", views[i].photo.string(),
                    photo.channels());
      cameras[i] = views[i].camera;
      if (cameras[i].width != photo.width() || cameras[i].height != photo.height()) {
        cameras[i] = cameras[i].Scaled(photo.width(), photo.height());
      }
      const int w = max_width > 0 ? std::min(max_width, photo.width()) : photo.width();
      const int h = std::max(1, static_cast<int>(std::lround(static_cast<double>(photo.height()) *
                                                             w / photo.width())));
      photos[i] = internal::ShrinkArea(photo, w, h);
      poses[i] = views[i].cam_from_world;
    }
  });
  std::vector<Image> depths(views.size());
  std::unique_ptr<Progress> progress;
  size_t count = 0;
  for (bool e : estimate) count += e;
  if (options.show_progress) progress = std::make_unique<Progress>("plane sweep", count);
  std::vector<size_t> swept;                         // views whose depth is estimated
  std::vector<std::vector<size_t>> swept_neighbors;  // their neighbours (view indices)
  for (size_t v = 0; v < views.size(); ++v) {
    if (!estimate[v]) continue;
    // Neighbours by triangulation angle at the middle of the view's depth range.
    std::vector<size_t> all;
    for (size_t i = 0; i < views.size(); ++i) {
      if (i != v) all.push_back(i);
    }
    const auto [near, far] = SweepRange(views, cameras, v, options, all);
    const std::vector<size_t> neighbors =
        SelectNeighbors(poses, v, std::sqrt(near * far), options.sweep_neighbors);
    if (neighbors.empty()) {
      // Nothing to match against (e.g. a sparse ring of training cameras): the view's depth is
      // unknown everywhere, so it contributes no pixels; the other views still do.
      LogWarning(fmt::format("{}: no neighbouring view for plane sweep; its depth is unknown",
                             views[v].name));
      depths[v] =
          Image(photos[v].width(), photos[v].height(), 1, std::numeric_limits<float>::quiet_NaN());
      if (progress) progress->Advance(views[v].name);
      continue;
    }
    PlaneSweepOptions sweep = options.plane_sweep;
    sweep.min_depth = near;
    sweep.max_depth = far;
    const PlaneSweepView reference{cameras[v], poses[v], &photos[v]};
    std::vector<PlaneSweepView> others;
    for (size_t n : neighbors) others.push_back({cameras[n], poses[n], &photos[n]});
    const bool given_range = options.plane_sweep.min_depth > 0 && options.plane_sweep.max_depth > 0;
    if (!given_range && options.sweep_refine_range) {
      // Coarse pass at a quarter of the working width over the estimated range; the fine pass
      // sweeps the 2nd..98th percentile of its confident depths, widened by 15 % each way.
      PlaneSweepOptions coarse = sweep;
      coarse.max_width = std::max(16, photos[v].width() / 4);
      const Image depth = ComputePlaneSweepDepth(reference, others, coarse).depth;
      std::vector<float> found;
      for (size_t p = 0; p < depth.pixel_count(); ++p) {
        if (std::isfinite(depth.data()[p])) found.push_back(depth.data()[p]);
      }
      if (found.size() >= 50) {
        std::sort(found.begin(), found.end());
        const double low = found[static_cast<size_t>(0.02 * (found.size() - 1))] / 1.15;
        const double high = found[static_cast<size_t>(0.98 * (found.size() - 1))] * 1.15;
        sweep.min_depth = std::max(near, low);
        sweep.max_depth = std::min(far, high);
        if (!(sweep.max_depth > sweep.min_depth)) {
          sweep.min_depth = near;
          sweep.max_depth = far;
        }
      }
    }
    depths[v] = ComputePlaneSweepDepth(reference, others, sweep).depth;
    swept.push_back(v);
    swept_neighbors.push_back(neighbors);
    if (progress) progress->Advance(views[v].name);
  }
  if (progress) progress->Finish();
  // Consistency between the estimated depth maps (views not estimated here are not used).
  if (options.sweep_min_consistent > 0 && swept.size() > 1) {
    std::vector<DepthView> depth_views;
    std::vector<int> position(views.size(), -1);
    for (size_t i = 0; i < swept.size(); ++i) {
      const size_t v = swept[i];
      position[v] = static_cast<int>(i);
      depth_views.push_back(
          {cameras[v].Scaled(depths[v].width(), depths[v].height()), poses[v], &depths[v]});
    }
    std::vector<std::vector<size_t>> local(swept.size());
    for (size_t i = 0; i < swept.size(); ++i) {
      for (size_t n : swept_neighbors[i]) {
        if (position[n] >= 0) local[i].push_back(static_cast<size_t>(position[n]));
      }
    }
    FilterInconsistentDepths(depth_views, local, options.depth_tolerance,
                             options.sweep_min_consistent);
  }
  return depths;
}

namespace {

// IBR step 1a: each raster view's proxy grid vertices projected into the novel view ((x, y) in
// novel pixels, 1/z; NaN behind the camera or outside its model), and per grid row the range of
// novel rows its quads span.
void ProjectProxyGrids(const std::vector<ViewData>& views, const camera::Camera& camera,
                       const camera::Pose& pose, const std::vector<int>& raster_views,
                       Scratch* scratch) {
  const size_t n = raster_views.size();
  scratch->projected.resize(n);
  scratch->row_range.resize(n);
  const Eigen::Matrix3d R = pose.rotation;
  const Eigen::Vector3d t = pose.translation;
  const bool pinhole = camera.IsPinhole();
  const camera::CamToImage to_image(camera);
  const double fx = camera.FocalLengthX(), fy = camera.FocalLengthY(),
               cx = camera.PrincipalPointX(), cy = camera.PrincipalPointY();
  // Project the grid vertices: (x, y) in novel pixels, 1/z.
  ParallelFor(0, static_cast<int64_t>(n), 1, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const ViewData& v = views[raster_views[i]];
      auto& projected = scratch->projected[i];
      projected.resize(v.grid_world.size());
      auto& range = scratch->row_range[i];
      range.assign(std::max(0, v.grid_h - 1), Eigen::Vector2f(kInf, -kInf));
      for (int gy = 0; gy < v.grid_h; ++gy) {
        float row_min = kInf, row_max = -kInf;
        for (int gx = 0; gx < v.grid_w; ++gx) {
          const size_t g = static_cast<size_t>(gy) * v.grid_w + gx;
          projected[g] = Eigen::Vector3f(kNaN, kNaN, kNaN);
          const Eigen::Vector3f& X = v.grid_world[g];
          if (!std::isfinite(X.x())) continue;
          const Eigen::Vector3d p = R * X.cast<double>() + t;
          if (!(p.z() > 1e-9)) continue;
          Eigen::Vector2d pixel;
          if (pinhole) {
            pixel = Eigen::Vector2d(fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy);
          } else {
            const auto q = to_image(p);
            if (!q) continue;
            pixel = *q;
          }
          projected[g] =
              Eigen::Vector3f(static_cast<float>(pixel.x()), static_cast<float>(pixel.y()),
                              static_cast<float>(1.0 / p.z()));
          row_min = std::min(row_min, projected[g].y());
          row_max = std::max(row_max, projected[g].y());
        }
        if (gy > 0) {
          range[gy - 1].x() = std::min(range[gy - 1].x(), row_min);
          range[gy - 1].y() = std::max(range[gy - 1].y(), row_max);
        }
        if (gy + 1 < v.grid_h) {
          range[gy] = Eigen::Vector2f(row_min, row_max);
        }
      }
    }
  });
}

}  // namespace

// IBR step 1: forward-warps every proxy mesh into the novel view and resolves each pixel's
// depth into scratch->novel_depth.
void ImageBasedRenderer::State::RasterizeProxies(const camera::Camera& camera,
                                                 const camera::Pose& pose,
                                                 const std::vector<int>& raster_views,
                                                 Scratch* scratch) const {
  const int width = camera.width, height = camera.height;
  const size_t n = raster_views.size();
  ProjectProxyGrids(views, camera, pose, raster_views, scratch);

  scratch->layers.resize(static_cast<size_t>(width) * height);
  scratch->novel_depth.Resize(width, height, 1);
  const float tolerance = static_cast<float>(options.depth_tolerance);
  const int bands = (height + kBandRows - 1) / kBandRows;
  ParallelFor(0, bands, 1, [&](int64_t band_begin, int64_t band_end) {
    for (int64_t band = band_begin; band < band_end; ++band) {
      const int y0 = static_cast<int>(band) * kBandRows;
      const int y1 = std::min(height, y0 + kBandRows);
      DepthLayers* layers = scratch->layers.data() + static_cast<size_t>(y0) * width;
      for (size_t i = 0; i < static_cast<size_t>(y1 - y0) * width; ++i) layers[i].count = 0;
      auto insert = [&](int x, int y, float z, uint16_t view) {
        DepthLayers& l = layers[static_cast<size_t>(y - y0) * width + x];
        for (int k = 0; k < l.count; ++k) {
          if (l.view[k] != view) continue;
          if (z >= l.depth[k]) return;
          // Same view, nearer: remove the old entry, insert below.
          for (int m = k; m + 1 < l.count; ++m) {
            l.depth[m] = l.depth[m + 1];
            l.view[m] = l.view[m + 1];
          }
          --l.count;
          break;
        }
        if (l.count == kDepthLayers && z >= l.depth[kDepthLayers - 1]) return;
        int k = std::min(l.count, kDepthLayers - 1);
        while (k > 0 && l.depth[k - 1] > z) {
          l.depth[k] = l.depth[k - 1];
          l.view[k] = l.view[k - 1];
          --k;
        }
        l.depth[k] = z;
        l.view[k] = view;
        l.count = std::min(l.count + 1, kDepthLayers);
      };
      auto triangle = [&](const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                          const Eigen::Vector3f& c, uint16_t view) {
        const float area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
        if (!(std::abs(area) > 1e-12f)) return;
        const float min_x = std::min({a.x(), b.x(), c.x()}),
                    max_x = std::max({a.x(), b.x(), c.x()});
        const float min_y = std::min({a.y(), b.y(), c.y()}),
                    max_y = std::max({a.y(), b.y(), c.y()});
        const int px0 = std::max(0, static_cast<int>(std::ceil(min_x - 0.5f)));
        const int px1 = std::min(width - 1, static_cast<int>(std::floor(max_x - 0.5f)));
        const int py0 = std::max(y0, static_cast<int>(std::ceil(min_y - 0.5f)));
        const int py1 = std::min(y1 - 1, static_cast<int>(std::floor(max_y - 0.5f)));
        if (px0 > px1 || py0 > py1) return;
        const float inv_area = 1.0f / area;
        for (int y = py0; y <= py1; ++y) {
          const float sy = y + 0.5f;
          for (int x = px0; x <= px1; ++x) {
            const float sx = x + 0.5f;
            // Barycentric coordinates (edge functions normalized by the signed area).
            const float wa = ((b.x() - sx) * (c.y() - sy) - (b.y() - sy) * (c.x() - sx)) * inv_area;
            const float wb = ((c.x() - sx) * (a.y() - sy) - (c.y() - sy) * (a.x() - sx)) * inv_area;
            const float wc = 1.0f - wa - wb;
            if (wa < -1e-5f || wb < -1e-5f || wc < -1e-5f) continue;
            const float inv_z = wa * a.z() + wb * b.z() + wc * c.z();
            if (!(inv_z > 0)) continue;
            insert(x, y, 1.0f / inv_z, view);
          }
        }
      };
      for (size_t i = 0; i < n; ++i) {
        const ViewData& v = views[raster_views[i]];
        const auto& projected = scratch->projected[i];
        const auto& range = scratch->row_range[i];
        const uint16_t view = static_cast<uint16_t>(i);
        for (int gy = 0; gy + 1 < v.grid_h; ++gy) {
          if (!(range[gy].y() >= y0 - 0.5f && range[gy].x() <= y1 + 0.5f)) continue;
          for (int gx = 0; gx + 1 < v.grid_w; ++gx) {
            const size_t g = static_cast<size_t>(gy) * v.grid_w + gx;
            const size_t corners[4] = {g, g + 1, g + v.grid_w, g + v.grid_w + 1};
            const uint8_t flags = v.quad_triangles[static_cast<size_t>(gy) * (v.grid_w - 1) + gx];
            if (flags == 0) continue;
            // Triangles (a, b, c) and (b, d, c) of the quad a b / c d.
            const int tris[2][3] = {{0, 1, 2}, {1, 3, 2}};
            for (int t = 0; t < 2; ++t) {
              const int* tri = tris[t];
              if ((flags & (1 << t)) == 0) continue;
              if (!std::isfinite(projected[corners[tri[0]]].x()) ||
                  !std::isfinite(projected[corners[tri[1]]].x()) ||
                  !std::isfinite(projected[corners[tri[2]]].x())) {
                continue;
              }
              const Eigen::Vector3f& pa = projected[corners[tri[0]]];
              const Eigen::Vector3f& pb = projected[corners[tri[1]]];
              const Eigen::Vector3f& pc = projected[corners[tri[2]]];
              if (std::max({pa.y(), pb.y(), pc.y()}) < y0 ||
                  std::min({pa.y(), pb.y(), pc.y()}) > y1) {
                continue;
              }
              triangle(pa, pb, pc, view);
            }
          }
        }
      }
      // Resolve: the nearest surface confirmed by a second view, else the nearest one.
      for (int y = y0; y < y1; ++y) {
        float* out = scratch->novel_depth.row(y);
        for (int x = 0; x < width; ++x) {
          const DepthLayers& l = layers[static_cast<size_t>(y - y0) * width + x];
          float z = l.count > 0 ? l.depth[0] : kNaN;
          for (int k = 0; k + 1 < l.count; ++k) {
            if (l.depth[k + 1] <= l.depth[k] * (1.0f + tolerance)) {
              z = l.depth[k];
              break;
            }
          }
          out[x] = z;
        }
      }
    }
  });
}

// Step 2-5 of the header: per-pixel fusion given the novel view's depth (sampled at the pixel
// centres; `depth` has the novel view's size).
void ImageBasedRenderer::State::Fuse(const render::CameraRays& rays, const camera::Pose& pose,
                                     const Image& depth, int /*depth_stride*/,
                                     render::Rephoto* out) const {
  const int width = rays.width(), height = rays.height();
  out->color.Resize(width, height, 4);
  out->depth.Resize(width, height, 1);
  const Eigen::Matrix3f world_from_cam = pose.rotation.transpose().cast<float>();
  const Eigen::Vector3f origin = pose.Center().cast<float>();
  const int k_best = options.k_best;
  const float tolerance = static_cast<float>(options.depth_tolerance);
  const float depth_penalty = static_cast<float>(options.depth_penalty);
  const float epsilon = static_cast<float>(options.epipole_epsilon);
  const float resolution_penalty = static_cast<float>(options.resolution_penalty);
  // Resolution penalty only: the world point of every pixel with depth (NaN elsewhere), each
  // computed once for the finite differences of its four neighbours.
  std::vector<Eigen::Vector3f> points;
  if (resolution_penalty > 0) {
    points.assign(static_cast<size_t>(width) * height, Eigen::Vector3f::Constant(kNaN));
    ParallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
      for (int64_t y = y0; y < y1; ++y) {
        for (int x = 0; x < width; ++x) {
          const float z = depth.at(x, static_cast<int>(y));
          float xn, yn;
          if (!std::isfinite(z) || !rays.Ray(x + 0.5f, y + 0.5f, &xn, &yn)) continue;
          points[static_cast<size_t>(y) * width + x] =
              origin + world_from_cam * Eigen::Vector3f(xn * z, yn * z, z);
        }
      }
    });
  }
  // dX along one image axis at (x, y) (header, step 3): the central difference, or the one-sided
  // one when one neighbour is missing or beyond 10 * depth_tolerance; false when neither is.
  const float neighbour_tolerance = 10 * tolerance;
  auto derivative = [&](int x, int y, int dx, int dy, float z, const Eigen::Vector3f& X,
                        Eigen::Vector3f* d) {
    const Eigen::Vector3f* P[2] = {nullptr, nullptr};
    for (int s = 0; s < 2; ++s) {
      const int nx = x + (s ? dx : -dx), ny = y + (s ? dy : -dy);
      if (nx < 0 || ny < 0 || nx >= width || ny >= height) continue;
      const float zn = depth.at(nx, ny);
      const Eigen::Vector3f& p = points[static_cast<size_t>(ny) * width + nx];
      if (std::abs(zn - z) <= neighbour_tolerance * z && std::isfinite(p.x())) P[s] = &p;
    }
    if (P[0] && P[1]) {
      *d = 0.5f * (*P[1] - *P[0]);
    } else if (P[1]) {
      *d = *P[1] - X;
    } else if (P[0]) {
      *d = X - *P[0];
    } else {
      return false;
    }
    return true;
  };

  // Candidate views for this novel view (RankViews at the median depth of the view).
  const std::vector<int> ranked = RankViews(views, pose, MedianDepth(depth, typical_depth));
  const int m = static_cast<int>(ranked.size());
  int candidates[kMaxCandidates];
  Eigen::Vector3f centers[kMaxCandidates];
  for (int i = 0; i < m; ++i) {
    candidates[i] = ranked[i];
    centers[i] = views[candidates[i]].center;
  }

  ParallelFor(0, height, 4, [&](int64_t row_begin, int64_t row_end) {
    struct Accepted {
      float penalty;
      float rgb[3];
    };
    Accepted accepted[kMaxK + 1];
    // Candidates by increasing angle: the order of the previous pixel is re-sorted by insertion
    // (neighbouring pixels have nearly the same order, so this is close to linear).
    int order[kMaxCandidates];
    float key[kMaxCandidates];  // -cos of the angle, per candidate
    for (int i = 0; i < m; ++i) order[i] = i;
    std::pair<float, float> samples[kMaxK];
    for (int64_t yy = row_begin; yy < row_end; ++yy) {
      const int y = static_cast<int>(yy);
      float* rgba = out->color.row(y);
      float* zout = out->depth.row(y);
      for (int x = 0; x < width; ++x) {
        rgba[4 * x] = rgba[4 * x + 1] = rgba[4 * x + 2] = rgba[4 * x + 3] = 0;
        zout[x] = kNaN;
        const float z = depth.at(x, y);
        float xn, yn;
        if (!std::isfinite(z) || !rays.Ray(x + 0.5f, y + 0.5f, &xn, &yn)) continue;
        const Eigen::Vector3f X = origin + world_from_cam * Eigen::Vector3f(xn * z, yn * z, z);
        const Eigen::Vector3f to_novel = (origin - X).normalized();
        // The novel pixel's footprint and the surface normal (resolution penalty only).
        Eigen::Vector3f normal = Eigen::Vector3f::Zero();
        float novel_area = 0;
        if (resolution_penalty > 0) {
          Eigen::Vector3f dx, dy;
          if (derivative(x, y, 1, 0, z, X, &dx) && derivative(x, y, 0, 1, z, X, &dy)) {
            normal = dx.cross(dy);
            novel_area = normal.norm();
            if (novel_area > 0) normal /= novel_area;
          }
        }
        for (int i = 0; i < m; ++i) {
          const Eigen::Vector3f d = centers[i] - X;
          key[i] = -to_novel.dot(d) / d.norm();
        }
        for (int i = 1; i < m; ++i) {
          const int c = order[i];
          int j = i;
          while (j > 0 && key[order[j - 1]] > key[c]) {
            order[j] = order[j - 1];
            --j;
          }
          order[j] = c;
        }
        int count = 0;
        for (int j = 0; j < m; ++j) {
          const float angle = std::acos(std::clamp(-key[order[j]], -1.f, 1.f));
          if (count == k_best + 1 && angle >= accepted[k_best].penalty) break;
          const ViewData& v = views[candidates[order[j]]];
          float u, w, zi;
          if (!v.Project(X, &u, &w, &zi)) continue;
          if (!(u >= 0.5f && w >= 0.5f && u <= v.width - 0.5f && w <= v.height - 0.5f)) continue;
          // Visibility against the view's depth map (see the header): 1/z interpolated
          // bilinearly between the four depth pixels around the projection, or the nearest
          // one when some of them have no depth.
          const float du = u * v.depth_sx - 0.5f, dv = w * v.depth_sy - 0.5f;
          const int dw = v.depth.width(), dh = v.depth.height();
          const int bx = std::clamp(static_cast<int>(std::floor(du)), 0, std::max(0, dw - 2));
          const int by = std::clamp(static_cast<int>(std::floor(dv)), 0, std::max(0, dh - 2));
          const int bx1 = std::min(bx + 1, dw - 1), by1 = std::min(by + 1, dh - 1);
          const float ax = std::clamp(du - bx, 0.f, 1.f), ay = std::clamp(dv - by, 0.f, 1.f);
          const float d00 = v.Depth(bx, by), d10 = v.Depth(bx1, by), d01 = v.Depth(bx, by1),
                      d11 = v.Depth(bx1, by1);
          float surface;
          bool smooth =
              std::isfinite(d00) && std::isfinite(d10) && std::isfinite(d01) && std::isfinite(d11);
          if (smooth) {
            const float inverse =
                (1 - ay) * ((1 - ax) / d00 + ax / d10) + ay * ((1 - ax) / d01 + ax / d11);
            surface = 1.0f / inverse;
          } else {
            surface = v.Depth(ax < 0.5f ? bx : bx1, ay < 0.5f ? by : by1);
          }
          const float limit = tolerance * zi;
          const float depth_error = std::abs(surface - zi);
          if (!(depth_error <= limit)) continue;
          Accepted a;
          a.penalty = angle + depth_penalty * (depth_error / limit);
          if (novel_area > 0) {
            const Eigen::Vector3f ray = v.center - X;
            const float distance = ray.norm();
            // Edge-on (cosine 0) the footprint is unbounded; 1e-3 keeps the penalty finite
            // (at most about 10 doublings more than at 45 degrees).
            const float cosine = std::max(1e-3f, std::abs(normal.dot(ray)) / distance);
            const float area = zi * zi * zi / (v.fx * v.fy * distance * cosine);
            if (area > novel_area) a.penalty += resolution_penalty * std::log2(area / novel_area);
          }
          if (count == k_best + 1 && a.penalty >= accepted[k_best].penalty) continue;
          if (smooth) {
            v.Bilinear(u, w, a.rgb);
          } else {
            v.Nearest(u, w, a.rgb);
          }
          int k = std::min(count, k_best);
          while (k > 0 && accepted[k - 1].penalty > a.penalty) {
            accepted[k] = accepted[k - 1];
            --k;
          }
          accepted[k] = a;
          count = std::min(count + 1, k_best + 1);
        }
        if (count == 0) continue;
        const int used = std::min(count, k_best);
        const float threshold =
            count > k_best ? accepted[k_best].penalty : 2.0f * accepted[used - 1].penalty + epsilon;
        float weights[kMaxK];
        float total = 0;
        for (int i = 0; i < used; ++i) {
          const float p = accepted[i].penalty;
          weights[i] = std::max(0.f, 1.0f - p / threshold) / (p + epsilon);
          total += weights[i];
        }
        if (!(total > 0)) {
          for (int i = 0; i < used; ++i) weights[i] = 1;
        }
        for (int c = 0; c < 3; ++c) {
          for (int i = 0; i < used; ++i) samples[i] = {accepted[i].rgb[c], weights[i]};
          rgba[4 * x + c] =
              render::WeightedMedian(std::span<std::pair<float, float>>(samples, used));
        }
        rgba[4 * x + 3] = 1;
        zout[x] = z;
      }
    }
  });
}

ImageBasedRenderer::ImageBasedRenderer(std::unique_ptr<State> state) : state_(std::move(state)) {}
ImageBasedRenderer::ImageBasedRenderer(ImageBasedRenderer&&) noexcept = default;
ImageBasedRenderer& ImageBasedRenderer::operator=(ImageBasedRenderer&&) noexcept = default;
ImageBasedRenderer::~ImageBasedRenderer() = default;

ImageBasedRenderer ImageBasedRenderer::Vdt(const mesh::Mesh& proxy,
                                           std::vector<TrainingView> training,
                                           const ImageBasedOptions& options) {
  ValidateOptions(options);
  REPHOTO_CHECK(!proxy.faces.empty(), "view-dependent texturing: the proxy mesh has no triangles");
  auto state = std::make_unique<State>();
  state->options = options;
  mesh::Mesh geometry;
  geometry.positions = proxy.positions;
  geometry.faces = proxy.faces;
  render::ModelOptions model_options;
  model_options.load_textures = false;
  state->proxy = std::make_unique<render::RenderModel>(std::move(geometry), model_options, "proxy");
  state->LoadPhotos(std::move(training));
  render::RenderOptions render_options;
  render_options.samples_per_pixel = 1;
  render_options.pattern = render::SamplePattern::kRegular;
  render::Rephoto rendering;
  for (ViewData& v : state->views) {
    render::RenderRephoto(*state->proxy, *state->RaysFor(v.camera), v.info.cam_from_world,
                          render_options, &rendering);
    v.depth = rendering.depth;
    v.depth_sx = v.depth_sy = 1;
  }
  state->ComputeTypicalDepth();
  return ImageBasedRenderer(std::move(state));
}

ImageBasedRenderer ImageBasedRenderer::Ibr(std::vector<TrainingView> training,
                                           const ImageBasedOptions& options) {
  ValidateOptions(options);
  auto state = std::make_unique<State>();
  state->options = options;
  state->ibr = true;
  std::vector<bool> estimate;
  for (const TrainingView& t : training) estimate.push_back(t.depth_map.empty() && !t.depth);
  const bool need_sweep = std::find(estimate.begin(), estimate.end(), true) != estimate.end();
  if (need_sweep) {
    REPHOTO_CHECK(training.size() >= 2,
                  "image-based rendering: plane sweep needs at least 2 training views");
  }
  std::vector<Image> estimated;
  if (need_sweep) estimated = EstimateDepthMaps(training, estimate, options);
  state->LoadPhotos(std::move(training));
  ParallelFor(0, static_cast<int64_t>(state->views.size()), 1, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      ViewData& v = state->views[i];
      if (v.info.depth) {
        REPHOTO_CHECK(v.info.depth->width() > 0 && v.info.depth->height() > 0 &&
                          v.info.depth->channels() == 1,
                      "image-based rendering: {}: in-memory depth map is empty or not 1 channel",
                      v.info.name);
        v.depth = *v.info.depth;
      } else if (!v.info.depth_map.empty()) {
        v.depth = ReadDepthMap(v.info.depth_map);
      } else {
        v.depth = std::move(estimated[i]);
      }
    }
  });
  for (ViewData& v : state->views) {
    v.depth_sx = static_cast<float>(v.depth.width()) / v.width;
    v.depth_sy = static_cast<float>(v.depth.height()) / v.height;
  }
  state->BuildProxyGrids();
  state->ComputeTypicalDepth();
  return ImageBasedRenderer(std::move(state));
}

render::Rephoto ImageBasedRenderer::Render(const camera::Camera& camera,
                                           const camera::Pose& cam_from_world) const {
  render::Rephoto out;
  Render(camera, cam_from_world, &out);
  return out;
}

void ImageBasedRenderer::Render(const camera::Camera& camera, const camera::Pose& cam_from_world,
                                render::Rephoto* out) const {
  camera.Validate("image-based rendering: camera");
  cam_from_world.Validate("image-based rendering: pose");
  const State& s = *state_;
  // Borrow the shared scratch buffers, or use private ones when another call holds them.
  std::unique_ptr<Scratch> scratch;
  {
    std::lock_guard<std::mutex> lock(s.scratch_mutex);
    scratch = std::move(s.scratch);
  }
  if (!scratch) scratch = std::make_unique<Scratch>();
  const auto rays = s.RaysFor(camera);
  if (s.ibr) {
    std::vector<int> raster_views = RankViews(s.views, cam_from_world, s.typical_depth);
    if (raster_views.size() > static_cast<size_t>(kRasterViewsPerK * s.options.k_best)) {
      raster_views.resize(static_cast<size_t>(kRasterViewsPerK * s.options.k_best));
    }
    s.RasterizeProxies(camera, cam_from_world, raster_views, scratch.get());
    s.Fuse(*rays, cam_from_world, scratch->novel_depth, 1, out);
  } else {
    render::RenderOptions options;
    options.samples_per_pixel = 1;
    options.pattern = render::SamplePattern::kRegular;
    render::RenderRephoto(*s.proxy, *rays, cam_from_world, options, &scratch->geometry);
    s.Fuse(*rays, cam_from_world, scratch->geometry.depth, 1, out);
  }
  std::lock_guard<std::mutex> lock(s.scratch_mutex);
  if (!s.scratch) s.scratch = std::move(scratch);
}

size_t ImageBasedRenderer::view_count() const { return state_->views.size(); }
const TrainingView& ImageBasedRenderer::view(size_t index) const {
  return state_->views.at(index).info;
}
const Image& ImageBasedRenderer::depth_map(size_t index) const {
  return state_->views.at(index).depth;
}

}  // namespace rephoto::ibr
