#include "rephoto/render/render_model.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/progress.h"
#include "rephoto/render/point_radius.h"

namespace rephoto::render {

struct RenderModel::PointGeometry {
  const Eigen::Vector3f* positions = nullptr;
  const Eigen::Vector3f* normals = nullptr;  // nullptr: view-facing discs
  const float* radii = nullptr;
};

namespace {

// The box of a disc: a view-facing disc (no normal) can turn any way, so the cube of side 2r;
// an oriented disc of unit normal u reaches r sqrt(1 - u_i^2) along axis i (a ground disc is
// flat in z), widened by a margin (5 % of r and the coordinates' rounding) so that the ray's
// entry into the box lies clearly before its hit, also for a disc at exactly the nearest hit's
// distance (DecideDiscLane's ties must all be presented). Looser boxes only cost time: the hit
// itself is decided by IntersectDisc.
void PointBounds(const RTCBoundsFunctionArguments* args) {
  const auto* data = static_cast<const RenderModel::PointGeometry*>(args->geometryUserPtr);
  const Eigen::Vector3f& c = data->positions[args->primID];
  const double r = data->radii[args->primID];
  Eigen::Vector3d extent(r, r, r);
  if (data->normals != nullptr) {
    const Eigen::Vector3d n = data->normals[args->primID].cast<double>();
    const double length = n.norm();
    if (length > 0 && std::isfinite(length)) {
      const double margin = 0.05 * r + 1e-6 * c.cwiseAbs().maxCoeff();
      for (int i = 0; i < 3; ++i) {
        const double u = n[i] / length;
        extent[i] = std::min(r, r * std::sqrt(std::max(0.0, 1.0 - u * u)) + margin);
      }
    }
  }
  RTCBounds* b = args->bounds_o;
  b->lower_x = static_cast<float>(c.x() - extent.x());
  b->lower_y = static_cast<float>(c.y() - extent.y());
  b->lower_z = static_cast<float>(c.z() - extent.z());
  b->upper_x = static_cast<float>(c.x() + extent.x());
  b->upper_y = static_cast<float>(c.y() + extent.y());
  b->upper_z = static_cast<float>(c.z() + extent.z());
}

// Ray-disc test; returns the ray parameter of the hit or NaN. `normal_out` is the disc normal.
inline float IntersectDisc(const RenderModel::PointGeometry& data, unsigned prim,
                           const Eigen::Vector3f& o, const Eigen::Vector3f& d, float tnear,
                           float tfar, Eigen::Vector3f* normal_out) {
  const Eigen::Vector3f& c = data.positions[prim];
  const float r = data.radii[prim];
  Eigen::Vector3f n = Eigen::Vector3f::Zero();
  if (data.normals != nullptr) n = data.normals[prim];
  float t;
  if (n.squaredNorm() > 0) {
    const float denom = d.dot(n);
    if (std::abs(denom) < 1e-12f) return std::numeric_limits<float>::quiet_NaN();
    t = (c - o).dot(n) / denom;
  } else {  // view-facing: the disc through c perpendicular to the ray
    t = (c - o).dot(d) / d.squaredNorm();
    n = -d;
  }
  if (!(t > tnear && t < tfar)) return std::numeric_limits<float>::quiet_NaN();
  if ((o + t * d - c).squaredNorm() > r * r) return std::numeric_limits<float>::quiet_NaN();
  *normal_out = n;
  return t;
}

// Lane i of a ray packet against point disc `prim` (IntersectDisc); NaN = no hit.
float IntersectLane(const RenderModel::PointGeometry& data, unsigned prim, RTCRayN* ray, unsigned n,
                    unsigned i, Eigen::Vector3f* normal) {
  const Eigen::Vector3f o(RTCRayN_org_x(ray, n, i), RTCRayN_org_y(ray, n, i),
                          RTCRayN_org_z(ray, n, i));
  const Eigen::Vector3f d(RTCRayN_dir_x(ray, n, i), RTCRayN_dir_y(ray, n, i),
                          RTCRayN_dir_z(ray, n, i));
  return IntersectDisc(data, prim, o, d, RTCRayN_tnear(ray, n, i), RTCRayN_tfar(ray, n, i), normal);
}

// The disc of `prim` against kN lanes of a packet at once: IntersectDisc's operations in its
// order, written out per component (Eigen sums a 3-vector's dot product and squared norm as
// x + (y + z)), with tfar = infinity, so that a lane gets the same bits as IntersectDisc and
// the loop vectorizes under each path's target (no contraction in this library). NaN = no hit.
template <unsigned kN>
[[gnu::always_inline]] inline void IntersectDiscLanes(const RenderModel::PointGeometry& data,
                                                      unsigned prim, const float* ray,
                                                      float* t_out) {
  // Explicit kN-wide vectors (GCC left the lane loop scalar on the AVX2 path): each lane's
  // operations are the scalar ones, in the same order.
  typedef float VF __attribute__((vector_size(4 * kN)));
  typedef int VI __attribute__((vector_size(4 * kN)));
  VF ox, oy, oz, tnear, dx, dy, dz;
  __builtin_memcpy(&ox, ray, sizeof(VF));
  __builtin_memcpy(&oy, ray + kN, sizeof(VF));
  __builtin_memcpy(&oz, ray + 2 * kN, sizeof(VF));
  __builtin_memcpy(&tnear, ray + 3 * kN, sizeof(VF));
  __builtin_memcpy(&dx, ray + 4 * kN, sizeof(VF));
  __builtin_memcpy(&dy, ray + 5 * kN, sizeof(VF));
  __builtin_memcpy(&dz, ray + 6 * kN, sizeof(VF));
  const Eigen::Vector3f& c = data.positions[prim];
  const float cx = c.x(), cy = c.y(), cz = c.z();
  const float r = data.radii[prim];
  const float r2 = r * r;
  const VF nan = VF{} + std::numeric_limits<float>::quiet_NaN();
  const VF inf = VF{} + std::numeric_limits<float>::infinity();
  Eigen::Vector3f n = Eigen::Vector3f::Zero();
  if (data.normals != nullptr) n = data.normals[prim];
  const float nx = n.x(), ny = n.y(), nz = n.z();
  VF t;
  VI hit;
  if (nx * nx + (ny * ny + nz * nz) > 0) {
    const VF denom = dx * nx + (dy * ny + dz * nz);
    t = ((cx - ox) * nx + ((cy - oy) * ny + (cz - oz) * nz)) / denom;
    const VF abs_denom = (VF)((VI)denom & (VI{} + 0x7fffffff));
    const VI tiny = abs_denom < 1e-12f;
    hit = ~tiny;
  } else {  // view-facing
    t = ((cx - ox) * dx + ((cy - oy) * dy + (cz - oz) * dz)) / (dx * dx + (dy * dy + dz * dz));
    hit = VI{} - 1;
  }
  const VF px = (ox + t * dx) - cx, py = (oy + t * dy) - cy, pz = (oz + t * dz) - cz;
  const VI outside = px * px + (py * py + pz * pz) > r2;
  hit = hit & (t > tnear) & (t < inf) & ~outside;
  const VF out = (VF)(((VI)t & hit) | ((VI)nan & ~hit));
  __builtin_memcpy(t_out, &out, sizeof(VF));
}

// Lane i's hit t (NaN: none) against the lane's current best: the nearest disc; of discs at
// exactly the same distance (coplanar discs, e.g. on a flat ground: their planes give the same
// t for every ray) the one whose centre is nearest to the hit point, then the lowest index: the
// same hit whatever order Embree's traversal (which differs between its ISA kernels and packet
// widths) visits them in, and the disc that represents that point of the surface best.
[[gnu::always_inline]] inline void DecideDiscLane(const RTCIntersectFunctionNArguments* args,
                                                  const RenderModel::PointGeometry& data,
                                                  unsigned i, float t) {
  const unsigned n = args->N;
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, n);
  RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, n);
  const float tfar = RTCRayN_tfar(ray, n, i);
  bool better = t < tfar;
  if (!better && t == tfar && RTCHitN_geomID(hit, n, i) != RTC_INVALID_GEOMETRY_ID) {
    const Eigen::Vector3f o(RTCRayN_org_x(ray, n, i), RTCRayN_org_y(ray, n, i),
                            RTCRayN_org_z(ray, n, i));
    const Eigen::Vector3f d(RTCRayN_dir_x(ray, n, i), RTCRayN_dir_y(ray, n, i),
                            RTCRayN_dir_z(ray, n, i));
    const unsigned current = RTCHitN_primID(hit, n, i);
    const Eigen::Vector3f point = o + t * d;
    const float mine = (point - data.positions[args->primID]).squaredNorm();
    const float theirs = (point - data.positions[current]).squaredNorm();
    better = mine < theirs || (mine == theirs && args->primID < current);
  }
  if (!better) return;
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();
  if (data.normals != nullptr) normal = data.normals[args->primID];
  if (!(normal.squaredNorm() > 0)) {
    normal = -Eigen::Vector3f(RTCRayN_dir_x(ray, n, i), RTCRayN_dir_y(ray, n, i),
                              RTCRayN_dir_z(ray, n, i));
  }
  RTCRayN_tfar(ray, n, i) = t;
  RTCHitN_Ng_x(hit, n, i) = normal.x();
  RTCHitN_Ng_y(hit, n, i) = normal.y();
  RTCHitN_Ng_z(hit, n, i) = normal.z();
  RTCHitN_u(hit, n, i) = 0;
  RTCHitN_v(hit, n, i) = 0;
  RTCHitN_primID(hit, n, i) = args->primID;
  RTCHitN_geomID(hit, n, i) = args->geomID;
  RTCHitN_instID(hit, n, i, 0) = args->context->instID[0];
}

template <unsigned kN>
[[gnu::always_inline]] inline void PointIntersectPacket(
    const RTCIntersectFunctionNArguments* args) {
  const auto& data = *static_cast<const RenderModel::PointGeometry*>(args->geometryUserPtr);
  alignas(64) float t[kN];
  IntersectDiscLanes<kN>(data, args->primID,
                         reinterpret_cast<const float*>(RTCRayHitN_RayN(args->rayhit, kN)), t);
  // The lanes with a hit, as bits (branch-free), then only those in lane order.
  uint32_t hits = 0;
  for (unsigned i = 0; i < kN; ++i) {
    hits |= static_cast<uint32_t>((args->valid[i] != 0) & (t[i] == t[i])) << i;
  }
  while (hits != 0) {
    const unsigned i = static_cast<unsigned>(__builtin_ctz(hits));
    hits &= hits - 1;
    DecideDiscLane(args, data, i, t[i]);
  }
}

[[gnu::always_inline]] inline void PointIntersectBody(const RTCIntersectFunctionNArguments* args) {
  switch (args->N) {
    case 16:
      return PointIntersectPacket<16>(args);
    case 8:
      return PointIntersectPacket<8>(args);
    case 4:
      return PointIntersectPacket<4>(args);
    default:
      break;
  }
  const auto& data = *static_cast<const RenderModel::PointGeometry*>(args->geometryUserPtr);
  const unsigned n = args->N;
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, n);
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    Eigen::Vector3f normal;
    const Eigen::Vector3f o(RTCRayN_org_x(ray, n, i), RTCRayN_org_y(ray, n, i),
                            RTCRayN_org_z(ray, n, i));
    const Eigen::Vector3f d(RTCRayN_dir_x(ray, n, i), RTCRayN_dir_y(ray, n, i),
                            RTCRayN_dir_z(ray, n, i));
    const float t = IntersectDisc(data, args->primID, o, d, RTCRayN_tnear(ray, n, i),
                                  std::numeric_limits<float>::infinity(), &normal);
    if (!std::isnan(t)) DecideDiscLane(args, data, i, t);
  }
}

// The intersect callback of the disc geometry, compiled for each instruction-set path.
REPHOTO_ISA_DISPATCH(void, PointIntersect, (const RTCIntersectFunctionNArguments* args), (args))

void PointOccluded(const RTCOccludedFunctionNArguments* args) {
  const auto* data = static_cast<const RenderModel::PointGeometry*>(args->geometryUserPtr);
  const unsigned n = args->N;
  RTCRayN* ray = args->ray;
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    Eigen::Vector3f normal;
    const float t = IntersectLane(*data, args->primID, ray, n, i, &normal);
    if (!std::isnan(t)) RTCRayN_tfar(ray, n, i) = -std::numeric_limits<float>::infinity();
  }
}

void CheckDevice(RTCDevice device, std::string_view name, const char* step) {
  const RTCError error = rtcGetDeviceError(device);
  REPHOTO_CHECK(error == RTC_ERROR_NONE, "{}: Embree error {} while {}", name,
                static_cast<int>(error), step);
}

// A triangle geometry of `positions` and `triangles` (copied into Embree's buffers), set up by
// `configure` (filters), committed and attached to `scene` as `id`.
template <typename Configure = void (*)(RTCGeometry)>
void AttachTriangles(
    RTCDevice device, RTCScene scene, const std::vector<Eigen::Vector3f>& positions,
    const std::vector<mesh::Triangle>& triangles, unsigned id, std::string_view name,
    Configure configure = [](RTCGeometry) {}) {
  RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), positions.size()));
  auto* indices = static_cast<uint32_t*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                              3 * sizeof(uint32_t), triangles.size()));
  CheckDevice(device, name, "allocating buffers");
  std::memcpy(vertices, positions.data(), positions.size() * 3 * sizeof(float));
  std::memcpy(indices, triangles.data(), triangles.size() * 3 * sizeof(uint32_t));
  configure(geometry);
  rtcCommitGeometry(geometry);
  rtcAttachGeometryByID(scene, geometry, id);
  rtcReleaseGeometry(geometry);
}

}  // namespace

RenderModel::RenderModel(mesh::Mesh mesh, const ModelOptions& options, std::string_view name)
    : mesh_(std::move(mesh)), options_(options) {
  mesh_.Validate(name);
  REPHOTO_CHECK(options_.point_radius >= 0 && std::isfinite(options_.point_radius),
                "{}: point radius {} must be >= 0", name, options_.point_radius);
  REPHOTO_CHECK(options_.point_radius_neighbors >= 1, "{}: point radius neighbours must be >= 1",
                name);

  if (mesh_.is_point_cloud()) {
    representation_ = Representation::kPointCloud;
  } else if (options_.load_textures && mesh_.is_textured()) {
    representation_ = Representation::kTexturedMesh;
    textures_.resize(mesh_.materials.size());
    for (size_t m = 0; m < mesh_.materials.size(); ++m) {
      if (!mesh_.materials[m].diffuse_texture.empty()) {
        textures_[m] = Texture::Read(mesh_.materials[m].diffuse_texture);
      }
    }
  } else if (!mesh_.colors.empty()) {
    representation_ = Representation::kVertexColoredMesh;
  } else {
    representation_ = Representation::kPlainMesh;
  }

  device_ = rtcNewDevice(core::EmbreeDeviceConfig().c_str());
  REPHOTO_CHECK(device_ != nullptr, "{}: cannot create an Embree device", name);
  scene_ = rtcNewScene(device_);
  // Robust (watertight) triangle tests: render/nearest_hit.h.
  rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION | RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_MEDIUM);

  if (representation_ == Representation::kPointCloud) {
    const size_t n = mesh_.positions.size();
    if (options_.point_radius > 0) {
      point_radii_.assign(n, options_.point_radius);
    } else if (!mesh_.radii.empty()) {
      point_radii_ = mesh_.radii;
    } else {
      point_radii_ = KthNeighborDistances(mesh_.positions, options_.point_radius_neighbors);
      float fallback = 0;  // the median positive radius (also for exact duplicates)
      std::vector<float> positive;
      for (float r : point_radii_) {
        if (r > 0) positive.push_back(r);
      }
      if (!positive.empty()) {
        std::nth_element(positive.begin(), positive.begin() + positive.size() / 2, positive.end());
        fallback = positive[positive.size() / 2];
      }
      const float cap = options_.point_radius_max_factor > 0
                            ? options_.point_radius_max_factor * fallback
                            : std::numeric_limits<float>::infinity();
      for (float& r : point_radii_) {
        r = std::min(r > 0 ? r : fallback, cap) * options_.point_radius_scale;
      }
      REPHOTO_CHECK(fallback > 0,
                    "{}: cannot derive a point radius (all points coincide); give "
                    "one explicitly",
                    name);
    }
    point_geometry_ = std::make_unique<PointGeometry>();
    point_geometry_->positions = mesh_.positions.data();
    point_geometry_->normals = mesh_.normals.empty() ? nullptr : mesh_.normals.data();
    point_geometry_->radii = point_radii_.data();
    RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(n));
    rtcSetGeometryUserData(geometry, point_geometry_.get());
    rtcSetGeometryBoundsFunction(geometry, PointBounds, nullptr);
    rtcSetGeometryIntersectFunction(geometry, PointIntersect);
    rtcSetGeometryOccludedFunction(geometry, PointOccluded);
    rtcCommitGeometry(geometry);
    rtcAttachGeometryByID(scene_, geometry, 0);
    rtcReleaseGeometry(geometry);
  } else {
    AttachTriangles(device_, scene_, mesh_.positions, mesh_.faces, kMeshGeometry, name);
    // The border strips (nearest_hit.h), seen only by the renderer's nearest-hit queries.
    skirts_ = MakeBorderSkirts(mesh_);
    if (!skirts_.triangles.empty()) {
      AttachTriangles(device_, scene_, skirts_.positions, skirts_.triangles, kSkirtGeometry, name,
                      [](RTCGeometry g) {
                        rtcSetGeometryIntersectFilterFunction(g, SkirtIntersectGate);
                        rtcSetGeometryOccludedFilterFunction(g, SkirtOcclusionGate);
                      });
    }
  }
  const auto start = std::chrono::steady_clock::now();
  rtcCommitScene(scene_);
  build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  CheckDevice(device_, name, "building the BVH");
}

RenderModel::~RenderModel() {
  if (scene_ != nullptr) rtcReleaseScene(scene_);
  if (device_ != nullptr) rtcReleaseDevice(device_);
}

void RenderModel::SetVertexColors(std::vector<Eigen::Vector3f> colors) {
  REPHOTO_CHECK(!mesh_.faces.empty() && colors.size() == mesh_.positions.size(),
                "vertex colours: {} colours for a mesh of {} vertices and {} faces", colors.size(),
                mesh_.positions.size(), mesh_.faces.size());
  mesh_.colors = std::move(colors);
  if (representation_ != Representation::kTexturedMesh) {
    representation_ = Representation::kVertexColoredMesh;
  }
}

void RenderModel::SetVertexScalar(mesh::VertexScalar scalar) {
  REPHOTO_CHECK(scalar.values.size() == mesh_.positions.size(),
                "vertex scalar '{}': {} values for {} vertices", scalar.name, scalar.values.size(),
                mesh_.positions.size());
  mesh_.SetScalar(std::move(scalar));
}

std::shared_ptr<const CameraRays> RenderModel::RaysFor(const camera::Camera& camera) const {
  return SharedCameraRays(camera);
}

}  // namespace rephoto::render
