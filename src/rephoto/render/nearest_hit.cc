#include "rephoto/render/nearest_hit.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace rephoto::render {

BorderSkirts MakeBorderSkirts(const mesh::Mesh& mesh) {
  BorderSkirts skirts;
  const size_t faces = mesh.faces.size();
  skirts.face_borders.assign(faces, 0);
  skirts.neighbors.assign(3 * faces, BorderSkirts::kNoNeighbor);
  // Per undirected edge: how many faces use it and the first one (3 * face + edge).
  struct Use {
    uint32_t count = 0;
    uint32_t first = 0;
  };
  std::unordered_map<uint64_t, Use> uses;
  uses.reserve(faces * 2);
  auto key = [](uint32_t a, uint32_t b) {
    return (static_cast<uint64_t>(std::min(a, b)) << 32) | std::max(a, b);
  };
  for (size_t i = 0; i < faces; ++i) {
    const mesh::Triangle& f = mesh.faces[i];
    for (int k = 0; k < 3; ++k) {
      Use& use = uses[key(f[k], f[(k + 1) % 3])];
      if (use.count == 1) {
        skirts.neighbors[use.first] = static_cast<uint32_t>(3 * i + k);
        skirts.neighbors[3 * i + k] = use.first;
      } else if (use.count == 2) {  // more than two faces: no neighbour for any of them
        skirts.neighbors[skirts.neighbors[use.first]] = BorderSkirts::kNoNeighbor;
        skirts.neighbors[use.first] = BorderSkirts::kNoNeighbor;
      }
      if (use.count == 0) use.first = static_cast<uint32_t>(3 * i + k);
      ++use.count;
    }
  }
  for (size_t i = 0; i < faces; ++i) {
    const mesh::Triangle& f = mesh.faces[i];
    for (int k = 0; k < 3; ++k) {
      if (uses[key(f[k], f[(k + 1) % 3])].count != 1) continue;
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

// A candidate face for one ray: its exact hit, or why not.
struct Candidate {
  enum State { kOk, kCulled, kEdgeOn, kOutsideBorder } state = kCulled;
  bool ok() const { return state == kOk; }
  ExactHit hit{};
  float b[3] = {};  // barycentric coordinate of each edge k (that of the opposite corner)
};

Candidate Evaluate(const NearestHitContext& context, unsigned face, const float o[3],
                   const float d[3]) {
  Candidate c;
  const mesh::Mesh& mesh = *context.mesh;
  const mesh::Triangle& f = mesh.faces[face];
  const Eigen::Vector3f& p0 = mesh.positions[f[0]];
  const Eigen::Vector3f& p1 = mesh.positions[f[1]];
  const Eigen::Vector3f& p2 = mesh.positions[f[2]];
  if (context.cull && (p1 - p0).cross(p2 - p0).dot(Eigen::Vector3f(d[0], d[1], d[2])) > 0) {
    c.state = Candidate::kCulled;
    return c;
  }
  c.hit = MoellerTrumbore(o, d, p0, p1, p2);
  if (!(c.hit.det != 0.0f && std::isfinite(c.hit.t) && std::isfinite(c.hit.u) &&
        std::isfinite(c.hit.v))) {
    c.state = Candidate::kEdgeOn;
    return c;
  }
  c.b[0] = c.hit.v;
  c.b[1] = 1.0f - c.hit.u - c.hit.v;
  c.b[2] = c.hit.u;
  const uint8_t borders =
      context.skirts->face_borders.empty() ? uint8_t{0} : context.skirts->face_borders[face];
  for (int k = 0; k < 3; ++k) {
    if (((borders >> k) & 1u) && !(c.b[k] >= 0.0f)) {
      c.state = Candidate::kOutsideBorder;
      return c;
    }
  }
  c.state = Candidate::kOk;
  return c;
}

}  // namespace

void NearestHitFilter(const RTCFilterFunctionNArguments* args) {
  const auto* context = reinterpret_cast<const NearestHitContext*>(args->context);
  const BorderSkirts& skirts = *context->skirts;
  const unsigned n = args->N;
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    unsigned face = RTCHitN_primID(args->hit, n, i);
    const bool strip = RTCHitN_geomID(args->hit, n, i) == kSkirtGeometry;
    if (strip) face = skirts.owner[face / 2];
    const float o[3] = {RTCRayN_org_x(args->ray, n, i), RTCRayN_org_y(args->ray, n, i),
                        RTCRayN_org_z(args->ray, n, i)};
    const float d[3] = {RTCRayN_dir_x(args->ray, n, i), RTCRayN_dir_y(args->ray, n, i),
                        RTCRayN_dir_z(args->ray, n, i)};
    Candidate c = Evaluate(*context, face, o, d);
    if (!c.ok()) {
      if (c.state != Candidate::kEdgeOn || strip) {
        args->valid[i] = 0;
        continue;
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
      const uint32_t across = skirts.neighbors[3 * face + k];
      if (c.b[k] < kEdgeBand && across != BorderSkirts::kNoNeighbor) {
        const unsigned other = across / 3;
        const Candidate g = Evaluate(*context, other, o, d);
        if (g.ok() && (g.b[across % 3] > c.b[k] || (g.b[across % 3] == c.b[k] && other < face))) {
          c = g;
          face = other;
        }
      }
    }
    if (!(c.hit.t >= RTCRayN_tnear(args->ray, n, i))) {
      args->valid[i] = 0;
      continue;
    }
    const unsigned lane = RTCRayN_id(args->ray, n, i);
    if (c.hit.t < context->best_t[lane] ||
        (c.hit.t == context->best_t[lane] && face < context->best_prim[lane])) {
      context->best_t[lane] = c.hit.t;
      context->best_u[lane] = c.hit.u;
      context->best_v[lane] = c.hit.v;
      context->best_prim[lane] = face;
      RTCRayN_tfar(args->ray, n, i) = c.hit.t + c.hit.t * kDepthSlack;
    } else {
      args->valid[i] = 0;
    }
  }
}

void SkirtIntersectGate(const RTCFilterFunctionNArguments* args) {
  if (args->context->filter == NearestHitFilter) return;
  for (unsigned i = 0; i < args->N; ++i) args->valid[i] = 0;
}

void SkirtOcclusionGate(const RTCFilterFunctionNArguments* args) {
  for (unsigned i = 0; i < args->N; ++i) args->valid[i] = 0;
}

}  // namespace rephoto::render
