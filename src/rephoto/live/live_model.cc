#include "rephoto/live/live_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
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

Eigen::Vector3d UpDirection(const std::vector<camera::Pose>& poses) {
  // Mean of the cameras' -y axes (COLMAP cameras: y points down in the image): the sign, and
  // the answer when the x axes are (nearly) parallel.
  Eigen::Vector3d mean_up = Eigen::Vector3d::Zero();
  Eigen::Matrix3d xx = Eigen::Matrix3d::Zero();
  for (const camera::Pose& p : poses) {
    mean_up -= p.rotation.row(1).transpose();
    const Eigen::Vector3d x = p.rotation.row(0).transpose();
    xx += x * x.transpose();
  }
  if (!(mean_up.norm() > 1e-9)) return Eigen::Vector3d::UnitZ();
  mean_up.normalize();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(xx);
  const Eigen::Vector3d ev = solver.eigenvalues();
  // Level cameras: every x axis is horizontal, so up is the direction orthogonal to all of
  // them (the smallest eigenvector), well defined once two x axes differ by > ~10 degrees.
  if (!(ev[1] > 0.03 * ev[2])) return mean_up;
  Eigen::Vector3d up = solver.eigenvectors().col(0).normalized();
  if (up.dot(mean_up) < 0) up = -up;
  // Cameras that are far from level (the x axes do not share a plane) keep the mean.
  if (!(ev[0] < 0.1 * ev[1])) return mean_up;
  return up;
}

namespace {
constexpr double kFacing = 0.1;  // cosine: the camera sees the direction from outside
// Points less than this many inlier distances above the support plane are the floor's (its
// stereo noise), not the object's.
constexpr double kFloorBand = 3;
// An observed radius further than this fraction from the median of its observed grid
// neighbours' is a stereo outlier (a spike) and takes that median.
constexpr double kSpike = 0.15;

// The support plane (see live_model.h) of `points`; fills env->support and env->support_plane.
// Returns the inlier distance when a plane was found, else 0.
// `points` are the consistent depth points (the fit), `all` every depth point (the seen cells:
// a point within the inlier distance of the fitted plane is evidence of the floor there).
double FitSupportPlane(const std::vector<Eigen::Vector3d>& points,
                       const std::vector<Eigen::Vector3d>& all,
                       const std::vector<camera::Pose>& poses, const EnvelopeOptions& options,
                       Envelope* env) {
  if (points.size() < 100 || !(options.support_min_fraction <= 1)) return 0;
  std::vector<double> dc;
  for (const camera::Pose& p : poses) dc.push_back((p.Center() - env->center).norm());
  std::nth_element(dc.begin(), dc.begin() + dc.size() / 2, dc.end());
  const double tolerance = 0.005 * std::max(1e-9, dc[dc.size() / 2]);
  const size_t step = std::max<size_t>(1, points.size() / 20000);
  std::vector<size_t> sample;
  for (size_t i = 0; i < points.size(); i += step) sample.push_back(i);
  uint64_t state = 0x9e3779b97f4a7c15ull;  // fixed seed: the same plane on every run
  auto next = [&]() {
    state ^= state << 13;
    state ^= state >> 7;
    state ^= state << 17;
    return state;
  };
  const double cos_up = std::cos(45 * M_PI / 180);
  size_t best_count = 0;
  Eigen::Vector4d best = Eigen::Vector4d::Zero();
  for (int it = 0; it < 256; ++it) {
    const Eigen::Vector3d& a = points[sample[next() % sample.size()]];
    const Eigen::Vector3d& b = points[sample[next() % sample.size()]];
    const Eigen::Vector3d& c = points[sample[next() % sample.size()]];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (!(n.norm() > 1e-12)) continue;
    n.normalize();
    if (n.dot(env->up) < 0) n = -n;
    if (n.dot(env->up) < cos_up) continue;
    const double d = -n.dot(a);
    size_t count = 0;
    for (size_t i : sample) count += std::abs(n.dot(points[i]) + d) <= tolerance;
    if (count > best_count) {
      best_count = count;
      best << n, d;
    }
  }
  if (best_count < options.support_min_fraction * sample.size()) return 0;
  // Least-squares refit on the inliers (all points).
  auto inliers = [&](const Eigen::Vector4d& plane) {
    std::vector<size_t> in;
    for (size_t i = 0; i < points.size(); ++i)
      if (std::abs(plane.head<3>().dot(points[i]) + plane[3]) <= tolerance) in.push_back(i);
    return in;
  };
  std::vector<size_t> in = inliers(best);
  // The fixed point of the refit: the least-squares plane of the inliers, whose inliers are
  // taken again until they no longer change. The band then follows the densest floor points
  // rather than the plane-sweep points whose errors grow with their distance (a single refit of
  // RANSAC's band keeps part of their tilt). On the demo it converged in 12-27 rounds; the cap
  // bounds a cycle between two sets.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), n = best.head<3>();
  for (int round = 0; round < 100; ++round) {
    mean.setZero();
    for (size_t i : in) mean += points[i];
    mean /= static_cast<double>(in.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (size_t i : in) cov += (points[i] - mean) * (points[i] - mean).transpose();
    n = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0).normalized();
    std::vector<size_t> again = inliers(Eigen::Vector4d(n.x(), n.y(), n.z(), -n.dot(mean)));
    if (again == in || again.size() < 3) break;
    in = std::move(again);
  }
  if (n.dot(env->up) < 0) n = -n;
  if (n.dot(env->up) < cos_up) return 0;
  const Eigen::Vector4d plane(n.x(), n.y(), n.z(), -n.dot(mean));
  for (const camera::Pose& p : poses)
    if (plane.head<3>().dot(p.Center()) + plane[3] <= tolerance) return 0;  // a camera below it
  if (plane.head<3>().dot(env->center) + plane[3] <= tolerance) return 0;  // c not above it
  in = inliers(plane);
  if (in.size() < options.support_min_fraction * points.size()) return 0;
  std::vector<size_t> seen;  // cells: inliers among all points
  for (size_t i = 0; i < all.size(); ++i)
    if (std::abs(plane.head<3>().dot(all[i]) + plane[3]) <= tolerance) seen.push_back(i);
  // Cells of a grid over the inliers' extent that hold >= 2 inliers, closed by one cell.
  const Eigen::Vector3d eu = n.unitOrthogonal(), ev = n.cross(eu);
  double u0 = 1e300, u1 = -1e300, v0 = 1e300, v1 = -1e300;
  for (size_t i : seen) {
    const double u = eu.dot(all[i] - mean), v = ev.dot(all[i] - mean);
    u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
  }
  constexpr int kCells = 96;
  const double cell = std::max(u1 - u0, v1 - v0) / kCells;
  if (!(cell > 0)) return 0;
  const int nu = std::max(1, static_cast<int>(std::ceil((u1 - u0) / cell)));
  const int nv = std::max(1, static_cast<int>(std::ceil((v1 - v0) / cell)));
  std::vector<int> count(static_cast<size_t>(nu) * nv, 0);
  for (size_t i : seen) {
    const int a = std::clamp(static_cast<int>((eu.dot(all[i] - mean) - u0) / cell), 0, nu - 1);
    const int b = std::clamp(static_cast<int>((ev.dot(all[i] - mean) - v0) / cell), 0, nv - 1);
    ++count[static_cast<size_t>(b) * nu + a];
  }
  auto morph = [&](const std::vector<uint8_t>& src, bool dilate) {
    std::vector<uint8_t> dst(src.size());
    for (int b = 0; b < nv; ++b)
      for (int a = 0; a < nu; ++a) {
        bool any = false, all = true;
        for (int db = -1; db <= 1; ++db)
          for (int da = -1; da <= 1; ++da) {
            const int x = a + da, y = b + db;
            const bool on = x >= 0 && y >= 0 && x < nu && y < nv && src[static_cast<size_t>(y) * nu + x];
            any |= on;
            all &= on;
          }
        dst[static_cast<size_t>(b) * nu + a] = dilate ? any : all;
      }
    return dst;
  };
  std::vector<uint8_t> occupied(count.size());
  for (size_t k = 0; k < count.size(); ++k) occupied[k] = count[k] >= 2;
  const std::vector<uint8_t> closed = morph(morph(occupied, true), false);
  mesh::Mesh& m = env->support;
  auto vertex = [&](int a, int b) {
    const Eigen::Vector3d x = mean + (u0 + a * cell) * eu + (v0 + b * cell) * ev;
    m.positions.push_back(x.cast<float>());
    return static_cast<uint32_t>(m.positions.size() - 1);
  };
  std::vector<uint32_t> id(static_cast<size_t>(nu + 1) * (nv + 1), UINT32_MAX);
  auto corner = [&](int a, int b) {
    uint32_t& v = id[static_cast<size_t>(b) * (nu + 1) + a];
    if (v == UINT32_MAX) v = vertex(a, b);
    return v;
  };
  for (int b = 0; b < nv; ++b)
    for (int a = 0; a < nu; ++a) {
      if (!closed[static_cast<size_t>(b) * nu + a]) continue;
      const uint32_t p00 = corner(a, b), p10 = corner(a + 1, b), p11 = corner(a + 1, b + 1),
                     p01 = corner(a, b + 1);
      m.faces.push_back({p00, p10, p11});
      m.faces.push_back({p00, p11, p01});
    }
  env->support_plane = plane;
  return tolerance;
}

}  // namespace

bool ConfirmedByDepthMaps(const Eigen::Vector3d& world, const std::vector<size_t>& check,
                          const std::vector<EnvelopeInput>& depths, const EnvelopeOptions& options) {
  if (options.min_consistent <= 0) return true;
  int agree = 0;
  for (size_t j : check) {
    const EnvelopeInput& in = depths[j];
    const Eigen::Vector3d cam = in.cam_from_world.CamFromWorld(world);
    if (!(cam.z() > 0)) continue;
    const std::optional<Eigen::Vector2d> px = in.camera.ImgFromCam(cam);
    if (!px) continue;
    const int x = static_cast<int>(std::floor(px->x())), y = static_cast<int>(std::floor(px->y()));
    if (x < 0 || y < 0 || x >= in.depth->width() || y >= in.depth->height()) continue;
    const float z = in.depth->at(x, y);
    if (!(z > 0) || !std::isfinite(z)) continue;
    if (std::abs(z - cam.z()) <= options.consistency_tolerance * cam.z() &&
        ++agree >= options.min_consistent)
      return true;
  }
  return false;
}

std::vector<size_t> ConsistencyViews(size_t k, const std::vector<EnvelopeInput>& depths,
                                     const EnvelopeOptions& options) {
  std::vector<std::pair<double, size_t>> ranked;
  for (size_t j = 0; j < depths.size(); ++j) {
    if (j == k) continue;
    ranked.push_back(
        {-depths[j].cam_from_world.ViewDirection().dot(depths[k].cam_from_world.ViewDirection()), j});
  }
  std::sort(ranked.begin(), ranked.end());
  std::vector<size_t> out;
  for (size_t r = 0; r < ranked.size() && r < static_cast<size_t>(options.consistency_views); ++r)
    out.push_back(ranked[r].second);
  return out;
}

Envelope BuildEnvelope(const std::vector<camera::Pose>& poses,
                       const std::vector<EnvelopeInput>& depths, const EnvelopeOptions& options) {
  REPHOTO_CHECK(!poses.empty(), "envelope: no photos");
  REPHOTO_CHECK(options.bands >= 2 && options.segments >= 3 && options.stride >= 1 &&
                    options.min_points >= 1 && options.min_views >= 1,
                "envelope: invalid options");
  // Depth points.
  // The views each depth map's points are checked against.
  std::vector<std::vector<size_t>> check(depths.size());
  for (size_t k = 0; k < depths.size() && options.min_consistent > 0; ++k)
    check[k] = ConsistencyViews(k, depths, options);
  std::vector<Eigen::Vector3d> points, all_points;  // consistent ones; all
  std::vector<int> source;
  std::vector<Eigen::Vector3d> seen_from;  // camera centre of each point
  // CamFromImg at the grid's pixel centres, once per distinct camera and depth size (the photos
  // of one COLMAP camera share it; with distortion each call is a Newton solve): the same values
  // as calling it per pixel.
  struct GridRays {
    camera::Camera camera;
    int width, height;
    std::vector<std::optional<Eigen::Vector3d>> rays;  // row by row over the stride grid
  };
  std::vector<GridRays> tables;
  const int s0 = options.stride / 2;
  auto grid_rays = [&](const camera::Camera& cam, int w, int h) -> const GridRays& {
    for (const GridRays& t : tables)
      if (t.width == w && t.height == h && t.camera == cam) return t;
    GridRays t{cam, w, h, {}};
    for (int y = s0; y < h; y += options.stride)
      for (int x = s0; x < w; x += options.stride)
        t.rays.push_back(cam.CamFromImg({x + 0.5, y + 0.5}));
    tables.push_back(std::move(t));
    return tables.back();
  };
  for (size_t k = 0; k < depths.size(); ++k) {
    const EnvelopeInput& in = depths[k];
    const Image& d = *in.depth;
    const Eigen::Matrix3d world_from_cam = in.cam_from_world.rotation.transpose();
    const Eigen::Vector3d origin = in.cam_from_world.Center();
    const GridRays& table = grid_rays(in.camera, d.width(), d.height());
    size_t next = 0;  // the table's entry of (x, y): the same loops made it
    for (int y = s0; y < d.height(); y += options.stride) {
      for (int x = s0; x < d.width(); x += options.stride) {
        const std::optional<Eigen::Vector3d>& ray = table.rays[next++];
        const float z = d.at(x, y);
        if (!(z > 0) || !std::isfinite(z)) continue;
        if (!ray) continue;
        const Eigen::Vector3d cam = *ray / ray->z() * z;
        const Eigen::Vector3d world = origin + world_from_cam * cam;
        all_points.push_back(world);
        if (!ConfirmedByDepthMaps(world, check[k], depths, options)) continue;
        points.push_back(world);
        source.push_back(static_cast<int>(k));
        seen_from.push_back(origin);
      }
    }
  }
  Envelope env;
  env.point_count = points.size();
  env.up = UpDirection(poses);
  env.converging = NearestPointToAxes(poses, &env.center);
  if (!env.converging) {
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
  // The support plane first: its points (and any below it) are the floor, not the object.
  const double floor_tolerance = FitSupportPlane(points, all_points, poses, options, &env);
  const bool has_floor = floor_tolerance > 0;
  const Eigen::Vector3d floor_n = env.support_plane.head<3>();
  const double floor_d = env.support_plane[3];
  std::vector<std::vector<float>> dist(n);
  std::vector<std::set<int>> views(n);
  for (size_t i = 0; i < points.size(); ++i) {
    if (has_floor && floor_n.dot(points[i]) + floor_d <= kFloorBand * floor_tolerance) continue;
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
  // Spikes: one pass against the median of the observed grid neighbours, or, for a vertex with
  // fewer than 3 of them (at the edge of what was seen), of the observed vertices within two
  // grid steps (at least 3).
  {
    const std::vector<double> before = radius;
    std::vector<size_t> ring;
    for (size_t v = 0; v < n; ++v) {
      if (!env.observed[v]) continue;
      ring.assign(nb[v].begin(), nb[v].end());
      int direct = 0;
      for (size_t u : nb[v]) direct += env.observed[u];
      if (direct < 3) {
        for (size_t u : nb[v])
          for (size_t w : nb[u])
            if (w != v) ring.push_back(w);
      }
      std::sort(ring.begin(), ring.end());
      ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
      std::vector<double> r;
      for (size_t u : ring)
        if (env.observed[u]) r.push_back(before[u]);
      if (r.size() < 3) continue;
      std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
      const double m = r[r.size() / 2];
      if (std::abs(before[v] - m) > kSpike * m) radius[v] = m;
    }
  }
  // Distance from c to the floor along each direction (infinite when it does not point down
  // to it): the object stands on the floor, so the envelope does not reach below it.
  std::vector<double> to_floor(n, std::numeric_limits<double>::infinity());
  if (has_floor) {
    const double height = floor_n.dot(c) + floor_d;  // > 0 (checked by FitSupportPlane)
    for (size_t v = 0; v < n; ++v) {
      const double down = -floor_n.dot(dir_of(v));
      if (down > 1e-6) to_floor[v] = height / down;
    }
  }
  for (size_t v = 0; v < n; ++v) radius[v] = std::min(radius[v], to_floor[v]);
  // Harmonic fill of the unobserved radii.
  if (!observed_r.empty()) {
    std::vector<double> next = radius;
    for (int it = 0; it < 300; ++it) {
      for (size_t v = 0; v < n; ++v) {
        if (env.observed[v]) continue;
        double sum = 0;
        for (size_t u : nb[v]) sum += radius[u];
        next[v] = std::min(sum / nb[v].size(), to_floor[v]);
      }
      radius.swap(next);
    }
  }
  // Directions that end on the floor have nothing to see (the object's contact with it).
  for (size_t v = 0; v < n; ++v)
    if (!env.observed[v] && radius[v] >= to_floor[v] * (1 - 1e-9)) env.observed[v] = 1;
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
    const Eigen::Vector3d d = z * up + r * (std::cos(phi) * ex + std::sin(phi) * ey);
    // Not under the support plane (a camera cannot stand below the floor).
    if (!env.support.faces.empty() &&
        !(env.support_plane.head<3>().dot(c + distance * d) + env.support_plane[3] > 0))
      continue;
    dirs.push_back(d);
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
  double total_area = 0;
  for (size_t v = 0; v < need.size(); ++v) {
    weight[v] = env.area[v] * need[v];
    total_area += env.area[v];
  }
  // View-space coverage (see PlanOptions::unseen_exhausted_fraction). Target directions: the
  // candidates within the photos' elevation range, widened by half the candidates' spacing so
  // that photos all at one elevation still have some.
  const double half_spacing = 0.5 * std::sqrt(4 * M_PI / options.candidates);
  std::vector<size_t> targets;
  for (size_t j = 0; j < dirs.size(); ++j) {
    const double el = std::asin(std::clamp(dirs[j].dot(up), -1.0, 1.0));
    if (el >= el_lo - half_spacing && el <= el_hi + half_spacing) targets.push_back(j);
  }
  auto angle = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::acos(std::clamp(a.dot(b), -1.0, 1.0));
  };
  const double partner = options.stereo_partner_degrees * M_PI / 180;
  // Whether each photo of `ph` counts for view-space coverage: it has another photo of `ph`
  // within `partner` (every photo when partner is 0).
  auto partnered = [&](const std::vector<Eigen::Vector3d>& ph) {
    std::vector<uint8_t> counts(ph.size(), 1);
    if (partner > 0)
      for (size_t a = 0; a < ph.size(); ++a) {
        counts[a] = 0;
        for (size_t b = 0; b < ph.size() && !counts[a]; ++b)
          if (a != b && angle(ph[a], ph[b]) <= partner) counts[a] = 1;
      }
    return counts;
  };
  // Sum over the target directions of the angle to the nearest photo of `ph` that counts; pi
  // when none does. (Nearest = largest cosine; one acos per target.)
  auto gap_sum = [&](const std::vector<Eigen::Vector3d>& ph, const std::vector<uint8_t>& counts) {
    double sum = 0;
    for (size_t j : targets) {
      double best_cos = -2;
      for (size_t a = 0; a < ph.size(); ++a)
        if (counts[a]) best_cos = std::max(best_cos, dirs[j].dot(ph[a]));
      sum += best_cos < -1.5 ? M_PI : std::acos(std::clamp(best_cos, -1.0, 1.0));
    }
    return sum;
  };
  std::vector<PlannedView> out;
  std::vector<uint8_t> used(dirs.size(), 0);
  for (int pick = 0; pick < options.count; ++pick) {
    for (double max_gap = options.max_gap_degrees; max_gap <= 180; max_gap *= 2) {
      const double cos_min = std::cos(options.min_gap_degrees * M_PI / 180);
      const double cos_max = std::cos(max_gap * M_PI / 180);
      std::vector<size_t> band;
      std::vector<double> surface_score;
      double best_unseen = 0;
      for (size_t k = 0; k < dirs.size(); ++k) {
        if (used[k]) continue;
        double nearest = -1;
        for (const Eigen::Vector3d& t : taken) nearest = std::max(nearest, dirs[k].dot(t));
        if (nearest > cos_min || nearest < cos_max) continue;
        double s = 0, u = 0;
        for (size_t v = 0; v < weight.size(); ++v) {
          if (!seen[k][v]) continue;
          s += weight[v];
          if (need[v] >= 1 && weight[v] > 0) u += env.area[v];
        }
        band.push_back(k);
        surface_score.push_back(s);
        best_unseen = std::max(best_unseen, u);
      }
      if (options.partner_first && partner > 0 && !band.empty()) {
        const std::vector<uint8_t> has = partnered(taken);
        std::vector<size_t> near_band;
        std::vector<double> near_score;
        for (size_t i = 0; i < band.size(); ++i) {
          bool near = false;
          for (size_t a = 0; a < taken.size() && !near; ++a)
            near = !has[a] && angle(taken[a], dirs[band[i]]) <= partner;
          if (!near) continue;
          near_band.push_back(band[i]);
          near_score.push_back(surface_score[i]);
        }
        if (!near_band.empty()) {
          band.swap(near_band);
          surface_score.swap(near_score);
        }
      }
      if (band.empty()) continue;
      const bool exhausted = options.unseen_exhausted_fraction > 0 &&
                             best_unseen < options.unseen_exhausted_fraction * total_area;
      std::vector<uint8_t> counts_now;
      double gap_now = 0;
      if (exhausted) {
        counts_now = partnered(taken);
        gap_now = gap_sum(taken, counts_now);
      }
      double best = -1, best_s = -1;
      size_t best_k = 0;
      for (size_t i = 0; i < band.size(); ++i) {
        double key = surface_score[i];
        if (exhausted) {
          // The photos with the candidate added: it partners the photos within `partner` of
          // it, and counts itself when it has one (cost linear in the photos per candidate).
          std::vector<Eigen::Vector3d> with = taken;
          with.push_back(dirs[band[i]]);
          std::vector<uint8_t> counts = counts_now;
          counts.push_back(partner > 0 ? 0 : 1);
          for (size_t a = 0; partner > 0 && a < taken.size(); ++a)
            if (angle(taken[a], with.back()) <= partner) counts[a] = counts.back() = 1;
          key = gap_now - gap_sum(with, counts);
        }
        // Ties (e.g. no coverage gain anywhere) go to the larger surface score.
        if (key > best || (key == best && surface_score[i] > best_s)) {
          best = key;
          best_s = surface_score[i];
          best_k = band[i];
        }
      }
      PlannedView pv;
      pv.cam_from_world = poses[best_k];
      pv.score = best_s;
      pv.view_coverage = exhausted;
      if (exhausted) pv.coverage_gain = targets.empty() ? 0.0 : best / targets.size();
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
