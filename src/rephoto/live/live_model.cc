#include "rephoto/live/live_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <set>

#include "rephoto/core/error.h"

namespace rephoto::live {

double Envelope::ObservedFraction() const {
  double all = 0, seen = 0;
  for (size_t i = 0; i < area.size(); ++i) {
    all += area[i];
    if (observed[i]) seen += area[i];
  }
  return all > 0 ? seen / all : 0.0;
}

bool NearestPointToAxes(const std::vector<camera::Pose>& poses, Eigen::Vector3d* point) {
  if (poses.size() < 2) return false;
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const camera::Pose& p : poses) {
    const Eigen::Vector3d d = p.ViewDirection().normalized();
    const Eigen::Matrix3d m = Eigen::Matrix3d::Identity() - d * d.transpose();
    a += m;
    b += m * p.Center();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(a);
  const Eigen::Vector3d ev = solver.eigenvalues();
  // Nearly parallel axes: the smallest eigenvalue (along the common direction) vanishes.
  if (!(ev[0] > 0.02 * ev[2])) return false;
  *point = a.ldlt().solve(b);
  // A point behind most cameras is no look-at point.
  int in_front = 0;
  for (const camera::Pose& p : poses) in_front += p.CamFromWorld(*point).z() > 0;
  return in_front * 2 > static_cast<int>(poses.size());
}

namespace {
constexpr double kFacing = 0.1;  // cosine: the camera sees the direction from outside
}  // namespace

Envelope BuildEnvelope(const std::vector<camera::Pose>& poses,
                       const std::vector<EnvelopeInput>& depths, const EnvelopeOptions& options) {
  REPHOTO_CHECK(!poses.empty(), "envelope: no photos");
  REPHOTO_CHECK(options.bands >= 2 && options.segments >= 3 && options.stride >= 1 &&
                    options.min_points >= 1 && options.min_views >= 1,
                "envelope: invalid options");
  // Depth points.
  std::vector<Eigen::Vector3d> points;
  std::vector<int> source;
  std::vector<Eigen::Vector3d> seen_from;  // camera centre of each point
  for (size_t k = 0; k < depths.size(); ++k) {
    const EnvelopeInput& in = depths[k];
    const Image& d = *in.depth;
    const Eigen::Matrix3d world_from_cam = in.cam_from_world.rotation.transpose();
    const Eigen::Vector3d origin = in.cam_from_world.Center();
    for (int y = options.stride / 2; y < d.height(); y += options.stride) {
      for (int x = options.stride / 2; x < d.width(); x += options.stride) {
        const float z = d.at(x, y);
        if (!(z > 0) || !std::isfinite(z)) continue;
        const std::optional<Eigen::Vector3d> ray = in.camera.CamFromImg({x + 0.5, y + 0.5});
        if (!ray) continue;
        const Eigen::Vector3d cam = *ray / ray->z() * z;
        points.push_back(origin + world_from_cam * cam);
        source.push_back(static_cast<int>(k));
        seen_from.push_back(origin);
      }
    }
  }
  Envelope env;
  env.point_count = points.size();
  // Up: mean of the cameras' -y axes (COLMAP cameras: y points down in the image).
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  for (const camera::Pose& p : poses) up -= p.rotation.row(1).transpose();
  env.up = up.norm() > 1e-9 ? up.normalized() : Eigen::Vector3d::UnitZ();
  if (!NearestPointToAxes(poses, &env.center)) {
    if (!points.empty()) {
      for (int a = 0; a < 3; ++a) {
        std::vector<double> v;
        for (const auto& p : points) v.push_back(p[a]);
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        env.center[a] = v[v.size() / 2];
      }
    } else {
      env.center = poses[0].Center() + poses[0].ViewDirection();
    }
  }
  const Eigen::Vector3d& c = env.center;
  Eigen::Vector3d ex = env.up.unitOrthogonal();
  Eigen::Vector3d ey = env.up.cross(ex);
  const int rows = options.bands, cols = options.segments;
  // Vertex layout: 0 = north pole (up), 1 + r * cols + s for rows r = 0..rows-1, last = south.
  const size_t n = 2 + static_cast<size_t>(rows) * cols;
  auto dir_of = [&](size_t v) -> Eigen::Vector3d {
    if (v == 0) return env.up;
    if (v == n - 1) return -env.up;
    const int r = static_cast<int>((v - 1) / cols), s = static_cast<int>((v - 1) % cols);
    const double theta = M_PI * (r + 1) / (rows + 1);  // from the north pole
    const double phi = 2 * M_PI * s / cols;
    return std::cos(theta) * env.up + std::sin(theta) * (std::cos(phi) * ex + std::sin(phi) * ey);
  };
  auto bin_of = [&](const Eigen::Vector3d& d) -> size_t {
    const double theta = std::acos(std::clamp(d.dot(env.up), -1.0, 1.0));
    const int r = static_cast<int>(std::lround(theta / M_PI * (rows + 1))) - 1;
    if (r < 0) return 0;
    if (r >= rows) return n - 1;
    double phi = std::atan2(d.dot(ey), d.dot(ex));
    if (phi < 0) phi += 2 * M_PI;
    const int s = static_cast<int>(std::lround(phi / (2 * M_PI) * cols)) % cols;
    return 1 + static_cast<size_t>(r) * cols + s;
  };
  std::vector<std::vector<float>> dist(n);
  std::vector<std::set<int>> views(n);
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d d = points[i] - c;
    const double r = d.norm();
    if (!(r > 1e-9)) continue;
    // A point counts for its direction only when its camera looked at it from outside the
    // envelope (from the side the direction points to): background seen past the object
    // (ground behind it) is not the object's far side.
    if ((seen_from[i] - points[i]).normalized().dot(d / r) < kFacing) continue;
    const size_t b = bin_of(d / r);
    dist[b].push_back(static_cast<float>(r));
    views[b].insert(source[i]);
  }
  std::vector<double> radius(n, 0.0);
  env.observed.assign(n, 0);
  std::vector<double> observed_r;
  for (size_t v = 0; v < n; ++v) {
    if (static_cast<int>(dist[v].size()) >= options.min_points &&
        static_cast<int>(views[v].size()) >= options.min_views) {
      auto& d = dist[v];
      const size_t k = static_cast<size_t>(0.2 * (d.size() - 1));
      std::nth_element(d.begin(), d.begin() + k, d.end());
      radius[v] = d[k];
      env.observed[v] = 1;
      observed_r.push_back(radius[v]);
    }
  }
  double median = 0;
  if (!observed_r.empty()) {
    std::nth_element(observed_r.begin(), observed_r.begin() + observed_r.size() / 2,
                     observed_r.end());
    median = observed_r[observed_r.size() / 2];
  } else {
    std::vector<double> dc;
    for (const camera::Pose& p : poses) dc.push_back((p.Center() - c).norm());
    std::nth_element(dc.begin(), dc.begin() + dc.size() / 2, dc.end());
    median = std::max(1e-3, dc[dc.size() / 2] / 4);
  }
  for (size_t v = 0; v < n; ++v) {
    radius[v] = env.observed[v] ? std::clamp(radius[v], 0.05 * median, 4 * median) : median;
  }
  // Grid neighbours.
  std::vector<std::vector<size_t>> nb(n);
  auto link = [&](size_t a, size_t b) {
    nb[a].push_back(b);
    nb[b].push_back(a);
  };
  auto vid = [&](int r, int s) { return 1 + static_cast<size_t>(r) * cols + ((s + cols) % cols); };
  for (int s = 0; s < cols; ++s) {
    link(0, vid(0, s));
    link(n - 1, vid(rows - 1, s));
    for (int r = 0; r < rows; ++r) {
      link(vid(r, s), vid(r, s + 1));
      if (r + 1 < rows) link(vid(r, s), vid(r + 1, s));
    }
  }
  // Harmonic fill of the unobserved radii.
  if (!observed_r.empty()) {
    std::vector<double> next = radius;
    for (int it = 0; it < 300; ++it) {
      for (size_t v = 0; v < n; ++v) {
        if (env.observed[v]) continue;
        double sum = 0;
        for (size_t u : nb[v]) sum += radius[u];
        next[v] = sum / nb[v].size();
      }
      radius.swap(next);
    }
  }
  env.mesh.positions.resize(n);
  for (size_t v = 0; v < n; ++v) env.mesh.positions[v] = (c + radius[v] * dir_of(v)).cast<float>();
  // Faces, counter-clockwise seen from outside. With theta measured from `up` and phi turning
  // from ex to ey = up x ex, (north, row0 s+1, row0 s) ... orientation fixed below by a test.
  std::vector<mesh::Triangle>& f = env.mesh.faces;
  auto tri = [&](size_t a, size_t b, size_t d) {
    f.push_back({static_cast<uint32_t>(a), static_cast<uint32_t>(b), static_cast<uint32_t>(d)});
  };
  for (int s = 0; s < cols; ++s) {
    tri(0, vid(0, s), vid(0, s + 1));
    tri(n - 1, vid(rows - 1, s + 1), vid(rows - 1, s));
    for (int r = 0; r + 1 < rows; ++r) {
      tri(vid(r, s), vid(r + 1, s), vid(r + 1, s + 1));
      tri(vid(r, s), vid(r + 1, s + 1), vid(r, s + 1));
    }
  }
  // Orientation: the first face's normal must point away from the centre.
  {
    const auto& t = f.front();
    const Eigen::Vector3f p0 = env.mesh.positions[t[0]], p1 = env.mesh.positions[t[1]],
                          p2 = env.mesh.positions[t[2]];
    const Eigen::Vector3f normal = (p1 - p0).cross(p2 - p0);
    if (normal.dot((p0 + p1 + p2) / 3 - c.cast<float>()) < 0) {
      for (auto& t2 : f) std::swap(t2[1], t2[2]);
    }
  }
  env.area.assign(n, 0.f);
  for (const auto& t : f) {
    const Eigen::Vector3f p0 = env.mesh.positions[t[0]], p1 = env.mesh.positions[t[1]],
                          p2 = env.mesh.positions[t[2]];
    const float a = 0.5f * (p1 - p0).cross(p2 - p0).norm() / 3;
    for (uint32_t v : t) env.area[v] += a;
  }
  return env;
}

}  // namespace rephoto::live

#include "rephoto/render/render_model.h"
#include "rephoto/suggest/next_views.h"

namespace rephoto::live {

std::vector<PlannedView> PlanNextViews(const render::RenderModel& surface, const Envelope& env,
                                       const std::vector<float>& need,
                                       const std::vector<camera::Pose>& photos,
                                       const camera::Camera& camera, const PlanOptions& options) {
  REPHOTO_CHECK(!photos.empty() && need.size() == env.mesh.positions.size(),
                "plan: no photos or a need per vertex missing");
  const Eigen::Vector3d& c = env.center;
  const Eigen::Vector3d& up = env.up;
  // Photo directions and elevations seen from the look-at point.
  std::vector<Eigen::Vector3d> taken;
  std::vector<double> dist;
  double el_lo = 1e9, el_hi = -1e9;
  for (const camera::Pose& p : photos) {
    const Eigen::Vector3d d = p.Center() - c;
    dist.push_back(d.norm());
    taken.push_back(d.normalized());
    const double el = std::asin(std::clamp(taken.back().dot(up), -1.0, 1.0));
    el_lo = std::min(el_lo, el);
    el_hi = std::max(el_hi, el);
  }
  std::nth_element(dist.begin(), dist.begin() + dist.size() / 2, dist.end());
  const double distance = dist[dist.size() / 2];
  const double margin = options.elevation_margin_degrees * M_PI / 180;
  const double low = el_lo > 0 ? std::max(0.0, el_lo - margin) : el_lo - margin;
  const double high = el_hi + margin;
  // Candidates.
  const Eigen::Vector3d ex = up.unitOrthogonal(), ey = up.cross(ex);
  const double golden = M_PI * (3 - std::sqrt(5.0));
  std::vector<Eigen::Vector3d> dirs;
  for (int i = 0; i < options.candidates; ++i) {
    const double z = 1 - 2 * (i + 0.5) / options.candidates;
    const double r = std::sqrt(std::max(0.0, 1 - z * z)), phi = golden * i;
    const double el = std::asin(z);
    if (el < low || el > high) continue;
    dirs.push_back(z * up + r * (std::cos(phi) * ex + std::sin(phi) * ey));
  }
  // Vertex normals (area weighted) for the visibility rule.
  std::vector<Eigen::Vector3f> normals(env.mesh.positions.size(), Eigen::Vector3f::Zero());
  for (const auto& t : env.mesh.faces) {
    const Eigen::Vector3f n = (env.mesh.positions[t[1]] - env.mesh.positions[t[0]])
                                  .cross(env.mesh.positions[t[2]] - env.mesh.positions[t[0]]);
    for (uint32_t v : t) normals[v] += n;
  }
  for (auto& n : normals) n.normalize();
  auto pose_of = [&](const Eigen::Vector3d& d) { return camera::LookAt(c + distance * d, c, up); };
  const camera::UsableField field(camera);
  std::vector<std::vector<uint8_t>> seen(dirs.size());
  std::vector<camera::Pose> poses(dirs.size());
  for (size_t k = 0; k < dirs.size(); ++k) {
    poses[k] = pose_of(dirs[k]);
    seen[k] = suggest::VisibleVertices(surface, normals, camera, poses[k], &field);
  }
  std::vector<double> weight(need.size());
  for (size_t v = 0; v < need.size(); ++v) weight[v] = env.area[v] * need[v];
  std::vector<PlannedView> out;
  std::vector<uint8_t> used(dirs.size(), 0);
  for (int pick = 0; pick < options.count; ++pick) {
    for (double max_gap = options.max_gap_degrees; max_gap <= 180; max_gap *= 2) {
      const double cos_min = std::cos(options.min_gap_degrees * M_PI / 180);
      const double cos_max = std::cos(max_gap * M_PI / 180);
      double best = -1;
      size_t best_k = 0;
      for (size_t k = 0; k < dirs.size(); ++k) {
        if (used[k]) continue;
        double nearest = -1;
        for (const Eigen::Vector3d& t : taken) nearest = std::max(nearest, dirs[k].dot(t));
        if (nearest > cos_min || nearest < cos_max) continue;
        double s = 0;
        for (size_t v = 0; v < weight.size(); ++v)
          if (seen[k][v]) s += weight[v];
        if (s > best) {
          best = s;
          best_k = k;
        }
      }
      if (best < 0) continue;
      PlannedView pv;
      pv.cam_from_world = poses[best_k];
      pv.score = best;
      for (size_t v = 0; v < weight.size(); ++v) {
        if (!seen[best_k][v]) continue;
        ++pv.visible_vertices;
        if (need[v] >= 1 && weight[v] > 0) pv.unseen_area += env.area[v];
        weight[v] = 0;
      }
      used[best_k] = 1;
      taken.push_back(dirs[best_k]);
      out.push_back(pv);
      break;
    }
  }
  return out;
}

}  // namespace rephoto::live
