#include "rephoto/texture/view_selection.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/progress.h"
#include "rephoto/render/visibility.h"
#include "rephoto/texture/photo.h"

namespace rephoto::texture {
namespace {

// Sum of the gradient (plus floor) and of the colour over the pixel centres inside the
// triangle a, b, c (pixel coordinates); returns the number of those pixels.
size_t IntegrateTriangle(const Photo& photo, const Image& gradient, const Eigen::Vector2d& a,
                         const Eigen::Vector2d& b, const Eigen::Vector2d& c, float floor,
                         double* quality, Eigen::Vector3f* color_sum) {
  const double area2 = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
  if (!(std::abs(area2) > 0)) return 0;
  const double sign = area2 > 0 ? 1.0 : -1.0;
  const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}) - 0.5)));
  const int x1 = std::min(photo.width() - 1,
                          static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}) - 0.5)));
  const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}) - 0.5)));
  const int y1 = std::min(photo.height() - 1,
                          static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}) - 0.5)));
  auto edge = [sign](const Eigen::Vector2d& p, const Eigen::Vector2d& q, double x, double y) {
    return sign * ((q.x() - p.x()) * (y - p.y()) - (q.y() - p.y()) * (x - p.x()));
  };
  size_t count = 0;
  double sum = 0;
  Eigen::Vector3f colors = Eigen::Vector3f::Zero();
  for (int y = y0; y <= y1; ++y) {
    const double cy = y + 0.5;
    const float* g = gradient.row(y);
    for (int x = x0; x <= x1; ++x) {
      const double cx = x + 0.5;
      if (edge(a, b, cx, cy) < 0 || edge(b, c, cx, cy) < 0 || edge(c, a, cx, cy) < 0) continue;
      ++count;
      sum += g[x] + floor;
      colors += photo.Pixel(x, y);
    }
  }
  *quality = sum;
  *color_sum = colors;
  return count;
}

struct Found {
  uint32_t face;
  FaceCandidate candidate;
};

// The face's sample points for visibility: the centroid and the points of a barycentric grid
// with n + 1 points per edge (n = 1: the corners), each moved 1 % of the way towards the
// centroid so that the neighbours sharing a corner or an edge do not count. n grows with the
// face's projected size (one row of points per 24 pixels of its longest projected edge, at
// most 12), so that a large face is not called visible when an object hides its middle but
// not its corners.
void FacePoints(const mesh::Mesh& mesh, size_t face, const Eigen::Vector3d& centroid,
                const Eigen::Vector2d* pixels, std::vector<Eigen::Vector3d>& points) {
  double longest = 0;
  for (int k = 0; k < 3; ++k) longest = std::max(longest, (pixels[(k + 1) % 3] - pixels[k]).norm());
  const int n = std::clamp(static_cast<int>(std::ceil(longest / 24.0)), 1, 12);
  const Eigen::Vector3d p0 = mesh.positions[mesh.faces[face][0]].cast<double>();
  const Eigen::Vector3d p1 = mesh.positions[mesh.faces[face][1]].cast<double>();
  const Eigen::Vector3d p2 = mesh.positions[mesh.faces[face][2]].cast<double>();
  points.clear();
  points.push_back(centroid);
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; i + j <= n; ++j) {
      const Eigen::Vector3d p = (i * p0 + j * p1 + (n - i - j) * p2) / n;
      points.push_back(p + 0.01 * (centroid - p));
    }
  }
}

// The fraction of `points` that no surface hides from the camera centre (render/visibility.h
// OcclusionBatch). With `all_or_nothing` it returns 0 as soon as a batch has a hidden point.
double UnoccludedFraction(render::OcclusionBatch& batch, const std::vector<Eigen::Vector3d>& points,
                          bool all_or_nothing) {
  size_t visible = 0, traced = 0;
  auto count = [&](uint32_t) { ++visible; };
  for (size_t i = 0; i < points.size(); ++i) {
    batch.Add(points[i], static_cast<uint32_t>(i), count);
    if ((i + 1) % 16 == 0) {
      traced = i + 1;
      if (all_or_nothing && visible < traced) return 0;
    }
  }
  batch.Flush(count);
  if (all_or_nothing && visible < points.size()) return 0;
  return points.empty() ? 0 : static_cast<double>(visible) / static_cast<double>(points.size());
}

// Keeps the points that project inside the photo (half a pixel from the border) and its usable
// field; returns the fraction kept.
double KeepInside(const render::ViewGeometry& geometry, std::vector<Eigen::Vector3d>& points) {
  const size_t total = points.size();
  size_t kept = 0;
  for (const Eigen::Vector3d& p : points) {
    if (render::UsableProjection(geometry, p, 0.5)) points[kept++] = p;
  }
  points.resize(kept);
  return total == 0 ? 0 : static_cast<double>(kept) / static_cast<double>(total);
}

}  // namespace

Candidates ComputeCandidates(const render::RenderModel& model, const scene::Scene& scene,
                             const std::vector<size_t>& views, const CandidateOptions& options) {
  const mesh::Mesh& mesh = model.mesh();
  const size_t face_count = mesh.faces.size();
  std::vector<Eigen::Vector3d> normals(face_count), centroids(face_count);
  std::vector<double> areas(face_count);
  for (size_t f = 0; f < face_count; ++f) {
    const Eigen::Vector3d p0 = mesh.positions[mesh.faces[f][0]].cast<double>();
    const Eigen::Vector3d p1 = mesh.positions[mesh.faces[f][1]].cast<double>();
    const Eigen::Vector3d p2 = mesh.positions[mesh.faces[f][2]].cast<double>();
    const Eigen::Vector3d n = (p1 - p0).cross(p2 - p0);
    areas[f] = 0.5 * n.norm();
    normals[f] = areas[f] > 0 ? Eigen::Vector3d(n / (2 * areas[f])) : Eigen::Vector3d::Zero();
    centroids[f] = (p0 + p1 + p2) / 3.0;
  }
  constexpr int64_t kBlock = 4096;
  const int64_t blocks = (static_cast<int64_t>(face_count) + kBlock - 1) / kBlock;
  std::vector<std::vector<std::vector<Found>>> found(
      views.size(), std::vector<std::vector<Found>>(static_cast<size_t>(blocks)));
  std::unique_ptr<Progress> progress;
  if (options.show_progress) progress = std::make_unique<Progress>("texture: views", views.size());
  RTCScene rtc_scene = model.scene();
  const float floor = static_cast<float>(options.gradient_floor);
  // Photos are decoded two at a time (one core each), then processed in list order.
  std::vector<Photo> batch(2);
  Image gradient;
  for (size_t position = 0; position < views.size(); ++position) {
    if (position % 2 == 0) {
      const size_t count = std::min<size_t>(2, views.size() - position);
      ParallelFor(0, static_cast<int64_t>(count), 1, [&](int64_t begin, int64_t end) {
        for (int64_t b = begin; b < end; ++b) {
          batch[b].Load(scene, scene.views[views[position + b]]);
        }
      });
    }
    const Photo& photo = batch[position % 2];
    GradientMagnitude(photo, &gradient);
    const render::ViewGeometry geometry(photo.camera(), photo.cam_from_world());
    render::VisibilityRule rule;
    rule.min_facing_cosine = options.min_facing_cosine;
    rule.occlusion_epsilon = options.occlusion_epsilon;
    ParallelFor(0, blocks, 1, [&](int64_t block_begin, int64_t block_end) {
      render::OcclusionBatch batch(rtc_scene, geometry.center, rule.occlusion_epsilon);
      std::vector<Eigen::Vector3d> points;
      for (int64_t block = block_begin; block < block_end; ++block) {
        std::vector<Found>& out = found[position][block];
        const int64_t end = std::min<int64_t>((block + 1) * kBlock, face_count);
        for (int64_t f = block * kBlock; f < end; ++f) {
          if (!(areas[f] > 0)) continue;
          // The face's centroid faces the camera and its corners lie in the usable field (the
          // rule of render/visibility.h, per face).
          const Eigen::Vector3d to_camera = geometry.center - centroids[f];
          const double distance = to_camera.norm();
          if (!(distance > 0) || !(normals[f].dot(to_camera) / distance > rule.min_facing_cosine)) {
            continue;
          }
          Eigen::Vector2d pixels[3];
          bool projected = true, inside = true;
          for (int k = 0; k < 3 && projected; ++k) {
            const auto pixel =
                render::ProjectInField(geometry, mesh.positions[mesh.faces[f][k]].cast<double>());
            projected = pixel.has_value();
            if (!projected) break;
            pixels[k] = *pixel;
            inside = inside && render::InsideImage(photo.camera(), *pixel, rule.border_pixels);
          }
          if (!projected) continue;
          FacePoints(mesh, f, centroids[f], pixels, points);
          double fraction = 0;
          if (inside) fraction = UnoccludedFraction(batch, points, true);
          bool partial = false;
          if (fraction < 1) {
            if (!(options.partial_min_fraction > 0 && options.partial_min_fraction <= 1)) continue;
            fraction = KeepInside(geometry, points);
            if (fraction < options.partial_min_fraction) continue;
            fraction *= UnoccludedFraction(batch, points, false);
            if (fraction < options.partial_min_fraction) continue;
            partial = true;
          }
          double quality = 0;
          Eigen::Vector3f color_sum;
          const size_t covered = IntegrateTriangle(photo, gradient, pixels[0], pixels[1], pixels[2],
                                                   floor, &quality, &color_sum);
          FaceCandidate candidate;
          candidate.view = static_cast<uint32_t>(position);
          if (covered > 0) {
            candidate.color = color_sum / static_cast<float>(covered);
          } else {
            const Eigen::Vector2d c = (pixels[0] + pixels[1] + pixels[2]) / 3.0;
            const Eigen::Vector2d e1 = pixels[1] - pixels[0], e2 = pixels[2] - pixels[0];
            const double area = 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
            const int gx = std::clamp(static_cast<int>(c.x()), 0, photo.width() - 1);
            const int gy = std::clamp(static_cast<int>(c.y()), 0, photo.height() - 1);
            quality = area * (gradient.at(gx, gy) + floor);
            candidate.color = photo.Sample(c.x(), c.y());
          }
          candidate.quality =
              static_cast<float>(partial ? quality * fraction * options.partial_weight : quality);
          candidate.partial = partial;
          out.push_back({static_cast<uint32_t>(f), candidate});
        }
      }
    });
    if (progress) progress->Advance(scene.views[views[position]].name);
  }
  if (progress) progress->Finish();

  // Gather per face, views in list order.
  Candidates result;
  result.offsets.assign(face_count + 1, 0);
  for (const auto& view_blocks : found) {
    for (const auto& list : view_blocks) {
      for (const Found& item : list) ++result.offsets[item.face + 1];
    }
  }
  for (size_t f = 0; f < face_count; ++f) result.offsets[f + 1] += result.offsets[f];
  result.items.resize(result.offsets.back());
  std::vector<uint32_t> fill(result.offsets.begin(), result.offsets.end() - 1);
  for (auto& view_blocks : found) {
    for (auto& list : view_blocks) {
      for (const Found& item : list) result.items[fill[item.face]++] = item.candidate;
      std::vector<Found>().swap(list);
    }
  }
  // Partial candidates only serve faces that no photo sees whole.
  size_t write = 0;
  for (size_t f = 0; f < face_count; ++f) {
    const uint32_t begin = result.offsets[f], end = result.offsets[f + 1];
    const bool has_full = std::any_of(result.items.begin() + begin, result.items.begin() + end,
                                      [](const FaceCandidate& c) { return !c.partial; });
    result.offsets[f] = static_cast<uint32_t>(write);
    for (uint32_t k = begin; k < end; ++k) {
      if (!has_full || !result.items[k].partial) result.items[write++] = result.items[k];
    }
  }
  result.offsets[face_count] = static_cast<uint32_t>(write);
  result.items.resize(write);
  return result;
}

size_t RemoveInconsistentCandidates(Candidates* candidates, const ConsistencyOptions& options) {
  const size_t face_count = candidates->face_count();
  std::vector<uint8_t> keep(candidates->items.size(), 1);
  const double inv_two_h2 = 1.0 / (2 * options.bandwidth * options.bandwidth);
  ParallelFor(0, static_cast<int64_t>(face_count), 4096, [&](int64_t begin, int64_t end) {
    std::vector<float> values;
    std::vector<double> distances;
    for (int64_t f = begin; f < end; ++f) {
      const uint32_t first = candidates->offsets[f], last = candidates->offsets[f + 1];
      const size_t n = last - first;
      if (n < 3) continue;
      const FaceCandidate* items = candidates->items.data() + first;
      Eigen::Vector3d mode;
      for (int c = 0; c < 3; ++c) {
        values.clear();
        for (size_t i = 0; i < n; ++i) values.push_back(items[i].color[c]);
        std::nth_element(values.begin(), values.begin() + n / 2, values.end());
        mode[c] = values[n / 2];
      }
      for (int it = 0; it < 20; ++it) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        double weight_sum = 0;
        for (size_t i = 0; i < n; ++i) {
          const double d2 = (items[i].color.cast<double>() - mode).squaredNorm();
          const double w = std::exp(-d2 * inv_two_h2);
          sum += w * items[i].color.cast<double>();
          weight_sum += w;
        }
        if (!(weight_sum > 1e-12)) break;
        const Eigen::Vector3d next = sum / weight_sum;
        const bool converged = (next - mode).norm() < 1e-5;
        mode = next;
        if (converged) break;
      }
      distances.clear();
      for (size_t i = 0; i < n; ++i) {
        distances.push_back((items[i].color.cast<double>() - mode).norm());
      }
      std::vector<double> sorted = distances;
      std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
      const double threshold =
          std::max(options.threshold_sigmas * 1.4826 * sorted[n / 2], options.min_threshold);
      for (size_t i = 0; i < n; ++i) {
        if (distances[i] > threshold) keep[first + i] = 0;
      }
    }
  });
  Candidates filtered;
  filtered.offsets.assign(face_count + 1, 0);
  filtered.items.reserve(candidates->items.size());
  for (size_t f = 0; f < face_count; ++f) {
    for (uint32_t k = candidates->offsets[f]; k < candidates->offsets[f + 1]; ++k) {
      if (keep[k]) filtered.items.push_back(candidates->items[k]);
    }
    filtered.offsets[f + 1] = static_cast<uint32_t>(filtered.items.size());
  }
  const size_t removed = candidates->items.size() - filtered.items.size();
  *candidates = std::move(filtered);
  return removed;
}

PottsProblem MakeViewSelectionProblem(const Candidates& candidates,
                                      const std::vector<std::pair<uint32_t, uint32_t>>& face_pairs,
                                      float smoothness) {
  PottsProblem problem;
  problem.offsets = candidates.offsets;
  problem.labels.resize(candidates.items.size());
  problem.costs.resize(candidates.items.size());
  double q_max = 0;
  if (!candidates.items.empty()) {
    std::vector<float> qualities;
    qualities.reserve(candidates.items.size());
    for (const FaceCandidate& c : candidates.items) qualities.push_back(c.quality);
    const size_t k = std::min(qualities.size() - 1, qualities.size() * 99 / 100);
    std::nth_element(qualities.begin(), qualities.begin() + k, qualities.end());
    q_max = qualities[k];
  }
  for (size_t i = 0; i < candidates.items.size(); ++i) {
    problem.labels[i] = static_cast<int>(candidates.items[i].view);
    const double q = q_max > 0 ? candidates.items[i].quality / q_max : 1.0;
    problem.costs[i] = static_cast<float>(1.0 - std::min(1.0, q));
  }
  problem.edges = face_pairs;
  problem.smoothness = smoothness;
  return problem;
}

}  // namespace rephoto::texture
