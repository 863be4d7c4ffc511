#include "rephoto/geometry/surface_distance.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/parallel.h"

namespace rephoto::geometry {
namespace {

struct QueryState {
  const std::vector<Eigen::Vector3f>* positions = nullptr;
  const std::vector<mesh::Triangle>* faces = nullptr;
  Eigen::Vector3d query;
  double best_squared = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best_point = Eigen::Vector3d::Zero();
  uint32_t best_primitive = 0;
};

bool TriangleQuery(RTCPointQueryFunctionArguments* args) {
  auto* state = static_cast<QueryState*>(args->userPtr);
  const mesh::Triangle& face = (*state->faces)[args->primID];
  const auto& p = *state->positions;
  Eigen::Vector3d closest;
  const double d2 =
      PointTriangleDistanceSquared(state->query, p[face[0]].cast<double>(),
                                   p[face[1]].cast<double>(), p[face[2]].cast<double>(), &closest);
  if (d2 < state->best_squared) {
    state->best_squared = d2;
    state->best_point = closest;
    state->best_primitive = args->primID;
    args->query->radius = static_cast<float>(std::sqrt(d2));
    return true;  // the search sphere shrank
  }
  return false;
}

bool PointQuery(RTCPointQueryFunctionArguments* args) {
  auto* state = static_cast<QueryState*>(args->userPtr);
  const Eigen::Vector3d p = (*state->positions)[args->primID].cast<double>();
  const double d2 = (p - state->query).squaredNorm();
  if (d2 < state->best_squared) {
    state->best_squared = d2;
    state->best_point = p;
    state->best_primitive = args->primID;
    args->query->radius = static_cast<float>(std::sqrt(d2));
    return true;
  }
  return false;
}

void PointBounds(const RTCBoundsFunctionArguments* args) {
  const auto* positions = static_cast<const std::vector<Eigen::Vector3f>*>(args->geometryUserPtr);
  const Eigen::Vector3f& p = (*positions)[args->primID];
  args->bounds_o->lower_x = args->bounds_o->upper_x = p.x();
  args->bounds_o->lower_y = args->bounds_o->upper_y = p.y();
  args->bounds_o->lower_z = args->bounds_o->upper_z = p.z();
}

// Rays never hit the points: this scene only serves point queries.
void NoIntersect(const RTCIntersectFunctionNArguments*) {}
void NoOccluded(const RTCOccludedFunctionNArguments*) {}

}  // namespace

double PointTriangleDistanceSquared(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                    Eigen::Vector3d* closest) {
  // Ericson 5.1.5: the Voronoi regions of the vertices, edges and face, in that order.
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  Eigen::Vector3d q;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  const double vc = d1 * d4 - d3 * d2;
  const double vb = d5 * d2 - d1 * d6;
  const double va = d3 * d6 - d5 * d4;
  if (d1 <= 0 && d2 <= 0) {
    q = a;
  } else if (d3 >= 0 && d4 <= d3) {
    q = b;
  } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    q = a + (d1 / (d1 - d3)) * ab;
  } else if (d6 >= 0 && d5 <= d6) {
    q = c;
  } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    q = a + (d2 / (d2 - d6)) * ac;
  } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    q = b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  } else {
    const double sum = va + vb + vc;
    if (!(sum > 0)) {
      // Degenerate (collinear) triangle not caught above: the nearest of its three edges.
      auto segment = [&](const Eigen::Vector3d& s, const Eigen::Vector3d& e) {
        const Eigen::Vector3d d = e - s;
        const double len2 = d.squaredNorm();
        const double t = len2 > 0 ? std::clamp((p - s).dot(d) / len2, 0.0, 1.0) : 0.0;
        return Eigen::Vector3d(s + t * d);
      };
      q = segment(a, b);
      for (const Eigen::Vector3d& r : {segment(b, c), segment(c, a)}) {
        if ((r - p).squaredNorm() < (q - p).squaredNorm()) q = r;
      }
    } else {
      const double v = vb / sum, w = vc / sum;
      q = a + v * ab + w * ac;
    }
  }
  if (closest != nullptr) *closest = q;
  return (q - p).squaredNorm();
}

SurfaceDistance::SurfaceDistance(const mesh::Mesh& mesh, std::string_view name)
    : positions_(mesh.positions), faces_(mesh.faces) {
  REPHOTO_CHECK(!positions_.empty(), "{}: the model has no vertices", name);
  mesh.Validate(name);
  device_ = rtcNewDevice(core::EmbreeDeviceConfig().c_str());
  REPHOTO_CHECK(device_ != nullptr, "{}: cannot create an Embree device", name);
  scene_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_MEDIUM);
  RTCGeometry geometry;
  if (faces_.empty()) {
    geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(positions_.size()));
    rtcSetGeometryUserData(geometry, &positions_);
    rtcSetGeometryBoundsFunction(geometry, PointBounds, nullptr);
    rtcSetGeometryIntersectFunction(geometry, NoIntersect);
    rtcSetGeometryOccludedFunction(geometry, NoOccluded);
  } else {
    geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                3 * sizeof(float), positions_.size()));
    REPHOTO_CHECK(vertices != nullptr, "{}: Embree cannot allocate {} vertices", name,
                  positions_.size());
    for (size_t i = 0; i < positions_.size(); ++i) {
      vertices[3 * i] = positions_[i].x();
      vertices[3 * i + 1] = positions_[i].y();
      vertices[3 * i + 2] = positions_[i].z();
    }
    auto* indices = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), faces_.size()));
    REPHOTO_CHECK(indices != nullptr, "{}: Embree cannot allocate {} faces", name, faces_.size());
    std::copy_n(faces_.front().data(), 3 * faces_.size(), indices);
  }
  rtcCommitGeometry(geometry);
  rtcAttachGeometryByID(scene_, geometry, 0);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(scene_);
  REPHOTO_CHECK(rtcGetDeviceError(device_) == RTC_ERROR_NONE,
                "{}: Embree error while building the distance BVH", name);
}

SurfaceDistance::~SurfaceDistance() {
  if (scene_ != nullptr) rtcReleaseScene(scene_);
  if (device_ != nullptr) rtcReleaseDevice(device_);
}

SurfaceDistance::Closest SurfaceDistance::Find(const Eigen::Vector3f& query,
                                               float upper_bound) const {
  QueryState state;
  state.positions = &positions_;
  state.faces = &faces_;
  state.query = query.cast<double>();
  RTCPointQuery point_query;
  point_query.x = query.x();
  point_query.y = query.y();
  point_query.z = query.z();
  point_query.time = 0;
  // Slightly enlarged so that the primitive realizing the bound is still visited.
  point_query.radius = std::isfinite(upper_bound) ? upper_bound * (1.0f + 1e-5f) + 1e-30f
                                                  : std::numeric_limits<float>::infinity();
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  rtcPointQuery(scene_, &point_query, &context, faces_.empty() ? PointQuery : TriangleQuery,
                &state);
  if (!std::isfinite(state.best_squared)) {
    // The bound was too tight (float rounding): search without it.
    REPHOTO_CHECK(std::isfinite(upper_bound), "distance query found no primitive");
    return Find(query);
  }
  return {static_cast<float>(std::sqrt(state.best_squared)), state.best_point.cast<float>(),
          state.best_primitive};
}

std::vector<float> SurfaceDistance::Distances(std::span<const Eigen::Vector3f> points) const {
  std::vector<float> out(points.size());
  ParallelFor(0, static_cast<int64_t>(points.size()), 4096, [&](int64_t begin, int64_t end) {
    float bound = std::numeric_limits<float>::infinity();
    Eigen::Vector3f previous_closest = Eigen::Vector3f::Zero();
    for (int64_t i = begin; i < end; ++i) {
      const Eigen::Vector3f& p = points[static_cast<size_t>(i)];
      if (i > begin) bound = (p - previous_closest).norm();
      const Closest closest = Find(p, bound);
      out[static_cast<size_t>(i)] = closest.distance;
      previous_closest = closest.point;
    }
  });
  return out;
}

}  // namespace rephoto::geometry
