// Which surface a camera ray hits, decided by rephoto's own arithmetic rather than by Embree's
// rounding, so that renders are the same bytes on every CPU and instruction-set path
// (docs/determinism.md). Internal to render/: RenderModel builds the geometry, render.cc traces.
//
// Embree finds candidate triangles; NearestHitFilter, an intersection-context filter, takes of
// them the one with the smallest (t, triangle index), t from MoellerTrumbore below. Two gaps
// remain in "Embree finds the candidates", both at the scale of float rounding, and both are
// closed here:
//   - Depth: Embree only presents candidates nearer than the ray's tfar, which is its own
//     rounded depth of the best hit so far. The filter sets tfar to t (1 + kDepthSlack) when it
//     accepts, so every candidate nearer by rephoto's arithmetic is presented.
//   - Borders: at an edge that only one triangle has (a silhouette, a hole's rim), whether a
//     ray passing within rounding of it hits is decided differently by Embree's SSE, AVX2 and
//     AVX-512 kernels (hit on one, miss on another). BorderSkirts gives Embree a thin strip
//     (2 triangles) across each border edge, reaching kSkirtWidth of the edge's length (plus a
//     margin for the coordinates' magnitude) to both sides; a ray near the border meets the
//     strip, and the filter decides with rephoto's barycentric coordinate of that edge (>= 0:
//     hit). The strips are a second geometry whose own filters hide them from every other query
//     (occlusion rays, rtcIntersect without this filter).
//   - Shared edges: Embree's robust (watertight) mode finds at least one of the two triangles of
//     a ray passing within rounding of their common edge, but which one differs between its
//     kernels, and their depths differ in the last bits. When a hit's barycentric coordinate of
//     a shared edge is below kEdgeBand, the filter also intersects the neighbour across that
//     edge and keeps the one more inside (larger coordinate of the common edge; on a tie the
//     lower index), whichever of the two Embree reported.
// Left: a ray within rounding of a vertex where three or more triangles meet.
//
// Cost: the filter loads a face once per call (Embree's packet kernels call it once per
// triangle, for the rays of the packet that hit it) and computes the exact hits of all of the
// packet's rays in one vectorized loop, compiled for each ISA path (ActiveNearestHitFilter);
// the decisions then go lane by lane. Not done: tracing without the filter and re-tracing only
// rays whose hit might differ. Embree's nearest hit E being well inside its triangle does not
// show that no other face G is within rounding of E's depth on that ray (overlapping or
// intersecting surfaces, a face folded onto its neighbour): the unfiltered trace has already
// culled every G behind E by Embree's depth, so it cannot tell, and the filter would keep G
// when rephoto's depth of G is the smaller. Skipping the filter is only sound with a per-face
// bound on the distance to every other face (precomputed), compared per ray with the depth's
// rounding error. Measured bounds (1920x1080, 1 spp, 1M triangles, 2 threads): without any
// filter 1.05x (AVX-512) and 1.03x (AVX2) of the Embree floor; with an empty filter callback
// 1.06x and 1.06x.
//
// Thread safety: the filter writes only the NearestHitContext of the query that calls it.
#pragma once

#include <embree3/rtcore.h>

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "rephoto/mesh/mesh.h"

namespace rephoto::render {

// Moeller-Trumbore for the ray o + t d and triangle (p0, p1, p2) in float, in this fixed order
// of IEEE operations (the library is built without contraction): the same bits everywhere.
// Hit point (1 - u - v) p0 + u p1 + v p2. det 0 (edge-on) gives non-finite values.
struct ExactHit {
  float t, u, v, det;
};
// The same with the edges e1 = p1 - p0 and e2 = p2 - p0 given (computed as above, component by
// component): the same bits.
[[gnu::always_inline]] inline ExactHit MoellerTrumboreEdges(const float o[3], const float d[3],
                                                            const Eigen::Vector3f& p0,
                                                            const float e1[3], const float e2[3]) {
  const float e1x = e1[0], e1y = e1[1], e1z = e1[2];
  const float e2x = e2[0], e2y = e2[1], e2z = e2[2];
  const float sx = o[0] - p0.x(), sy = o[1] - p0.y(), sz = o[2] - p0.z();
  const float px = d[1] * e2z - d[2] * e2y, py = d[2] * e2x - d[0] * e2z,
              pz = d[0] * e2y - d[1] * e2x;
  const float qx = sy * e1z - sz * e1y, qy = sz * e1x - sx * e1z, qz = sx * e1y - sy * e1x;
  const float det = (e1x * px + e1y * py) + e1z * pz;
  return {((e2x * qx + e2y * qy) + e2z * qz) / det, ((sx * px + sy * py) + sz * pz) / det,
          ((d[0] * qx + d[1] * qy) + d[2] * qz) / det, det};
}
[[gnu::always_inline]] inline ExactHit MoellerTrumbore(const float o[3], const float d[3],
                                                       const Eigen::Vector3f& p0,
                                                       const Eigen::Vector3f& p1,
                                                       const Eigen::Vector3f& p2) {
  const float e1[3] = {p1.x() - p0.x(), p1.y() - p0.y(), p1.z() - p0.z()};
  const float e2[3] = {p2.x() - p0.x(), p2.y() - p0.y(), p2.z() - p0.z()};
  return MoellerTrumboreEdges(o, d, p0, e1, e2);
}

// Relative depth slack (see above).
inline constexpr float kDepthSlack = 1e-4f;
// Barycentric band around shared edges where the neighbour is consulted.
inline constexpr float kEdgeBand = 1e-4f;
// Half-width of a border strip, relative to its edge's length.
inline constexpr float kSkirtWidth = 1e-3f;
// geomIDs in a RenderModel's scene.
inline constexpr unsigned kMeshGeometry = 0;
inline constexpr unsigned kSkirtGeometry = 1;

// Border edges of a mesh and their strips, and the neighbours across shared edges.
struct BorderSkirts {
  // Per face: bit k set when edge k (corners k, k + 1 mod 3) is a border (no other face has it).
  std::vector<uint8_t> face_borders;
  // Per face and edge k: the other face of that edge and its edge index there (3 * face + edge),
  // or kNoNeighbor (a border, or an edge of more than two faces).
  static constexpr uint32_t kNoNeighbor = 0xFFFFFFFFu;
  std::vector<uint32_t> neighbors;
  // Strip triangle s belongs to face owner[s / 2].
  std::vector<uint32_t> owner;
  std::vector<Eigen::Vector3f> positions;  // 4 per border edge
  std::vector<mesh::Triangle> triangles;   // 2 per border edge, into `positions`
};
BorderSkirts MakeBorderSkirts(const mesh::Mesh& mesh);

// What the filter reads and writes for one query: per ray of the packet (ray id = lane) the
// nearest hit so far. The caller sets best_t to +inf and best_prim to ~0 before each query.
struct NearestHitContext {
  RTCIntersectContext context;  // first member: Embree sees a plain RTCIntersectContext
  const mesh::Mesh* mesh = nullptr;
  const BorderSkirts* skirts = nullptr;
  bool cull = false;  // reject hits on triangles' back sides
  float* best_t = nullptr;
  float* best_u = nullptr;
  float* best_v = nullptr;
  unsigned* best_prim = nullptr;  // a face of the mesh
};

// The context filter (install as context.filter, with RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION).
// NearestHitFilter is compiled for the baseline; ActiveNearestHitFilter() is the same function
// compiled for core::ActiveIsa() (vectorized over the rays of a packet; the same decisions bit
// for bit, contraction being off).
void NearestHitFilter(const RTCFilterFunctionNArguments* args);
RTCFilterFunctionN ActiveNearestHitFilter();

// The strips' own intersection and occlusion filters: they let only NearestHitFilter's queries
// see the strips.
void SkirtIntersectGate(const RTCFilterFunctionNArguments* args);
void SkirtOcclusionGate(const RTCFilterFunctionNArguments* args);

}  // namespace rephoto::render
