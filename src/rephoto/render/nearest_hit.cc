#include "rephoto/render/nearest_hit.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"

namespace rephoto::render {

BorderSkirts MakeBorderSkirts(const mesh::Mesh& mesh) {
  BorderSkirts skirts;
  const size_t faces = mesh.faces.size();
  skirts.face_borders.assign(faces, 0);
  skirts.neighbors.assign(3 * faces, BorderSkirts::kNoNeighbor);
  // The faces of each undirected edge: the half-edges (3 * face + edge) bucketed by their
  // lower vertex (a counting sort, in half-edge order), then matched by the higher vertex
  // within each bucket (a vertex's few edges). An edge of exactly two faces links them; an edge
  // of one face is a border; an edge of three or more faces links none of them.
  const size_t half_edges = 3 * faces;
  const size_t vertices = mesh.positions.size();
  auto ends = [&](size_t he, uint32_t* lo, uint32_t* hi) {
    const mesh::Triangle& f = mesh.faces[he / 3];
    const int k = static_cast<int>(he % 3);
    *lo = std::min(f[k], f[(k + 1) % 3]);
    *hi = std::max(f[k], f[(k + 1) % 3]);
  };
  std::vector<uint32_t> start(vertices + 1, 0);
  for (size_t he = 0; he < half_edges; ++he) {
    uint32_t lo, hi;
    ends(he, &lo, &hi);
    REPHOTO_CHECK(hi < vertices, "mesh: face {} refers to vertex {} of {}", he / 3, hi, vertices);
    ++start[lo + 1];
  }
  for (size_t v = 0; v < vertices; ++v) start[v + 1] += start[v];
  struct Entry {
    uint32_t hi, he;
  };
  std::vector<Entry> bucket(half_edges);
  {
    std::vector<uint32_t> next(start.begin(), start.end() - 1);
    for (size_t he = 0; he < half_edges; ++he) {
      uint32_t lo, hi;
      ends(he, &lo, &hi);
      bucket[next[lo]++] = {hi, static_cast<uint32_t>(he)};
    }
  }
  std::vector<uint32_t> face_count(half_edges, 0);  // faces of each half-edge's edge
  for (size_t v = 0; v < vertices; ++v) {
    Entry* b = bucket.data() + start[v];
    const size_t n = start[v + 1] - start[v];
    // By (hi, he): insertion sort, the buckets being a handful of entries.
    for (size_t i = 1; i < n; ++i) {
      const Entry e = b[i];
      size_t j = i;
      for (; j > 0 && (b[j - 1].hi > e.hi || (b[j - 1].hi == e.hi && b[j - 1].he > e.he)); --j) {
        b[j] = b[j - 1];
      }
      b[j] = e;
    }
    for (size_t i = 0; i < n;) {
      size_t j = i + 1;
      while (j < n && b[j].hi == b[i].hi) ++j;
      for (size_t k = i; k < j; ++k) face_count[b[k].he] = static_cast<uint32_t>(j - i);
      if (j - i == 2) {
        skirts.neighbors[b[i].he] = b[i + 1].he;
        skirts.neighbors[b[i + 1].he] = b[i].he;
      }
      i = j;
    }
  }
  for (size_t i = 0; i < faces; ++i) {
    const mesh::Triangle& f = mesh.faces[i];
    for (int k = 0; k < 3; ++k) {
      if (face_count[3 * i + k] != 1) continue;
      const Eigen::Vector3f& a = mesh.positions[f[k]];
      const Eigen::Vector3f& b = mesh.positions[f[(k + 1) % 3]];
      const Eigen::Vector3f& c = mesh.positions[f[(k + 2) % 3]];
      const Eigen::Vector3f ab = b - a;
      const float length = ab.norm();
      // Outward in the face's plane: away from the third corner.
      Eigen::Vector3f out = (a - c) - ab * ((a - c).dot(ab) / (length * length));
      const float out_length = out.norm();
      if (!(length > 0) || !(out_length > 0) || !std::isfinite(out_length)) continue;
      out /= out_length;
      skirts.face_borders[i] |= static_cast<uint8_t>(1u << k);
      const float magnitude = std::max(a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff());
      const float width = kSkirtWidth * length + 1e-5f * magnitude;
      const uint32_t base = static_cast<uint32_t>(skirts.positions.size());
      skirts.positions.push_back(a - width * out);
      skirts.positions.push_back(b - width * out);
      skirts.positions.push_back(b + width * out);
      skirts.positions.push_back(a + width * out);
      skirts.triangles.push_back({base, base + 1, base + 2});
      skirts.triangles.push_back({base, base + 2, base + 3});
      skirts.owner.push_back(static_cast<uint32_t>(i));
    }
  }
  return skirts;
}

namespace {

// What a candidate test needs of one face, loaded once for all lanes of a filter call that meet
// the same face (Embree's packet kernels call the filter once per triangle with the mask of the
// rays that hit it). The values are those MoellerTrumbore and the cull test compute from the
// corners, by the same operations.
struct FaceData {
  unsigned face = ~0u;
  Eigen::Vector3f p0;
  float e1[3], e2[3];
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();  // (p1 - p0) x (p2 - p0), when culling
  uint8_t borders = 0;     // NearestHitContext::skirts->face_borders[face]
};

void LoadFace(const NearestHitContext& context, unsigned face, FaceData* data) {
  const mesh::Mesh& mesh = *context.mesh;
  const mesh::Triangle& f = mesh.faces[face];
  const Eigen::Vector3f& p0 = mesh.positions[f[0]];
  const Eigen::Vector3f& p1 = mesh.positions[f[1]];
  const Eigen::Vector3f& p2 = mesh.positions[f[2]];
  data->face = face;
  data->p0 = p0;
  data->e1[0] = p1.x() - p0.x();
  data->e1[1] = p1.y() - p0.y();
  data->e1[2] = p1.z() - p0.z();
  data->e2[0] = p2.x() - p0.x();
  data->e2[1] = p2.y() - p0.y();
  data->e2[2] = p2.z() - p0.z();
  if (context.cull) data->normal = (p1 - p0).cross(p2 - p0);
  // Faces have border bits only where a strip was built.
  data->borders =
      context.skirts->triangles.empty() ? uint8_t{0} : context.skirts->face_borders[face];
}

// A candidate face for one ray: its exact hit, or why not.
struct Candidate {
  enum State { kOk, kCulled, kEdgeOn, kOutsideBorder } state = kCulled;
  bool ok() const { return state == kOk; }
  ExactHit hit{};
  float b[3] = {};  // barycentric coordinate of each edge k (that of the opposite corner)
};

// The candidate `face` with exact hit `hit`; `facing` is normal . d (Eigen's order of operations),
// read only when culling.
[[gnu::always_inline]] inline Candidate Classify(const NearestHitContext& context,
                                                 const FaceData& face, float facing,
                                                 const ExactHit& hit) {
  Candidate c;
  if (context.cull && facing > 0) {
    c.state = Candidate::kCulled;
    return c;
  }
  c.hit = hit;
  if (!(c.hit.det != 0.0f && std::isfinite(c.hit.t) && std::isfinite(c.hit.u) &&
        std::isfinite(c.hit.v))) {
    c.state = Candidate::kEdgeOn;
    return c;
  }
  c.b[0] = c.hit.v;
  c.b[1] = 1.0f - c.hit.u - c.hit.v;
  c.b[2] = c.hit.u;
  for (int k = 0; k < 3; ++k) {
    if (((face.borders >> k) & 1u) && !(c.b[k] >= 0.0f)) {
      c.state = Candidate::kOutsideBorder;
      return c;
    }
  }
  c.state = Candidate::kOk;
  return c;
}

// normal . d as Eigen's Vector3f::dot computes it: x0 y0 + (x1 y1 + x2 y2).
[[gnu::always_inline]] inline float Facing(const Eigen::Vector3f& normal, const float d[3]) {
  return normal.x() * d[0] + (normal.y() * d[1] + normal.z() * d[2]);
}

[[gnu::always_inline]] inline Candidate Evaluate(const NearestHitContext& context,
                                                 const FaceData& face, const float o[3],
                                                 const float d[3]) {
  const float facing = context.cull ? Facing(face.normal, d) : 0.0f;
  if (context.cull && facing > 0) return Classify(context, face, facing, ExactHit{});
  return Classify(context, face, facing, MoellerTrumboreEdges(o, d, face.p0, face.e1, face.e2));
}

// Lane i of the filter call with candidate `c` on `face` (a face of the mesh; `strip`: Embree
// met the face's border strip): NearestHitFilter's decision, see nearest_hit.h.
[[gnu::always_inline]] inline void DecideLane(const RTCFilterFunctionNArguments* args,
                                              const NearestHitContext& context, unsigned i,
                                              unsigned face, bool strip, Candidate c,
                                              const float o[3], const float d[3]) {
  const BorderSkirts& skirts = *context.skirts;
  const unsigned n = args->N;
  if (!c.ok()) {
    if (c.state != Candidate::kEdgeOn || strip) {
      args->valid[i] = 0;
      return;
    }
    // Edge-on (the ray grazes the triangle's plane): Embree's values.
    c.hit = {RTCRayN_tfar(args->ray, n, i), RTCHitN_u(args->hit, n, i),
             RTCHitN_v(args->hit, n, i), 0.0f};
  } else if (!skirts.neighbors.empty()) {
    // Near a shared edge: of this face and its neighbour there, the one more inside.
    int k = 0;
    for (int e = 1; e < 3; ++e) {
      if (c.b[e] < c.b[k]) k = e;
    }
    if (c.b[k] < kEdgeBand) {
      const uint32_t across = skirts.neighbors[3 * face + k];
      if (across != BorderSkirts::kNoNeighbor) {
        const unsigned other = across / 3;
        FaceData other_data;
        LoadFace(context, other, &other_data);
        const Candidate g = Evaluate(context, other_data, o, d);
        if (g.ok() && (g.b[across % 3] > c.b[k] || (g.b[across % 3] == c.b[k] && other < face))) {
          c = g;
          face = other;
        }
      }
    }
  }
  if (!(c.hit.t >= RTCRayN_tnear(args->ray, n, i))) {
    args->valid[i] = 0;
    return;
  }
  const unsigned lane = RTCRayN_id(args->ray, n, i);
  if (c.hit.t < context.best_t[lane] ||
      (c.hit.t == context.best_t[lane] && face < context.best_prim[lane])) {
    context.best_t[lane] = c.hit.t;
    context.best_u[lane] = c.hit.u;
    context.best_v[lane] = c.hit.v;
    context.best_prim[lane] = face;
    RTCRayN_tfar(args->ray, n, i) = c.hit.t + c.hit.t * kDepthSlack;
  } else {
    args->valid[i] = 0;
  }
}

// Any call: lane by lane, the face loaded again only when it changes.
[[gnu::always_inline]] inline void FilterLanes(const RTCFilterFunctionNArguments* args) {
  const auto& context = *reinterpret_cast<const NearestHitContext*>(args->context);
  const unsigned n = args->N;
  FaceData data;  // the face of the previous lane, reused while lanes share it
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    unsigned face = RTCHitN_primID(args->hit, n, i);
    const bool strip = RTCHitN_geomID(args->hit, n, i) == kSkirtGeometry;
    if (strip) face = context.skirts->owner[face / 2];
    if (face != data.face) LoadFace(context, face, &data);
    const float o[3] = {RTCRayN_org_x(args->ray, n, i), RTCRayN_org_y(args->ray, n, i),
                        RTCRayN_org_z(args->ray, n, i)};
    const float d[3] = {RTCRayN_dir_x(args->ray, n, i), RTCRayN_dir_y(args->ray, n, i),
                        RTCRayN_dir_z(args->ray, n, i)};
    DecideLane(args, context, i, face, strip, Evaluate(context, data, o, d), o, d);
  }
}

// A call of kN lanes (a packet kernel's) whose valid lanes all met one triangle: the exact hits
// of all lanes in one vectorized loop (the same operations lane by lane, so the same bits as
// FilterLanes), then the decisions lane by lane. Other calls: FilterLanes.
template <unsigned kN>
[[gnu::always_inline]] inline void FilterPacket(const RTCFilterFunctionNArguments* args) {
  const auto& context = *reinterpret_cast<const NearestHitContext*>(args->context);
  unsigned first = kN;
  for (unsigned i = 0; i < kN; ++i) {
    if (args->valid[i] != 0) {
      first = i;
      break;
    }
  }
  if (first == kN) return;
  const unsigned geom = RTCHitN_geomID(args->hit, kN, first);
  const unsigned prim = RTCHitN_primID(args->hit, kN, first);
  for (unsigned i = first + 1; i < kN; ++i) {
    if (args->valid[i] != 0 &&
        (RTCHitN_geomID(args->hit, kN, i) != geom || RTCHitN_primID(args->hit, kN, i) != prim)) {
      return FilterLanes(args);
    }
  }
  const bool strip = geom == kSkirtGeometry;
  const unsigned face = strip ? context.skirts->owner[prim / 2] : prim;
  FaceData data;
  LoadFace(context, face, &data);
  const float* ray = reinterpret_cast<const float*>(args->ray);
  const float *ox = ray, *oy = ray + kN, *oz = ray + 2 * kN;
  const float *dx = ray + 4 * kN, *dy = ray + 5 * kN, *dz = ray + 6 * kN;
  alignas(64) float t[kN], u[kN], v[kN], det[kN], facing[kN];
  for (unsigned i = 0; i < kN; ++i) {
    const float o[3] = {ox[i], oy[i], oz[i]};
    const float d[3] = {dx[i], dy[i], dz[i]};
    const ExactHit hit = MoellerTrumboreEdges(o, d, data.p0, data.e1, data.e2);
    t[i] = hit.t;
    u[i] = hit.u;
    v[i] = hit.v;
    det[i] = hit.det;
    facing[i] = Facing(data.normal, d);
  }
  for (unsigned i = first; i < kN; ++i) {
    if (args->valid[i] == 0) continue;
    const float o[3] = {ox[i], oy[i], oz[i]};
    const float d[3] = {dx[i], dy[i], dz[i]};
    DecideLane(args, context, i, face, strip,
               Classify(context, data, facing[i], ExactHit{t[i], u[i], v[i], det[i]}), o, d);
  }
}

[[gnu::always_inline]] inline void NearestHitFilterBody(const RTCFilterFunctionNArguments* args) {
  switch (args->N) {
    case 16:
      return FilterPacket<16>(args);
    case 8:
      return FilterPacket<8>(args);
    case 4:
      return FilterPacket<4>(args);
    default:
      return FilterLanes(args);
  }
}

REPHOTO_TARGET_AVX512 void NearestHitFilterAvx512(const RTCFilterFunctionNArguments* args) {
  NearestHitFilterBody(args);
}
REPHOTO_TARGET_AVX2 void NearestHitFilterAvx2(const RTCFilterFunctionNArguments* args) {
  NearestHitFilterBody(args);
}

}  // namespace

void NearestHitFilter(const RTCFilterFunctionNArguments* args) { NearestHitFilterBody(args); }

RTCFilterFunctionN ActiveNearestHitFilter() {
  switch (core::ActiveIsa()) {
    case core::Isa::kAvx512:
      return NearestHitFilterAvx512;
    case core::Isa::kAvx2:
      return NearestHitFilterAvx2;
    case core::Isa::kBaseline:
      break;
  }
  return NearestHitFilter;
}

void SkirtIntersectGate(const RTCFilterFunctionNArguments* args) {
  const RTCFilterFunctionN filter = args->context->filter;
  if (filter == NearestHitFilter || filter == NearestHitFilterAvx2 ||
      filter == NearestHitFilterAvx512) {
    return;
  }
  for (unsigned i = 0; i < args->N; ++i) args->valid[i] = 0;
}

void SkirtOcclusionGate(const RTCFilterFunctionNArguments* args) {
  for (unsigned i = 0; i < args->N; ++i) args->valid[i] = 0;
}

}  // namespace rephoto::render
