#include "rephoto/suggest/next_views.h"

#include <embree3/rtcore.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/stats.h"
#include "rephoto/render/visibility.h"

namespace rephoto::suggest {
namespace {

// The scene's up direction: the direction most nearly orthogonal to every camera's x axis
// (photographers hold cameras without roll, so x axes are horizontal: COLMAP's model
// orientation aligner uses the same rule), signed like the mean of the cameras' -y axes. The
// mean -y axis alone tilts toward where the cameras look when they all stand on one side and
// look down. A small pull toward that mean breaks the tie when all x axes are parallel.
Eigen::Vector3d SceneUp(const scene::Scene& scene) {
  Eigen::Matrix3d x_axes = Eigen::Matrix3d::Zero();
  Eigen::Vector3d mean_up = Eigen::Vector3d::Zero();
  for (const scene::View& view : scene.views) {
    const Eigen::Vector3d x = view.cam_from_world.rotation.row(0).transpose();
    x_axes += x * x.transpose();
    mean_up -= view.cam_from_world.rotation.row(1).transpose();
  }
  mean_up = mean_up.norm() > 1e-9 ? mean_up.normalized() : Eigen::Vector3d::UnitZ();
  x_axes -= 1e-3 * static_cast<double>(scene.views.size()) * mean_up * mean_up.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(x_axes);
  Eigen::Vector3d up = solver.eigenvectors().col(0);  // smallest eigenvalue first
  return up.dot(mean_up) < 0 ? Eigen::Vector3d(-up) : up;
}

std::vector<double> VertexAreas(const mesh::Mesh& mesh) {
  if (mesh.is_point_cloud()) return std::vector<double>(mesh.vertex_count(), 1.0);
  std::vector<double> areas(mesh.vertex_count(), 0.0);
  for (const mesh::Triangle& f : mesh.faces) {
    const Eigen::Vector3d p0 = mesh.positions[f[0]].cast<double>();
    const Eigen::Vector3d p1 = mesh.positions[f[1]].cast<double>();
    const Eigen::Vector3d p2 = mesh.positions[f[2]].cast<double>();
    const double third = 0.5 * (p1 - p0).cross(p2 - p0).norm() / 3.0;
    for (uint32_t v : f) areas[v] += third;
  }
  return areas;
}


}  // namespace

void SuggestOptions::Check() const {
  REPHOTO_CHECK_USAGE(count >= 1, "--count must be at least 1");
  REPHOTO_CHECK_USAGE(candidate_count >= count, "--candidates {} is below --count {}",
                      candidate_count, count);
  REPHOTO_CHECK_USAGE(elevation_margin_degrees >= 0, "--elevation-margin must not be negative");
}

std::vector<uint8_t> VisibleVertices(const render::RenderModel& model,
                                     const std::vector<Eigen::Vector3f>& normals,
                                     const camera::Camera& camera,
                                     const camera::Pose& cam_from_world,
                                     const camera::UsableField* field) {
  const mesh::Mesh& mesh = model.mesh();
  const size_t n = mesh.vertex_count();
  std::vector<uint8_t> visible(n, 0);
  const render::ViewGeometry geometry = field != nullptr
                                            ? render::ViewGeometry(camera, cam_from_world, *field)
                                            : render::ViewGeometry(camera, cam_from_world);
  const render::VisibilityRule rule;  // render/visibility.h, the defaults
  ParallelFor(0, static_cast<int64_t>(n), 4096, [&](int64_t begin, int64_t end) {
    render::OcclusionBatch batch(model.scene(), geometry.center, rule.occlusion_epsilon);
    auto mark = [&](uint32_t vertex) { visible[vertex] = 1; };
    for (int64_t i = begin; i < end; ++i) {
      const Eigen::Vector3d v = mesh.positions[static_cast<size_t>(i)].cast<double>();
      const Eigen::Vector3d normal =
          static_cast<size_t>(i) < normals.size()
              ? Eigen::Vector3d(normals[static_cast<size_t>(i)].cast<double>())
              : Eigen::Vector3d::Zero();
      if (!render::Sighting(geometry, v, normal, rule)) continue;
      batch.Add(v, static_cast<uint32_t>(i), mark);
    }
    batch.Flush(mark);
  });
  return visible;
}

SuggestResult SuggestViews(const render::RenderModel& model, const scene::Scene& scene,
                           const camera::Camera& camera, const std::vector<float>& vertex_error,
                           const SuggestOptions& options) {
  options.Check();
  const mesh::Mesh& mesh = model.mesh();
  const size_t n = mesh.vertex_count();
  REPHOTO_CHECK(!scene.views.empty(), "the scene has no views to start from");
  REPHOTO_CHECK(vertex_error.empty() || vertex_error.size() == n,
                "the projected errors have {} values but the model has {} vertices",
                vertex_error.size(), n);
  const std::vector<Eigen::Vector3f> normals =
      mesh.is_point_cloud() ? mesh.normals : mesh::ComputeVertexNormals(mesh);
  const std::vector<double> areas = VertexAreas(mesh);

  SuggestResult result;
  for (double a : areas) result.total_area += a;

  // What the photos see.
  result.observed.assign(n, 0);
  for (const scene::View& view : scene.views) {
    const std::vector<uint8_t> seen =
        VisibleVertices(model, normals, scene.CameraOf(view), view.cam_from_world);
    for (size_t i = 0; i < n; ++i) result.observed[i] |= seen[i];
  }

  // Need per vertex.
  std::vector<double> need(n, 0.0);
  std::vector<double> finite;
  for (float e : vertex_error) {
    if (std::isfinite(e)) finite.push_back(e);
  }
  const double low = Quantile(finite, 0.025), high = Quantile(finite, 0.975);
  for (size_t i = 0; i < n; ++i) {
    if (!result.observed[i]) {
      need[i] = 1.0;
      result.unobserved_area += areas[i];
    } else if (!vertex_error.empty() && std::isfinite(vertex_error[i]) && !finite.empty()) {
      need[i] = high > low ? std::clamp((vertex_error[i] - low) / (high - low), 0.0, 1.0) : 0.0;
    }
  }

  // Candidate poses.
  const auto box = mesh::BoundingBox(mesh);
  result.target = (0.5 * (box[0] + box[1])).cast<double>();
  const Eigen::Vector3d up = SceneUp(scene);
  std::vector<double> distances, elevations;
  for (const scene::View& view : scene.views) {
    const Eigen::Vector3d offset = view.cam_from_world.Center() - result.target;
    distances.push_back(offset.norm());
    elevations.push_back(
        std::acos(std::clamp(offset.normalized().dot(up), -1.0, 1.0)));  // 0 = straight above
  }
  result.distance = Quantile(distances, 0.5);
  REPHOTO_CHECK(result.distance > 0, "the scene's cameras sit at the model's centre");
  const double margin = options.elevation_margin_degrees * std::numbers::pi / 180;
  const double min_elevation = *std::min_element(elevations.begin(), elevations.end()) - margin;
  const double lowest_photo = *std::max_element(elevations.begin(), elevations.end());
  double max_elevation = lowest_photo + margin;
  // Photos all taken from above the model's centre stand on something (the ground): no
  // suggestion from below that centre's horizon, where a photographer cannot stand.
  if (lowest_photo < std::numbers::pi / 2) {
    max_elevation = std::min(max_elevation, std::numbers::pi / 2);
  }
  // A Fibonacci sphere around `up`.
  const Eigen::Vector3d e1 =
      (std::abs(up.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY())
          .cross(up)
          .normalized();
  const Eigen::Vector3d e2 = up.cross(e1);
  std::vector<camera::Pose> candidates;
  const int m = options.candidate_count;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < m; ++k) {
    const double h = 1.0 - (k + 0.5) * 2.0 / m;  // cos(elevation)
    const double elevation = std::acos(h);
    if (elevation < min_elevation || elevation > max_elevation) continue;
    const double r = std::sqrt(std::max(0.0, 1 - h * h));
    const Eigen::Vector3d direction =
        h * up + r * std::cos(golden * k) * e1 + r * std::sin(golden * k) * e2;
    candidates.push_back(camera::LookAt(result.target + result.distance * direction, result.target, up));
  }
  REPHOTO_CHECK(static_cast<int>(candidates.size()) >= options.count,
                "only {} candidate poses within the photos' elevations; raise --candidates",
                candidates.size());

  std::vector<std::vector<uint32_t>> sees(candidates.size());
  const camera::UsableField field(camera);  // one camera for every candidate
  for (size_t c = 0; c < candidates.size(); ++c) {
    const std::vector<uint8_t> visible =
        VisibleVertices(model, normals, camera, candidates[c], &field);
    for (size_t i = 0; i < n; ++i) {
      if (visible[i]) sees[c].push_back(static_cast<uint32_t>(i));
    }
  }

  std::vector<double> weight(n);
  for (size_t i = 0; i < n; ++i) weight[i] = areas[i] * need[i];
  std::vector<uint8_t> unobserved_left(n);
  for (size_t i = 0; i < n; ++i) unobserved_left[i] = result.observed[i] ? 0 : 1;
  std::vector<uint8_t> taken(candidates.size(), 0);
  for (int k = 0; k < options.count; ++k) {
    size_t best = candidates.size();
    double best_score = -1;
    for (size_t c = 0; c < candidates.size(); ++c) {
      if (taken[c]) continue;
      double score = 0;
      for (uint32_t i : sees[c]) score += weight[i];
      if (score > best_score) {  // ties: the first candidate
        best_score = score;
        best = c;
      }
    }
    taken[best] = 1;
    Suggestion suggestion;
    suggestion.cam_from_world = candidates[best];
    suggestion.score = best_score;
    suggestion.visible_vertices = sees[best].size();
    double error_sum = 0, error_area = 0;
    for (uint32_t i : sees[best]) {
      if (!vertex_error.empty() && std::isfinite(vertex_error[i])) {
        error_sum += areas[i] * vertex_error[i];
        error_area += areas[i];
      }
    }
    suggestion.mean_error =
        error_area > 0 ? error_sum / error_area : std::numeric_limits<double>::quiet_NaN();
    for (uint32_t i : sees[best]) {
      weight[i] = 0;
      if (unobserved_left[i]) {
        suggestion.unobserved_area += areas[i];
        unobserved_left[i] = 0;
      }
    }
    result.unobserved_area_covered += suggestion.unobserved_area;
    result.suggestions.push_back(suggestion);
  }
  return result;
}

}  // namespace rephoto::suggest
