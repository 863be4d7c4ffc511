#include "rephoto/render/render.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/parallel.h"

namespace rephoto::render {
namespace {

// The tile loop is compiled for each instruction-set path (AVX-512, AVX2, baseline; core/isa.h)
// and RenderTiles calls the one of core::ActiveIsa(). Contraction is off (CMakeLists.txt), so
// all three compute the same values bit for bit.

// Tiles are 4 pixels wide and L / 4 rows high for packets of L = 8 or 16 rays (RenderTiles).
constexpr int kTileWidth = 4;

inline uint32_t Hash(uint32_t x) {  // "lowbias32" integer hash (C. Wellons)
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

inline float UnitFloat(uint32_t bits) {
  return static_cast<float>(bits >> 8) * (1.0f / 16777216.0f);
}

// Barycentric coordinates (b1, b2) of point q in the plane of triangle (p0, p1, p2).
inline Eigen::Vector2f PlaneBarycentric(const Eigen::Vector3f& q, const Eigen::Vector3f& p0,
                                        const Eigen::Vector3f& e1, const Eigen::Vector3f& e2) {
  const Eigen::Vector3f w = q - p0;
  const float d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2);
  const float w1 = w.dot(e1), w2 = w.dot(e2);
  const float det = d11 * d22 - d12 * d12;
  if (!(std::abs(det) > 0)) return Eigen::Vector2f::Zero();
  return Eigen::Vector2f((d22 * w1 - d12 * w2) / det, (d11 * w2 - d12 * w1) / det);
}

// Everything the per-sample shading needs, fixed for one view.
struct Shader {
  const RenderModel& model;
  const mesh::Mesh& mesh;
  const CameraRays& rays;
  Eigen::Matrix3f world_from_cam;
  Eigen::Vector3f origin;
  float sample_spacing;  // pixels between neighbouring samples (texture footprint)

  Eigen::Vector3f WorldDirection(float xn, float yn) const {
    return world_from_cam.col(0) * xn + world_from_cam.col(1) * yn + world_from_cam.col(2);
  }

  // Colour of a hit on primitive `prim` at Embree barycentrics (u, v); (sx, sy) is the sample
  // position in pixels (for texture footprints).
  Eigen::Vector3f Shade(unsigned prim, float u, float v, float sx, float sy) const {
    switch (model.representation()) {
      case Representation::kPointCloud:
        return mesh.colors.empty() ? model.options().default_color : mesh.colors[prim];
      case Representation::kVertexColoredMesh: {
        const mesh::Triangle& f = mesh.faces[prim];
        return (1 - u - v) * mesh.colors[f[0]] + u * mesh.colors[f[1]] + v * mesh.colors[f[2]];
      }
      case Representation::kTexturedMesh:
        return ShadeTextured(prim, u, v, sx, sy);
      case Representation::kPlainMesh:
        break;
    }
    return model.options().default_color;
  }

  Eigen::Vector3f ShadeTextured(unsigned prim, float u, float v, float sx, float sy) const {
    const int material = mesh.FaceMaterial(prim);
    const Texture* texture = model.texture(material);
    const mesh::Triangle& f = mesh.faces[prim];
    if (texture == nullptr) {
      if (!mesh.colors.empty()) {
        return (1 - u - v) * mesh.colors[f[0]] + u * mesh.colors[f[1]] + v * mesh.colors[f[2]];
      }
      return material >= 0 ? mesh.materials[material].diffuse : model.options().default_color;
    }
    const Eigen::Vector2f uv0 = mesh.Texcoord(prim, 0), uv1 = mesh.Texcoord(prim, 1),
                          uv2 = mesh.Texcoord(prim, 2);
    const Eigen::Vector2f uv = (1 - u - v) * uv0 + u * uv1 + v * uv2;
    // Ray differentials: the rays one sample spacing to the right and below, intersected with
    // the triangle's plane, give the texture-space footprint of a sample.
    const Eigen::Vector3f& p0 = mesh.positions[f[0]];
    const Eigen::Vector3f e1 = mesh.positions[f[1]] - p0, e2 = mesh.positions[f[2]] - p0;
    const Eigen::Vector3f normal = e1.cross(e2);
    const float plane = (p0 - origin).dot(normal);
    float footprint = 0;
    const float offsets[2][2] = {{sample_spacing, 0}, {0, sample_spacing}};
    for (const auto& offset : offsets) {
      float xn, yn;
      // At the right/bottom border look left/up instead: only the footprint's length matters.
      float qx = sx + offset[0], qy = sy + offset[1];
      if (qx > rays.width()) qx = sx - offset[0];
      if (qy > rays.height()) qy = sy - offset[1];
      if (!rays.Ray(qx, qy, &xn, &yn)) continue;
      const Eigen::Vector3f d = WorldDirection(xn, yn);
      const float denom = d.dot(normal);
      if (std::abs(denom) < 1e-20f) continue;
      const Eigen::Vector3f q = origin + (plane / denom) * d;
      const Eigen::Vector2f b = PlaneBarycentric(q, p0, e1, e2);
      const Eigen::Vector2f uvq = (1 - b.x() - b.y()) * uv0 + b.x() * uv1 + b.y() * uv2;
      const Eigen::Vector2f texels((uvq.x() - uv.x()) * texture->width(),
                                   (uvq.y() - uv.y()) * texture->height());
      footprint = std::max(footprint, texels.norm());
    }
    const float lod = footprint > 1 ? std::log2(footprint) : 0.0f;
    return texture->Sample(uv.x(), uv.y(), lod);
  }
};

// SampleOffset's pattern with what does not depend on the pixel computed once per rendering.
class SampleGrid {
 public:
  explicit SampleGrid(const RenderOptions& options)
      : jitter_(options.pattern == SamplePattern::kStratifiedJittered),
        n_(options.samples_per_pixel) {
    kx_ = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n_))));
    ky_ = (n_ + kx_ - 1) / kx_;
    exact_reciprocals_ = PowerOfTwo(kx_) && PowerOfTwo(ky_);
    inv_kx_ = 1.0f / static_cast<float>(kx_);
    inv_ky_ = 1.0f / static_cast<float>(ky_);
    const uint32_t seed = Hash(options.seed);
    sample_hash_.resize(std::max(n_, 1));
    for (int s = 0; s < n_; ++s) sample_hash_[s] = Hash(static_cast<uint32_t>(s) ^ seed);
  }
  Eigen::Vector2f Offset(int x, int y, int sample) const {
    if (n_ <= 1) return Eigen::Vector2f(0.5f, 0.5f);
    const int cx = sample % kx_, cy = sample / kx_;
    float jx = 0.5f, jy = 0.5f;
    if (jitter_) Jitter(x, y, sample_hash_[sample], &jx, &jy);
    if (exact_reciprocals_) return Eigen::Vector2f((cx + jx) * inv_kx_, (cy + jy) * inv_ky_);
    return Eigen::Vector2f((cx + jx) / kx_, (cy + jy) / ky_);
  }
  // The jitter of a sample with hash `sample_hash` (sample_hash(s)) in pixel (x, y), in [0,1)^2.
  static void Jitter(int x, int y, uint32_t sample_hash, float* jx, float* jy) {
    const uint32_t h = Hash(static_cast<uint32_t>(x) * 0x9E3779B1u ^
                            Hash(static_cast<uint32_t>(y) * 0x85EBCA77u ^ sample_hash));
    *jx = UnitFloat(h);
    *jy = UnitFloat(Hash(h ^ 0x68E31DA4u));
  }
  bool jittered() const { return jitter_ && n_ > 1; }
  int strata_x() const { return kx_; }  // kx (1 for one sample)
  int strata_y() const { return ky_; }
  uint32_t sample_hash(int sample) const { return sample_hash_[sample]; }

 private:
  static bool PowerOfTwo(int k) { return k > 0 && (k & (k - 1)) == 0; }
  bool jitter_;
  int n_, kx_ = 1, ky_ = 1;
  // Multiplying by 1/k equals dividing by k exactly when k is a power of two (e.g. 4 samples).
  bool exact_reciprocals_ = false;
  float inv_kx_ = 1, inv_ky_ = 1;
  std::vector<uint32_t> sample_hash_;
};

// Lane `lane` of packet `p` of a tile of L pixels (4 wide, row-major): its pixel and sample.
// Block mode (samples_per_packet S > 1, a power of two dividing L): a packet covers a block of
// P = L / S pixels (2 x 2 for P = 4, 2 x 1 for P = 2, one pixel for P = 1) and S consecutive
// samples of each; packet p = block * groups + group holds samples S * group .. S * group + S - 1
// (lane = P * sample-in-group + pixel-in-block). Else (S = 1) packet p is sample p of all L
// pixels. Either way each pixel's samples come in increasing order.
inline int PacketPixel(int p, int lane, int samples_per_packet, int groups, int lanes) {
  if (samples_per_packet == 1) return lane;
  const int pixels = lanes / samples_per_packet;  // P
  const int block_width = pixels >= 2 ? 2 : 1, block_height = pixels >= 4 ? 2 : 1;
  const int blocks_per_row = 4 / block_width;
  const int block = p / groups, in_block = lane % pixels;
  const int x = (block % blocks_per_row) * block_width + in_block % block_width;
  const int y = (block / blocks_per_row) * block_height + in_block / block_width;
  return y * 4 + x;
}
inline int PacketSample(int p, int lane, int samples_per_packet, int groups, int lanes) {
  if (samples_per_packet == 1) return p;
  return (p % groups) * samples_per_packet + lane / (lanes / samples_per_packet);
}

// What lane i of one packet traces in every tile (PacketPixel, PacketSample), with the parts
// of SampleGrid::Offset that depend on the sample only: the lane loops of RenderTiles then
// read consecutive values and no tables.
template <int L>
struct PacketLanes {
  int pixel[L];                // in the tile, row-major (4 wide)
  int dx[L], dy[L];            // pixel % 4, pixel / 4
  int has_sample[L];           // 0 for samples >= spp (a partial last group)
  float cell_x[L], cell_y[L];  // stratum of the sample: (s % kx, s / kx)
  uint32_t sample_hash[L];     // SampleGrid::sample_hash(s)
};

// The packets of a tile of 4 x L / 4 pixels with `spp` samples each: with at least L / 4
// samples per pixel a packet holds S samples of a block of L / S pixels, S the largest power of
// two up to L that divides spp (at least L / 4) (a narrow packet meets fewer BVH nodes: the 16 samples of the demo's
// photos trace as 8 samples of one pixel per packet on the AVX2 path), else one sample of all
// L pixels.
template <int L>
std::vector<PacketLanes<L>> PlanPackets(int spp, const SampleGrid& grid) {
  int samples_per_packet = 1;
  if (spp >= L / 4) {
    samples_per_packet = L / 4;
    while (samples_per_packet * 2 <= L && spp % (samples_per_packet * 2) == 0) {
      samples_per_packet *= 2;
    }
  }
  const int groups = (spp + samples_per_packet - 1) / samples_per_packet;  // per pixel block
  const int packets = (samples_per_packet == 1 ? 1 : samples_per_packet) * groups;
  std::vector<PacketLanes<L>> plan(static_cast<size_t>(packets));
  for (int p = 0; p < packets; ++p) {
    PacketLanes<L>& lanes = plan[static_cast<size_t>(p)];
    for (int i = 0; i < L; ++i) {
      const int pixel = PacketPixel(p, i, samples_per_packet, groups, L);
      const int s = PacketSample(p, i, samples_per_packet, groups, L);
      lanes.pixel[i] = pixel;
      lanes.dx[i] = pixel & 3;
      lanes.dy[i] = pixel >> 2;
      lanes.has_sample[i] = s < spp ? 1 : 0;
      const int sample = std::min(s, spp - 1);
      lanes.cell_x[i] = static_cast<float>(sample % grid.strata_x());
      lanes.cell_y[i] = static_cast<float>(sample / grid.strata_x());
      lanes.sample_hash[i] = grid.sample_hash(sample);
    }
  }
  return plan;
}

// (r, g, b, weight) of a sample, or a pixel's sums of them. A GCC/clang vector (SSE on x86-64,
// NEON on ARM): each lane is the scalar operation on that channel (no FMA contraction, see
// CMakeLists.txt), so results are those of per-channel scalar code.
typedef float Float4 __attribute__((vector_size(16)));

inline Float4 Load3(const Eigen::Vector3f& v) { return Float4{v.x(), v.y(), v.z(), 0.0f}; }

// Shading of vertex-coloured meshes, the common case, inlined into the tile loop:
// (1 - u - v) * c0 + u * c1 + v * c2 per channel, as Shader::Shade computes it.
struct VertexColorShade {
  const mesh::Triangle* faces;
  const Eigen::Vector3f* colors;
  [[gnu::always_inline]] Float4 operator()(unsigned prim, float u, float v, float /*sx*/,
                                           float /*sy*/) const {
    const mesh::Triangle& f = faces[prim];
    const float w = 1 - u - v;
    Float4 c = (w * Load3(colors[f[0]]) + u * Load3(colors[f[1]])) + v * Load3(colors[f[2]]);
    c[3] = 1.0f;
    return c;
  }
};

// Every other representation: Shader::Shade.
struct GenericShade {
  const Shader* shader;
  [[gnu::always_inline]] Float4 operator()(unsigned prim, float u, float v, float sx,
                                           float sy) const {
    const Eigen::Vector3f c = shader->Shade(prim, u, v, sx, sy);
    return Float4{c.x(), c.y(), c.z(), 1.0f};
  }
};

inline void Intersect(const int* valid, RTCScene scene, RTCIntersectContext* context,
                      RTCRayHit16* packet) {
  rtcIntersect16(valid, scene, context, packet);
}
inline void Intersect(const int* valid, RTCScene scene, RTCIntersectContext* context,
                      RTCRayHit8* packet) {
  rtcIntersect8(valid, scene, context, packet);
}

// What RenderTiles needs of a view.
struct View {
  const Shader& shader;
  const CameraRays& rays;
  const SampleGrid& grid;
  RTCScene scene;
  const mesh::Mesh& mesh;
  bool cull;
  bool triangles;  // a triangle mesh (NearestHitFilter), not a point cloud
  const BorderSkirts* skirts;
  int spp;
  Rephoto* out;
};

// One L-ray packet (RayHit = RTCRayHit8 or RTCRayHit16) and what a tile's samples add up to.
// The fields Embree only reads and that are the same for every ray of a view (origin, tnear,
// time, mask, id, flags) are written once; per packet only the directions, tfar and geomID.
template <int L, typename RayHit>
struct TileState {
  alignas(64) RayHit packet;
  alignas(64) int valid[L];
  alignas(64) float sample_x[L];
  alignas(64) float sample_y[L];
  alignas(64) float xn[L];
  alignas(64) float yn[L];
  alignas(64) int live[L];
  alignas(64) int has_ray[L];
  alignas(64) Float4 sum[L];  // per pixel of the tile: colour sums and the number of hits
  alignas(64) float nearest[L];
  // NearestHitFilter's choice per lane (triangle meshes).
  alignas(64) float best_t[L];
  alignas(64) float best_u[L];
  alignas(64) float best_v[L];
  alignas(64) unsigned best_prim[L];

  explicit TileState(const Eigen::Vector3f& origin) {
    for (int i = 0; i < L; ++i) {
      packet.ray.org_x[i] = origin.x();
      packet.ray.org_y[i] = origin.y();
      packet.ray.org_z[i] = origin.z();
      packet.ray.tnear[i] = 0.0f;
      packet.ray.time[i] = 0.0f;
      packet.ray.mask[i] = 0xFFFFFFFFu;
      packet.ray.id[i] = static_cast<unsigned>(i);
      packet.ray.flags[i] = 0;
    }
  }
};

// Lane i's sample position (sample_x, sample_y) in the tile at (x0, y0) (SampleGrid::Offset)
// and whether it is a sample inside the image (live).
template <bool kJitter, int L, typename RayHit>
[[gnu::always_inline]] inline void PlaceSample(const View& view, const PacketLanes<L>& lanes,
                                               int x0, int y0, int i, TileState<L, RayHit>* state) {
  const int px = x0 + lanes.dx[i], py = y0 + lanes.dy[i];
  // & of 0/1 ints, not &&: no branches in the lane loop.
  state->live[i] = static_cast<int>(px < view.rays.width()) &
                   static_cast<int>(py < view.rays.height()) & lanes.has_sample[i];
  float jx = 0.5f, jy = 0.5f;
  if constexpr (kJitter) SampleGrid::Jitter(px, py, lanes.sample_hash[i], &jx, &jy);
  // Dividing by a power of two is SampleGrid's multiplying by its reciprocal, exactly.
  state->sample_x[i] =
      static_cast<float>(px) + (lanes.cell_x[i] + jx) / static_cast<float>(view.grid.strata_x());
  state->sample_y[i] =
      static_cast<float>(py) + (lanes.cell_y[i] + jy) / static_cast<float>(view.grid.strata_y());
}

// Lane i's ray: the world direction of camera ray (xn, yn) (Shader::WorldDirection, channel by
// channel), unbounded; traced when the sample is live and the camera has a ray there.
template <int L, typename RayHit>
[[gnu::always_inline]] inline int AimRay(const Eigen::Matrix3f& m, float xn, float yn, int has_ray,
                                         int i, TileState<L, RayHit>* state) {
  auto& ray = state->packet.ray;
  ray.dir_x[i] = (m(0, 0) * xn + m(0, 1) * yn) + m(0, 2);
  ray.dir_y[i] = (m(1, 0) * xn + m(1, 1) * yn) + m(1, 2);
  ray.dir_z[i] = (m(2, 0) * xn + m(2, 1) * yn) + m(2, 2);
  const int traced = state->live[i] & has_ray;
  // An untraced lane also gets tfar < tnear: where Embree has no native kernel for the packet
  // width (16 rays on AVX2, 8 or 16 on SSE) it traces the packet as a ray stream, which ignores
  // the valid mask and skips only rays with tnear > tfar.
  ray.tfar[i] =
      traced ? std::numeric_limits<float>::infinity() : -std::numeric_limits<float>::infinity();
  state->packet.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
  state->valid[i] = -traced;
  return traced;
}

// Fills packet `lanes` of the tile at (x0, y0); returns whether any lane has a ray. Branch-free
// lane loops (vectorized by the compiler); pinhole rays in the same loop, other cameras' rays
// from their table in between.
template <bool kJitter, bool kPinhole, int L, typename RayHit>
[[gnu::always_inline]] inline bool FillPacket(const View& view, const PacketLanes<L>& lanes, int x0,
                                              int y0, TileState<L, RayHit>* state) {
  const Eigen::Matrix3f m = view.shader.world_from_cam;
  int any = 0;
  if constexpr (kPinhole) {
    for (int i = 0; i < L; ++i) {
      PlaceSample<kJitter>(view, lanes, x0, y0, i, state);
      float xn, yn;
      view.rays.PinholeRay(state->sample_x[i], state->sample_y[i], &xn, &yn);
      any |= AimRay(m, xn, yn, 1, i, state);
    }
  } else {
    for (int i = 0; i < L; ++i) PlaceSample<kJitter>(view, lanes, x0, y0, i, state);
    view.rays.Rays(L, state->sample_x, state->sample_y, state->xn, state->yn, state->has_ray);
    for (int i = 0; i < L; ++i)
      any |= AimRay(m, state->xn[i], state->yn[i], state->has_ray[i], i, state);
  }
  return any != 0;
}

// Writes the tile's pixels: mean colour of the hits, coverage and nearest depth (render.h).
// The divisions in a lane loop (vectorized), then one 16-byte store per pixel.
template <int L, typename RayHit>
[[gnu::always_inline]] inline void StoreTile(const View& view, const TileState<L, RayHit>& state,
                                             int x0, int y0) {
  const int width = view.rays.width(), height = view.rays.height();
  const float spp = static_cast<float>(view.spp);
  alignas(64) float scale[L], coverage[L];
  for (int k = 0; k < L; ++k) {
    const float hits = state.sum[k][3];
    scale[k] = 1.0f / hits;  // inf where nothing was hit (then unused)
    coverage[k] = hits / spp;
  }
  float* color = view.out->color.data();
  float* depth = view.out->depth.data();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const bool whole = x0 + kTileWidth <= width && y0 + L / kTileWidth <= height;
  for (int k = 0; k < L; ++k) {
    const int px = x0 + (k & 3), py = y0 + (k >> 2);
    if (!whole && (px >= width || py >= height)) continue;
    const size_t index = static_cast<size_t>(py) * width + px;
    Float4 rgba = {0.0f, 0.0f, 0.0f, 0.0f};
    float z = nan;
    if (state.sum[k][3] > 0) {
      rgba = state.sum[k] * scale[k];
      rgba[3] = coverage[k];
      z = state.nearest[k];
    }
    std::memcpy(color + 4 * index, &rgba, sizeof(rgba));
    depth[index] = z;
  }
}

// The nearest hits NearestHitFilter chose (nearest_hit.h), into the packet: the face and its
// (t, u, v) by rephoto's arithmetic.
template <int L, typename RayHit>
[[gnu::always_inline]] inline void TakeNearestHits(TileState<L, RayHit>* state) {
  for (int i = 0; i < L; ++i) {
    const bool hit = state->packet.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
    state->packet.ray.tfar[i] = hit ? state->best_t[i] : state->packet.ray.tfar[i];
    state->packet.hit.u[i] = hit ? state->best_u[i] : state->packet.hit.u[i];
    state->packet.hit.v[i] = hit ? state->best_v[i] : state->packet.hit.v[i];
    state->packet.hit.primID[i] = hit ? state->best_prim[i] : state->packet.hit.primID[i];
  }
}

// Renders tile rows [row_begin, row_end) of 4 x (L / 4)-pixel tiles with the packets of
// `plan`. Each pixel's samples are summed in increasing sample order, so both widths give the
// same sums from the same hits.
template <bool kJitter, bool kPinhole, int L, typename RayHit, typename Shade>
[[gnu::always_inline]] inline void RenderTilesBody(const View& view,
                                                   const std::vector<PacketLanes<L>>& plan,
                                                   const Shade& shade, int64_t row_begin,
                                                   int64_t row_end) {
  constexpr int kTileHeight = L / kTileWidth;
  const int width = view.rays.width();
  const float inf = std::numeric_limits<float>::infinity();
  TileState<L, RayHit> state(view.shader.origin);
  NearestHitContext context;
  rtcInitIntersectContext(&context.context);
  context.context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  if (view.triangles) context.context.filter = ActiveNearestHitFilter();
  context.mesh = &view.mesh;
  context.skirts = view.skirts;
  context.cull = view.cull;
  context.best_t = state.best_t;
  context.best_u = state.best_u;
  context.best_v = state.best_v;
  context.best_prim = state.best_prim;
  for (int64_t tile_row = row_begin; tile_row < row_end; ++tile_row) {
    const int y0 = static_cast<int>(tile_row) * kTileHeight;
    for (int x0 = 0; x0 < width; x0 += kTileWidth) {
      for (int k = 0; k < L; ++k) {
        state.sum[k] = Float4{0.0f, 0.0f, 0.0f, 0.0f};
        state.nearest[k] = inf;
      }
      for (const PacketLanes<L>& lanes : plan) {
        if (!FillPacket<kJitter, kPinhole>(view, lanes, x0, y0, &state)) continue;
        if (view.triangles) {
          for (int i = 0; i < L; ++i) {
            state.best_t[i] = std::numeric_limits<float>::infinity();
            state.best_prim[i] = std::numeric_limits<unsigned>::max();
          }
        }
        Intersect(state.valid, view.scene, &context.context, &state.packet);
        if (view.triangles) TakeNearestHits(&state);
        // Lanes in order: each pixel's samples are summed in increasing sample order. Lanes
        // without a ray keep geomID invalid.
        for (int i = 0; i < L; ++i) {
          if (state.packet.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
          // dir has camera-frame z = 1, so the ray parameter is the camera-frame depth.
          const float z = state.packet.ray.tfar[i];
          const int k = lanes.pixel[i];
          state.sum[k] += shade(state.packet.hit.primID[i], state.packet.hit.u[i],
                                state.packet.hit.v[i], state.sample_x[i], state.sample_y[i]);
          state.nearest[k] = std::min(state.nearest[k], z);
        }
      }
      StoreTile(view, state, x0, y0);
    }
  }
}

// RenderTilesBody compiled for each path (core/isa.h), called for the active one.
#define REPHOTO_RENDER_TILES_VARIANT(Name, Target)                                                \
  template <bool kJitter, bool kPinhole, int L, typename RayHit, typename Shade>                  \
  Target void Name(const View& view, const std::vector<PacketLanes<L>>& plan, const Shade& shade, \
                   int64_t row_begin, int64_t row_end) {                                          \
    RenderTilesBody<kJitter, kPinhole, L, RayHit>(view, plan, shade, row_begin, row_end);         \
  }
REPHOTO_RENDER_TILES_VARIANT(RenderTilesAvx512, REPHOTO_TARGET_AVX512)
REPHOTO_RENDER_TILES_VARIANT(RenderTilesAvx2, REPHOTO_TARGET_AVX2)
REPHOTO_RENDER_TILES_VARIANT(RenderTilesBaseline, )
#undef REPHOTO_RENDER_TILES_VARIANT

template <bool kJitter, bool kPinhole, int L, typename RayHit, typename Shade>
void RenderTiles(const View& view, const std::vector<PacketLanes<L>>& plan, const Shade& shade,
                 int64_t row_begin, int64_t row_end) {
  switch (core::ActiveIsa()) {
    case core::Isa::kAvx512:
      return RenderTilesAvx512<kJitter, kPinhole, L, RayHit>(view, plan, shade, row_begin, row_end);
    case core::Isa::kAvx2:
      return RenderTilesAvx2<kJitter, kPinhole, L, RayHit>(view, plan, shade, row_begin, row_end);
    case core::Isa::kBaseline:
      break;
  }
  RenderTilesBaseline<kJitter, kPinhole, L, RayHit>(view, plan, shade, row_begin, row_end);
}

// All tile rows of a view with L-ray packets, the tile loop specialized for the shading and
// the sample pattern.
template <int L, typename RayHit>
void RenderView(const View& view, const RenderModel& model) {
  const std::vector<PacketLanes<L>> plan = PlanPackets<L>(view.spp, view.grid);
  const int tile_rows = (view.rays.height() + L / kTileWidth - 1) / (L / kTileWidth);
  auto run = [&](const auto& shade) {
    const bool jitter = view.grid.jittered(), pinhole = view.rays.is_pinhole();
    ParallelFor(0, tile_rows, 1, [&](int64_t row_begin, int64_t row_end) {
      if (jitter && pinhole) {
        RenderTiles<true, true, L, RayHit>(view, plan, shade, row_begin, row_end);
      } else if (jitter) {
        RenderTiles<true, false, L, RayHit>(view, plan, shade, row_begin, row_end);
      } else if (pinhole) {
        RenderTiles<false, true, L, RayHit>(view, plan, shade, row_begin, row_end);
      } else {
        RenderTiles<false, false, L, RayHit>(view, plan, shade, row_begin, row_end);
      }
    });
  };
  if (model.representation() == Representation::kVertexColoredMesh) {
    run(VertexColorShade{view.mesh.faces.data(), view.mesh.colors.data()});
  } else {
    run(GenericShade{&view.shader});
  }
}

// 16 on the AVX-512 path (Embree traces 16-ray packets natively there), else 8: on an AVX2 CPU
// Embree splits a 16-ray packet into two 8-ray halves and 8-wide packets were measured 12 %
// faster. The image is the same either way (render.h).
int PacketWidth(int requested) {
  if (requested == 8 || requested == 16) return requested;
  return core::ActiveIsa() == core::Isa::kAvx512 ? 16 : 8;
}

}  // namespace

Eigen::Vector2f SampleOffset(int x, int y, int sample, const RenderOptions& options) {
  return SampleGrid(options).Offset(x, y, sample);
}

void RenderRephoto(const RenderModel& model, const CameraRays& rays,
                   const camera::Pose& cam_from_world, const RenderOptions& options, Rephoto* out) {
  REPHOTO_CHECK(options.samples_per_pixel >= 1 && options.samples_per_pixel <= 1024,
                "render: samples per pixel {} must be in [1, 1024]", options.samples_per_pixel);
  REPHOTO_CHECK(
      options.packet_width == 0 || options.packet_width == 8 || options.packet_width == 16,
      "render: packet width {} must be 0 (by CPU), 8 or 16", options.packet_width);
  cam_from_world.Validate("render: pose");
  const int width = rays.width(), height = rays.height();
  out->color.Resize(width, height, 4);
  out->depth.Resize(width, height, 1);
  const mesh::Mesh& mesh = model.mesh();
  const int spp = options.samples_per_pixel;
  const float sample_spacing =
      1.0f / static_cast<float>(std::ceil(std::sqrt(static_cast<double>(spp))));
  const Shader shader{model,
                      mesh,
                      rays,
                      cam_from_world.rotation.transpose().cast<float>(),
                      cam_from_world.Center().cast<float>(),
                      sample_spacing};
  const bool cull = !options.backfaces && !mesh.is_point_cloud();
  const SampleGrid grid(options);
  const View view{
      shader, rays, grid, model.scene(), mesh, cull, !mesh.is_point_cloud(), &model.border_skirts(),
      spp,    out};
  if (PacketWidth(options.packet_width) == 16) {
    RenderView<16, RTCRayHit16>(view, model);
  } else {
    RenderView<8, RTCRayHit8>(view, model);
  }
}

Rephoto RenderRephoto(const RenderModel& model, const camera::Camera& camera,
                      const camera::Pose& cam_from_world, const RenderOptions& options) {
  const auto rays = model.RaysFor(camera);
  Rephoto out;
  RenderRephoto(model, *rays, cam_from_world, options, &out);
  return out;
}

}  // namespace rephoto::render
