#include "rephoto/render/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"

namespace rephoto::render {
namespace {

// Tiles are 4 pixels wide and L / 4 rows high for packets of L = 8 or 16 rays (RenderTiles).
constexpr int kTileWidth = 4;

// Intersection context carrying what the backface filter needs.
struct RenderContext {
  RTCIntersectContext context;  // first member: Embree sees a plain RTCIntersectContext
  const mesh::Mesh* mesh = nullptr;
};

// Rejects hits on the back side of triangles (context filter, only installed when asked).
void BackfaceFilter(const RTCFilterFunctionNArguments* args) {
  const auto* context = reinterpret_cast<const RenderContext*>(args->context);
  const mesh::Mesh& mesh = *context->mesh;
  const unsigned n = args->N;
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    const mesh::Triangle& t = mesh.faces[RTCHitN_primID(args->hit, n, i)];
    const Eigen::Vector3f& p0 = mesh.positions[t[0]];
    const Eigen::Vector3f normal = (mesh.positions[t[1]] - p0).cross(mesh.positions[t[2]] - p0);
    const Eigen::Vector3f direction(RTCRayN_dir_x(args->ray, n, i), RTCRayN_dir_y(args->ray, n, i),
                                    RTCRayN_dir_z(args->ray, n, i));
    if (normal.dot(direction) > 0) args->valid[i] = 0;
  }
}

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
    if (jitter_) {
      const uint32_t h = Hash(static_cast<uint32_t>(x) * 0x9E3779B1u ^
                              Hash(static_cast<uint32_t>(y) * 0x85EBCA77u ^ sample_hash_[sample]));
      jx = UnitFloat(h);
      jy = UnitFloat(Hash(h ^ 0x68E31DA4u));
    }
    if (exact_reciprocals_) return Eigen::Vector2f((cx + jx) * inv_kx_, (cy + jy) * inv_ky_);
    return Eigen::Vector2f((cx + jx) / kx_, (cy + jy) / ky_);
  }

 private:
  static bool PowerOfTwo(int k) { return k > 0 && (k & (k - 1)) == 0; }
  bool jitter_;
  int n_, kx_ = 1, ky_ = 1;
  // Multiplying by 1/k equals dividing by k exactly when k is a power of two (e.g. 4 samples).
  bool exact_reciprocals_ = false;
  float inv_kx_ = 1, inv_ky_ = 1;
  std::vector<uint32_t> sample_hash_;
};

// Lane `lane` of packet `p` of a tile of L = 4 * samples_per_block pixels: its pixel (row-major
// in the 4-wide tile) and sample. Block mode (samples_per_packet = L / 4): packet p = block *
// groups + group covers the 2 x 2 block `block` and samples S * group .. S * group + S - 1,
// S = L / 4 (lane = 4 * sample-in-group + pixel-in-block); else (samples_per_packet 1) packet p
// is sample p of all L pixels. Either way each pixel's samples come in increasing order.
inline int PacketPixel(int p, int lane, int samples_per_packet, int groups) {
  if (samples_per_packet == 1) return lane;
  const int block = p / groups, in_block = lane & 3;
  return ((block >> 1) * 2 + (in_block >> 1)) * 4 + (block & 1) * 2 + (in_block & 1);
}
inline int PacketSample(int p, int lane, int samples_per_packet, int groups) {
  if (samples_per_packet == 1) return p;
  return (p % groups) * samples_per_packet + (lane >> 2);
}

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
  int spp;
  Rephoto* out;
};

// Renders tile rows [row_begin, row_end) of 4 x (L / 4)-pixel tiles with L-ray packets
// (RayHit = RTCRayHit8 or RTCRayHit16). With at least L / 4 samples per pixel a packet holds
// L / 4 samples of a 2 x 2 pixel block (a narrow packet meets fewer BVH nodes than L pixels'
// worth of one sample each), else one sample of all L pixels. Each pixel's samples are summed
// in increasing sample order, so both widths give the same sums from the same hits.
template <int L, typename RayHit>
void RenderTiles(const View& view, int64_t row_begin, int64_t row_end) {
  constexpr int kTileHeight = L / kTileWidth;
  const Shader& shader = view.shader;
  const int width = view.rays.width(), height = view.rays.height(), spp = view.spp;
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const int samples_per_packet = spp >= L / 4 ? L / 4 : 1;
  const int groups = (spp + samples_per_packet - 1) / samples_per_packet;  // per pixel block
  const int packets = (samples_per_packet == 1 ? 1 : L / 4) * groups;
  RenderContext context;
  rtcInitIntersectContext(&context.context);
  context.context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  if (view.cull) context.context.filter = BackfaceFilter;
  context.mesh = &view.mesh;
  alignas(64) RayHit packet;
  alignas(64) int valid[L];
  float sample_x[L], sample_y[L];
  int lane_pixel[L];
  float sum_r[L], sum_g[L], sum_b[L], nearest[L];
  int hits[L];
  for (int64_t tile_row = row_begin; tile_row < row_end; ++tile_row) {
    const int y0 = static_cast<int>(tile_row) * kTileHeight;
    for (int x0 = 0; x0 < width; x0 += kTileWidth) {
      for (int i = 0; i < L; ++i) {
        sum_r[i] = sum_g[i] = sum_b[i] = 0;
        nearest[i] = inf;
        hits[i] = 0;
      }
      for (int p = 0; p < packets; ++p) {
        int active = 0;
        for (int i = 0; i < L; ++i) {
          const int pixel = PacketPixel(p, i, samples_per_packet, groups);
          const int s = PacketSample(p, i, samples_per_packet, groups);
          const int px = x0 + (pixel & 3), py = y0 + (pixel >> 2);
          lane_pixel[i] = pixel;
          valid[i] = 0;
          packet.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
          if (px >= width || py >= height || s >= spp) continue;
          const Eigen::Vector2f offset = view.grid.Offset(px, py, s);
          sample_x[i] = static_cast<float>(px) + offset.x();
          sample_y[i] = static_cast<float>(py) + offset.y();
          float xn, yn;
          if (!view.rays.Ray(sample_x[i], sample_y[i], &xn, &yn)) continue;
          const Eigen::Vector3f d = shader.WorldDirection(xn, yn);
          packet.ray.org_x[i] = shader.origin.x();
          packet.ray.org_y[i] = shader.origin.y();
          packet.ray.org_z[i] = shader.origin.z();
          packet.ray.dir_x[i] = d.x();
          packet.ray.dir_y[i] = d.y();
          packet.ray.dir_z[i] = d.z();
          packet.ray.tnear[i] = 0.0f;
          packet.ray.tfar[i] = inf;
          packet.ray.time[i] = 0.0f;
          packet.ray.mask[i] = 0xFFFFFFFFu;
          packet.ray.id[i] = static_cast<unsigned>(i);
          packet.ray.flags[i] = 0;
          valid[i] = -1;
          ++active;
        }
        if (active == 0) continue;
        Intersect(valid, view.scene, &context.context, &packet);
        // Lanes in order: each pixel's samples are summed in increasing sample order.
        for (int i = 0; i < L; ++i) {
          if (valid[i] == 0 || packet.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
          // dir has camera-frame z = 1, so the ray parameter is the camera-frame depth.
          const float z = packet.ray.tfar[i];
          const Eigen::Vector3f c = shader.Shade(packet.hit.primID[i], packet.hit.u[i],
                                                 packet.hit.v[i], sample_x[i], sample_y[i]);
          const int k = lane_pixel[i];
          sum_r[k] += c.x();
          sum_g[k] += c.y();
          sum_b[k] += c.z();
          nearest[k] = std::min(nearest[k], z);
          ++hits[k];
        }
      }
      for (int i = 0; i < L; ++i) {
        const int px = x0 + (i & 3), py = y0 + (i >> 2);
        if (px >= width || py >= height) continue;
        float* rgba = view.out->color.data() + (static_cast<size_t>(py) * width + px) * 4;
        if (hits[i] > 0) {
          const float inv = 1.0f / static_cast<float>(hits[i]);
          rgba[0] = sum_r[i] * inv;
          rgba[1] = sum_g[i] * inv;
          rgba[2] = sum_b[i] * inv;
          rgba[3] = static_cast<float>(hits[i]) / static_cast<float>(spp);
          view.out->depth.at(px, py) = nearest[i];
        } else {
          rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0.0f;
          view.out->depth.at(px, py) = nan;
        }
      }
    }
  }
}

// 16 where Embree traces 16-ray packets natively (AVX-512), else 8: on an AVX2 CPU Embree
// splits a 16-ray packet into two 8-ray halves and 8-wide packets were measured 12 % faster.
int PacketWidth(RTCScene scene, int requested) {
  if (requested == 8 || requested == 16) return requested;
  static const int native = [scene] {
    const RTCDevice device = rtcGetSceneDevice(scene);
    return rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) ? 16 : 8;
  }();
  return native;
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
  const View view{shader, rays, grid, model.scene(), mesh, cull, spp, out};
  const int lanes = PacketWidth(model.scene(), options.packet_width);
  const int tile_rows = (height + lanes / kTileWidth - 1) / (lanes / kTileWidth);
  ParallelFor(0, tile_rows, 1, [&](int64_t row_begin, int64_t row_end) {
    if (lanes == 16) {
      RenderTiles<16, RTCRayHit16>(view, row_begin, row_end);
    } else {
      RenderTiles<8, RTCRayHit8>(view, row_begin, row_end);
    }
  });
}

Rephoto RenderRephoto(const RenderModel& model, const camera::Camera& camera,
                      const camera::Pose& cam_from_world, const RenderOptions& options) {
  const auto rays = model.RaysFor(camera);
  Rephoto out;
  RenderRephoto(model, *rays, cam_from_world, options, &out);
  return out;
}

}  // namespace rephoto::render
