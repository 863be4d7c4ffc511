#include "rephoto/splat/rasterize.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/parallel.h"

namespace rephoto::splat {
namespace {

constexpr int kTile = 16;  // BLOCK_X = BLOCK_Y of the reference
constexpr float kNearZ = 0.2f;
constexpr float kMinAlpha = 1.0f / 255.0f;
constexpr float kMaxAlpha = 0.99f;
constexpr float kMinTransmittance = 0.0001f;
constexpr float kDilation = 0.3f;

// SH basis constants (auxiliary.h of the reference).
constexpr float kShC1 = 0.4886025119029199f;
constexpr float kShC2[] = {1.0925484305920792f, -1.0925484305920792f, 0.31539156525252005f,
                           -1.0925484305920792f, 0.5462742152960396f};
constexpr float kShC3[] = {-0.5900435899266435f, 2.890611442640554f,   -0.4570457994644658f,
                           0.3731763325901154f,  -0.4570457994644658f, 1.445305721320277f,
                           -0.5900435899266435f};

using Clock = std::chrono::steady_clock;
double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

struct Pinhole {
  int width = 0;
  int height = 0;
  float fx = 0, fy = 0, cx = 0, cy = 0;  // corner convention (rephoto)
};

// What blending needs of one projected Gaussian (reference pixel coordinates: pixel x's centre
// is at x).
struct Splat {
  float px, py;                     // projected mean
  float conic_a, conic_b, conic_c;  // inverse 2D covariance (a b; b c)
  float opacity;
  float r, g, b;
  float depth;  // view z
  // Where opacity * exp(power) >= 1/255 can hold: q = d^T conic d <= level (inflated by the
  // rounding margin), and |dy| <= ext_y.
  float level, ext_y;
};

struct TileRect {
  int x0, y0, x1, y1;  // tiles [x0, x1) x [y0, y1)
};

[[gnu::always_inline]] inline Eigen::Vector3f ShColor(const float* sh, int degree,
                                                      const Eigen::Vector3f& dir) {
  auto coef = [&](int k) { return Eigen::Vector3f(sh[k * 3], sh[k * 3 + 1], sh[k * 3 + 2]); };
  Eigen::Vector3f result = kShC0 * coef(0);
  if (degree > 0) {
    const float x = dir.x(), y = dir.y(), z = dir.z();
    result = result - kShC1 * y * coef(1) + kShC1 * z * coef(2) - kShC1 * x * coef(3);
    if (degree > 1) {
      const float xx = x * x, yy = y * y, zz = z * z;
      const float xy = x * y, yz = y * z, xz = x * z;
      result = result + kShC2[0] * xy * coef(4) + kShC2[1] * yz * coef(5) +
               kShC2[2] * (2.0f * zz - xx - yy) * coef(6) + kShC2[3] * xz * coef(7) +
               kShC2[4] * (xx - yy) * coef(8);
      if (degree > 2) {
        result = result + kShC3[0] * y * (3.0f * xx - yy) * coef(9) + kShC3[1] * xy * z * coef(10) +
                 kShC3[2] * y * (4.0f * zz - xx - yy) * coef(11) +
                 kShC3[3] * z * (2.0f * zz - 3.0f * xx - 3.0f * yy) * coef(12) +
                 kShC3[4] * x * (4.0f * zz - xx - yy) * coef(13) +
                 kShC3[5] * z * (xx - yy) * coef(14) + kShC3[6] * x * (xx - 3.0f * yy) * coef(15);
      }
    }
  }
  result.array() += 0.5f;
  return result.cwiseMax(0.0f);
}

// Tile index range of getRect: min(grid, max(0, (int)v)), with the float clamped before the
// conversion so that huge radii cannot overflow.
[[gnu::always_inline]] inline int TileBound(float v, int grid) {
  if (!(v > 0.0f)) return 0;
  if (v >= static_cast<float>(grid)) return grid;
  return static_cast<int>(v);
}

// v clamped to [lo, hi] before the conversion (no overflow for huge extents); NaN (from
// extreme but finite parameters, e.g. inf - inf in an ellipse extent) gives lo.
[[gnu::always_inline]] inline int ClampToInt(float v, int lo, int hi) {
  if (!(v > static_cast<float>(lo))) return lo;
  if (v >= static_cast<float>(hi)) return hi;
  return static_cast<int>(v);
}

// What projecting one Gaussian computes before its tile range (ProjectCore8).
struct Projected {
  float depth, opacity, cov_a, cov_c, cov_b, det_inv, radius, px, py;
};

// The camera constants of the Jacobian clamp.
struct ClampLimits {
  float x_pos, x_neg, y_pos, y_neg;
  explicit ClampLimits(const Pinhole& cam) {
    const float tan_x = 0.5f * cam.width / cam.fx, tan_y = 0.5f * cam.height / cam.fy;
    x_pos = (cam.width - cam.cx) / cam.fx + 0.3f * tan_x;
    x_neg = cam.cx / cam.fx + 0.3f * tan_x;
    y_pos = (cam.height - cam.cy) / cam.fy + 0.3f * tan_y;
    y_neg = cam.cy / cam.fy + 0.3f * tan_y;
  }
};

// The rest of the projection of Gaussian g from ProjectCore8's values: tile range, alpha
// ellipse, colour; false when it is culled.
[[gnu::always_inline]] inline bool ProjectFinish(const GaussianModel& model, size_t g,
                                                 const Projected& pr, const Eigen::Vector3f& center,
                                                 int grid_x, int grid_y, Splat* splat,
                                                 TileRect* rect) {
  const float radius = pr.radius, px = pr.px, py = pr.py;
  const float cov_a = pr.cov_a, cov_b = pr.cov_b, cov_c = pr.cov_c, det_inv = pr.det_inv;
  const float opacity = pr.opacity;
  rect->x0 = TileBound((px - radius) / kTile, grid_x);
  rect->y0 = TileBound((py - radius) / kTile, grid_y);
  rect->x1 = TileBound((px + radius + kTile - 1) / kTile, grid_x);
  rect->y1 = TileBound((py + radius + kTile - 1) / kTile, grid_y);
  if ((rect->x1 - rect->x0) * (rect->y1 - rect->y0) == 0) return false;

  // Work saving, not a change of result: beyond the ellipse q = d^T conic d <= 2 ln(255 o),
  // alpha < 1/255 and the reference skips the pixel. The ellipse's bounding box has half extents
  // sqrt(level cov_xx), sqrt(level cov_yy) (cov = conic^-1). The level is inflated by a margin
  // that covers the float rounding of the per-pixel q (relative 1e-6 of its largest terms inside
  // the box, where thin rotated ellipses cancel), so no pixel the reference blends is missed.
  const float level = 2.0f * std::log(opacity * 255.0f);
  if (!(level >= 0.0f)) return false;
  const float ext_x0 = std::sqrt(level * cov_a), ext_y0 = std::sqrt(level * cov_c);
  const float conic_a = cov_c * det_inv, conic_b = -cov_b * det_inv, conic_c = cov_a * det_inv;
  const float term_scale = conic_a * ext_x0 * ext_x0 + conic_c * ext_y0 * ext_y0 +
                           2.0f * std::abs(conic_b) * ext_x0 * ext_y0;
  splat->level = level * 1.002f + 0.002f + 1e-6f * term_scale;
  const float ext_x = std::sqrt(splat->level * cov_a) + 0.01f;
  splat->ext_y = std::sqrt(splat->level * cov_c) + 0.01f;
  // Shrink the tile range to the tiles that ellipse box touches (others would skip it).
  rect->x0 = std::max(rect->x0, TileBound((px - ext_x) / kTile, grid_x));
  rect->y0 = std::max(rect->y0, TileBound((py - splat->ext_y) / kTile, grid_y));
  rect->x1 = std::min(rect->x1, TileBound((px + ext_x) / kTile + 1.0f, grid_x));
  rect->y1 = std::min(rect->y1, TileBound((py + splat->ext_y) / kTile + 1.0f, grid_y));
  if (rect->x1 <= rect->x0 || rect->y1 <= rect->y0) return false;

  const Eigen::Vector3f dir = (model.positions[g] - center).normalized();
  const Eigen::Vector3f color =
      ShColor(model.sh.data() + g * model.ShCoefficients() * 3, model.sh_degree, dir);
  splat->px = px;
  splat->py = py;
  splat->conic_a = conic_a;
  splat->conic_b = conic_b;
  splat->conic_c = conic_c;
  splat->opacity = opacity;
  splat->r = color[0];
  splat->g = color[1];
  splat->b = color[2];
  splat->depth = pr.depth;
  return true;
}

// An array of n trivially constructible T left uninitialized (std::vector would zero it on
// one thread before the parallel loops that fill it; here each page is first touched by the
// thread that writes it).
template <typename T>
std::unique_ptr<T[]> UninitializedArray(size_t n) {
  return std::unique_ptr<T[]>(new T[n]);
}

// A stable counting sort by bucket of items in contiguous chunks, counted and placed in
// parallel (the depth radix sort's passes and the per-tile lists). for_each(c, fn) calls
// fn(bucket, item) for the items of chunk c in their order (an item may be in several
// buckets). Each chunk's items of a bucket go after the earlier chunks' ones, so the result is
// the order one thread would give. Positions are 32-bit (fewer than 2^32 items).
class ChunkedBuckets {
 public:
  ChunkedBuckets(int64_t chunks, int64_t buckets)
      : chunks_(chunks), buckets_(buckets), at_(static_cast<size_t>(chunks * buckets)) {}

  // Counts the items per chunk and bucket.
  template <typename ForEach>
  void Count(const ForEach& for_each) {
    std::fill(at_.begin(), at_.end(), 0);
    ParallelFor(0, chunks_, 1, [&](int64_t cb, int64_t ce) {
      for (int64_t c = cb; c < ce; ++c) {
        uint32_t* count = at_.data() + c * buckets_;
        for_each(c, [&](int64_t bucket, uint32_t) { ++count[bucket]; });
      }
    });
  }
  // After Count: how many items bucket b holds.
  uint32_t InBucket(int64_t b) const {
    uint32_t n = 0;
    for (int64_t c = 0; c < chunks_; ++c) n += at_[c * buckets_ + b];
    return n;
  }
  // After Count: turns the counts into first positions (buckets in order, chunks in order
  // within a bucket); starts (optional, buckets + 1 values) receives each bucket's first
  // position and the total. Returns the total.
  uint32_t Prefix(uint32_t* starts = nullptr) {
    uint32_t total = 0;
    for (int64_t b = 0; b < buckets_; ++b) {
      if (starts) starts[b] = total;
      for (int64_t c = 0; c < chunks_; ++c) {
        const uint32_t n = at_[c * buckets_ + b];
        at_[c * buckets_ + b] = total;
        total += n;
      }
    }
    if (starts) starts[buckets_] = total;
    return total;
  }
  // After Prefix: place(position, item) for every (bucket, item) that for_each gives.
  template <typename ForEach, typename Place>
  void PlaceAll(const ForEach& for_each, const Place& place) {
    ParallelFor(0, chunks_, 1, [&](int64_t cb, int64_t ce) {
      for (int64_t c = cb; c < ce; ++c) {
        uint32_t* at = at_.data() + c * buckets_;
        for_each(c, [&](int64_t bucket, uint32_t item) { place(at[bucket]++, item); });
      }
    });
  }

 private:
  int64_t chunks_, buckets_;
  std::vector<uint32_t> at_;  // per chunk and bucket: the count, then the next position
};

// Stable LSD radix sort of n < 2^32 (key, value) pairs by key (non-negative float bits order as
// floats), 11 bits per pass, each pass a ChunkedBuckets sort. `keys` and `values` hold the
// result; the *_tmp arrays (n each) are scratch.
void RadixSort(size_t n, std::unique_ptr<uint32_t[]>& keys, std::unique_ptr<uint32_t[]>& values,
               std::unique_ptr<uint32_t[]>& keys_tmp, std::unique_ptr<uint32_t[]>& values_tmp) {
  constexpr int kBits = 11;
  constexpr uint32_t kBuckets = 1u << kBits, kMask = kBuckets - 1;
  if (n == 0) return;
  const int64_t chunks = std::clamp<int64_t>(static_cast<int64_t>(n / 65536), 1, 16);
  ChunkedBuckets sorter(chunks, kBuckets);
  for (int shift = 0; shift < 32; shift += kBits) {
    const uint32_t* k = keys.get();
    auto for_each = [&](int64_t c, const auto& fn) {
      const size_t i1 = n * (c + 1) / chunks;
      for (size_t i = n * c / chunks; i < i1; ++i)
        fn((k[i] >> shift) & kMask, static_cast<uint32_t>(i));
    };
    sorter.Count(for_each);
    if (sorter.InBucket((k[0] >> shift) & kMask) == n) continue;  // one bucket: order kept
    sorter.Prefix();
    sorter.PlaceAll(for_each, [&](uint32_t to, uint32_t i) {
      keys_tmp[to] = k[i];
      values_tmp[to] = values[i];
    });
    keys.swap(keys_tmp);
    values.swap(values_tmp);
  }
}

constexpr int kTilePixels = kTile * kTile;

// Eight floats (one AVX register; two SSE registers where AVX is missing), GCC/Clang vector
// extensions: the blend kernel is written once for both instruction sets.
typedef float V8f __attribute__((vector_size(32), may_alias));
typedef int32_t V8i __attribute__((vector_size(32), may_alias));
typedef int32_t V4i __attribute__((vector_size(16), may_alias));
// Eight floats at any float-aligned address.
typedef float V8fu __attribute__((vector_size(32), may_alias, aligned(4)));

// Bit k set where lane k of the comparison result `mask` (0 or -1 per lane) is true.
__attribute__((always_inline)) inline int MoveMask(const V8i& mask) {
#if defined(__SSE2__)
  const V4i low = __builtin_shufflevector(mask, mask, 0, 1, 2, 3);
  const V4i high = __builtin_shufflevector(mask, mask, 4, 5, 6, 7);
  return _mm_movemask_ps(_mm_castsi128_ps(reinterpret_cast<const __m128i&>(low))) |
         _mm_movemask_ps(_mm_castsi128_ps(reinterpret_cast<const __m128i&>(high))) << 4;
#else
  int bits = 0;
  for (int k = 0; k < 8; ++k) bits |= (mask[k] & 1) << k;
  return bits;
#endif
}

// The Gaussians index[0..7] up to their 2-D footprint (computeCov3D, computeCov2D with the
// Jacobian clamp, the culling tests of the reference), one per lane of 8-float vectors; a lane
// the reference culls gets keep[j] = 0 (its values are garbage). The operations and their order
// are those of the earlier one-at-a-time Eigen code (its 3-term dot products are
// a0 + (a1 + a2), its min/max selects), which gave the same bits; sqrt and ceil are correctly
// rounded on every path, so every lane has the same bits on every ISA path.
[[gnu::always_inline]] inline void ProjectCore8(const GaussianModel& model, const size_t* index,
                                                const Pinhole& cam, const ClampLimits& lim,
                                                const Eigen::Matrix3f& rot,
                                                const Eigen::Vector3f& trans, GaussianMode mode,
                                                Projected* out, bool* keep) {
  alignas(32) float in[11][8];
  for (int j = 0; j < 8; ++j) {
    const size_t g = index[j];
    const Eigen::Vector3f& mean = model.positions[g];
    const Eigen::Vector3f& sc = model.scales[g];
    const Eigen::Vector4f& q = model.rotations[g];
    for (int k = 0; k < 3; ++k) in[k][j] = mean[k];
    for (int k = 0; k < 3; ++k) in[3 + k][j] = sc[k];
    for (int k = 0; k < 4; ++k) in[6 + k][j] = q[k];
    in[10][j] = model.opacities[g];
  }
  // Macros, not functions returning vectors: without AVX a by-value 32-byte vector changes the
  // ABI (GCC's -Wpsabi). REPHOTO_BROADCAST8 puts v in every lane bit for bit (V8f{} + v would turn
  // -0 into +0); REPHOTO_VMAX / _VMIN are std::max / std::min (the same selects).
#define REPHOTO_LOAD8(k) (*reinterpret_cast<const V8f*>(in[k]))
#define REPHOTO_BROADCAST8(v) (V8f{(v), (v), (v), (v), (v), (v), (v), (v)})
#define REPHOTO_DOT3(a0, b0, a1, b1, a2, b2) ((a0) * (b0) + ((a1) * (b1) + (a2) * (b2)))
#define REPHOTO_VMAX(a, b) ((a) < (b) ? (b) : (a))
#define REPHOTO_VMIN(a, b) ((b) < (a) ? (b) : (a))
  const auto sqrt8 = [](const V8f& v, V8f* r) {
    for (int j = 0; j < 8; ++j) (*r)[j] = __builtin_sqrtf(v[j]);
  };
  const V8f mx = REPHOTO_LOAD8(0), my = REPHOTO_LOAD8(1), mz = REPHOTO_LOAD8(2);
  const V8f sx = REPHOTO_LOAD8(3), sy = REPHOTO_LOAD8(4), sz = REPHOTO_LOAD8(5);
  const V8f r = REPHOTO_LOAD8(6), x = REPHOTO_LOAD8(7), y = REPHOTO_LOAD8(8), z = REPHOTO_LOAD8(9);
  const V8f opacity_raw = REPHOTO_LOAD8(10);
  V8f p[3];
  for (int i = 0; i < 3; ++i) {
    p[i] = REPHOTO_DOT3(REPHOTO_BROADCAST8(rot(i, 0)), mx, REPHOTO_BROADCAST8(rot(i, 1)), my,
                        REPHOTO_BROADCAST8(rot(i, 2)), mz) +
           trans[i];
  }
  V8i alive = ~(p[2] <= kNearZ) & (opacity_raw >= kMinAlpha);  // the reference's tests (NaN)
  // rq, then m = rq * diag(s), sigma = m m^T.
  V8f rq[3][3];
  rq[0][0] = 1.f - 2.f * (y * y + z * z);
  rq[0][1] = 2.f * (x * y - r * z);
  rq[0][2] = 2.f * (x * z + r * y);
  rq[1][0] = 2.f * (x * y + r * z);
  rq[1][1] = 1.f - 2.f * (x * x + z * z);
  rq[1][2] = 2.f * (y * z - r * x);
  rq[2][0] = 2.f * (x * z - r * y);
  rq[2][1] = 2.f * (y * z + r * x);
  rq[2][2] = 1.f - 2.f * (x * x + y * y);
  const V8f s3[3] = {sx, sy, sz};
  V8f m[3][3];
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) m[i][k] = rq[i][k] * s3[k];
  }
  V8f sigma[3][3];  // symmetric: sigma[k][i] is the same products in the same order
  for (int i = 0; i < 3; ++i) {
    for (int k = i; k < 3; ++k) {
      sigma[i][k] = REPHOTO_DOT3(m[i][0], m[k][0], m[i][1], m[k][1], m[i][2], m[k][2]);
      sigma[k][i] = sigma[i][k];
    }
  }
  const V8f tz = p[2];
  const V8f tx = REPHOTO_VMIN(REPHOTO_BROADCAST8(lim.x_pos),
                              REPHOTO_VMAX(REPHOTO_BROADCAST8(-lim.x_neg), p[0] / tz)) *
                 tz;
  const V8f ty = REPHOTO_VMIN(REPHOTO_BROADCAST8(lim.y_pos),
                              REPHOTO_VMAX(REPHOTO_BROADCAST8(-lim.y_neg), p[1] / tz)) *
                 tz;
  const V8f zero{};
  const V8f jac[2][3] = {{cam.fx / tz, zero, -(cam.fx * tx) / (tz * tz)},
                         {zero, cam.fy / tz, -(cam.fy * ty) / (tz * tz)}};
  V8f t[2][3];
  for (int i = 0; i < 2; ++i) {
    for (int k = 0; k < 3; ++k) {
      t[i][k] =
          REPHOTO_DOT3(jac[i][0], REPHOTO_BROADCAST8(rot(0, k)), jac[i][1],
                       REPHOTO_BROADCAST8(rot(1, k)), jac[i][2], REPHOTO_BROADCAST8(rot(2, k)));
    }
  }
  V8f ts[2][3];  // t * sigma
  for (int i = 0; i < 2; ++i) {
    for (int k = 0; k < 3; ++k) {
      ts[i][k] = REPHOTO_DOT3(t[i][0], sigma[0][k], t[i][1], sigma[1][k], t[i][2], sigma[2][k]);
    }
  }
  const V8f cov_a0 = REPHOTO_DOT3(ts[0][0], t[0][0], ts[0][1], t[0][1], ts[0][2], t[0][2]);
  const V8f cov_b = REPHOTO_DOT3(ts[0][0], t[1][0], ts[0][1], t[1][1], ts[0][2], t[1][2]);
  const V8f cov_c0 = REPHOTO_DOT3(ts[1][0], t[1][0], ts[1][1], t[1][1], ts[1][2], t[1][2]);
  const V8f cov_a = cov_a0 + kDilation, cov_c = cov_c0 + kDilation;
  const V8f det = cov_a * cov_c - cov_b * cov_b;
  alive &= det != 0.0f;
  V8f opacity = opacity_raw;
  if (mode == GaussianMode::kAntialiased) {
    const V8f det_orig = cov_a0 * cov_c0 - cov_b * cov_b;
    const V8f ratio = det_orig / det;
    V8f root_ratio;
    sqrt8(REPHOTO_VMAX(zero, ratio), &root_ratio);
    opacity *= root_ratio;
    alive &= opacity >= kMinAlpha;
  }
  const V8f mid = 0.5f * (cov_a + cov_c);
  const V8f spread = mid * mid - det;
  V8f root_spread;
  sqrt8(REPHOTO_VMAX(REPHOTO_BROADCAST8(0.1f), spread), &root_spread);
  const V8f lambda1 = mid + root_spread;
  const V8f lambda2 = mid - root_spread;
  V8f root;
  sqrt8(REPHOTO_VMAX(lambda1, lambda2), &root);
  V8f radius;
  for (int j = 0; j < 8; ++j) radius[j] = std::ceil(3.0f * root[j]);
  const V8f det_inv = 1.0f / det;
  const V8f px = cam.fx * p[0] / p[2] + cam.cx - 0.5f;
  const V8f py = cam.fy * p[1] / p[2] + cam.cy - 0.5f;
  for (int j = 0; j < 8; ++j) {
    keep[j] = alive[j] != 0;
    out[j] = {p[2][j],    opacity[j], cov_a[j], cov_c[j], cov_b[j],
              det_inv[j], radius[j],  px[j],    py[j]};
  }
}
#undef REPHOTO_LOAD8
#undef REPHOTO_BROADCAST8
#undef REPHOTO_DOT3
#undef REPHOTO_VMAX
#undef REPHOTO_VMIN

// Projects Gaussians [begin, end) (visible[g] = 1 where not culled); returns how many are
// visible. Compiled per ISA path (core/isa.h): the same IEEE operations on each (no contraction,
// libm's logf, correctly rounded sqrt and ceil), only the encoding differs. Groups of 8; the
// last group's missing lanes repeat its last Gaussian (computed, not written).
[[gnu::always_inline]] inline uint32_t ProjectRangeBody(
    const GaussianModel& model, int64_t begin, int64_t end, const Pinhole& cam,
    const Eigen::Matrix3f& rot, const Eigen::Vector3f& trans, const Eigen::Vector3f& center,
    GaussianMode mode, int grid_x, int grid_y, Splat* splats, TileRect* rects, uint8_t* visible) {
  uint32_t count = 0;
  const size_t sh_floats = static_cast<size_t>(model.ShCoefficients()) * 3;
  const ClampLimits lim(cam);
  for (int64_t g = begin; g < end; g += 8) {
    // The colour coefficients (192 B at degree 3) of the next group: read only for the
    // visible ones, a stream with gaps that the hardware prefetcher followed late.
    if (g + 16 <= end) {
      const char* sh = reinterpret_cast<const char*>(model.sh.data() + (g + 8) * sh_floats);
      for (size_t b = 0; b < 8 * sh_floats * sizeof(float); b += 64) __builtin_prefetch(sh + b);
    }
    const int lanes = static_cast<int>(std::min<int64_t>(8, end - g));
    size_t index[8];
    for (int j = 0; j < 8; ++j) index[j] = static_cast<size_t>(g + std::min(j, lanes - 1));
    Projected pr[8];
    bool keep[8];
    ProjectCore8(model, index, cam, lim, rot, trans, mode, pr, keep);
    for (int j = 0; j < lanes; ++j) {
      const size_t i = index[j];
      visible[i] =
          keep[j] && ProjectFinish(model, i, pr[j], center, grid_x, grid_y, &splats[i], &rects[i]);
      count += visible[i];
    }
  }
  return count;
}
REPHOTO_ISA_DISPATCH_AVX2(
    uint32_t, ProjectRange,
    (const GaussianModel& model, int64_t begin, int64_t end, const Pinhole& cam,
     const Eigen::Matrix3f& rot, const Eigen::Vector3f& trans, const Eigen::Vector3f& center,
     GaussianMode mode, int grid_x, int grid_y, Splat* splats, TileRect* rects, uint8_t* visible),
    (model, begin, end, cam, rot, trans, center, mode, grid_x, grid_y, splats, rects, visible))

// exp(x) for x <= 0 (larger x are clamped to 0; callers mask them anyway), relative error
// below 2e-7: Cody-Waite reduction x = n ln2 + r, |r| <= ln2 / 2, a degree-6 Taylor polynomial
// for exp(r) and 2^n from the exponent bits (std::exp is a scalar libm call).
// (By reference: a 32-byte vector passed by value would change the ABI without AVX.)
__attribute__((always_inline)) inline void ExpNonPositive(const V8f& in, V8f* out) {
  V8f x = in < -87.0f ? V8f{} - 87.0f : in;
  x = x > 0.0f ? V8f{} : x;
  // round(x / ln2) for x <= 0 by truncation (SSE2 has no vector rounding instruction).
  const V8i ni = __builtin_convertvector(x * 1.44269504088896341f - 0.5f, V8i);
  const V8f n = __builtin_convertvector(ni, V8f);
  const V8f r = (x - n * 0.693359375f) + n * 2.12194440e-4f;
  V8f p = V8f{} + 1.3888889e-3f;
  p = p * r + 8.3333333e-3f;
  p = p * r + 4.1666667e-2f;
  p = p * r + 1.6666667e-1f;
  p = p * r + 0.5f;
  p = p * r + 1.0f;
  p = p * r + 1.0f;
  const V8i bits = (ni + 127) << 23;
  *out = p * reinterpret_cast<const V8f&>(bits);
}

// Per-pixel blending state of one tile (row-major, kTile x kTile).
struct TileState {
  alignas(64) float transmittance[kTilePixels];
  alignas(64) float acc_r[kTilePixels];
  alignas(64) float acc_g[kTilePixels];
  alignas(64) float acc_b[kTilePixels];
  alignas(64) float acc_z[kTilePixels];
  alignas(64) float done[kTilePixels];         // 1 = stopped (or outside the image)
  alignas(64) float error[kTilePixels];        // per-pixel error, 0 where invalid
  alignas(64) float error_valid[kTilePixels];  // 1 where the error is finite
  alignas(64) float weights[kTilePixels];      // one Gaussian's blending weights (error sums)
  alignas(64) float pixel_x[kTile];
  uint32_t row_done[kTile];  // per row, bit x set where done[row * kTile + x] is 1
  int done_count = 0;

  void Reset(int x_begin, int width, int height) {
    done_count = 0;
    for (int i = 0; i < kTile; ++i) row_done[i] = 0;
    for (int i = 0; i < kTilePixels; ++i) {
      transmittance[i] = 1.0f;
      acc_r[i] = acc_g[i] = acc_b[i] = acc_z[i] = 0.0f;
      const bool outside = i / kTile >= height || i % kTile >= width;
      done[i] = outside ? 1.0f : 0.0f;
      done_count += outside;
      row_done[i / kTile] |= static_cast<uint32_t>(outside) << (i % kTile);
    }
    for (int i = 0; i < kTile; ++i) pixel_x[i] = static_cast<float>(x_begin + i);
  }

  void SetError(const float* image, int image_width, int x_begin, int y_begin) {
    for (int i = 0; i < kTilePixels; ++i) {
      float e = 0;
      if (done[i] == 0.0f) {
        e = image[static_cast<size_t>(y_begin + i / kTile) * image_width + x_begin + i % kTile];
      }
      error_valid[i] = std::isfinite(e) ? 1.0f : 0.0f;
      error[i] = std::isfinite(e) ? e : 0.0f;
    }
  }
};

// Eight pixels [h, h + 8) of one tile row that a Gaussian may change.
struct BlendSpan {
  int row;  // offset of the span's first pixel in the tile arrays: row * kTile + h
  int h;
  float dy, bdy;  // the row's py - y and conic_b * dy
};

// power = -0.5 d^T conic d and alpha = min(0.99, opacity * exp(power)) of the span's pixels
// (only reads memory, so that two spans' arithmetic can overlap).
__attribute__((always_inline)) inline void SpanAlpha(const Splat& s, const BlendSpan& span,
                                                     const float* pixel_x, V8f* power, V8f* alpha) {
  const V8f dx = s.px - *reinterpret_cast<const V8fu*>(pixel_x + span.h);
  *power = -0.5f * (s.conic_a * dx * dx + s.conic_c * span.dy * span.dy) - span.bdy * dx;
  V8f a;
  ExpNonPositive(*power, &a);
  a *= s.opacity;
  *alpha = a < kMaxAlpha ? a : V8f{} + kMaxAlpha;
}

// Blends the span's pixels (the reference's per-pixel step); returns how many stopped.
__attribute__((always_inline)) inline int SpanBlend(const Splat& s, const BlendSpan& span,
                                                    const V8f& power, const V8f& alpha,
                                                    bool with_error, TileState* state) {
  const int at = span.row + span.h;
  V8fu& done = *reinterpret_cast<V8fu*>(state->done + at);
  V8fu& transmittance = *reinterpret_cast<V8fu*>(state->transmittance + at);
  const V8i valid = (done == 0.0f) & (power <= 0.0f) & (alpha >= kMinAlpha);
  const V8f t = transmittance;
  const V8f test_t = t * (1.0f - alpha);
  const V8i stop = valid & (test_t < kMinTransmittance);
  const V8i update = valid & ~stop;
  const V8f w = update ? alpha * t : V8f{};
  const int stop_bits = MoveMask(stop);
  if (stop_bits != 0) {
    done = stop ? V8f{} + 1.0f : V8f(done);
    state->row_done[span.row / kTile] |= static_cast<uint32_t>(stop_bits) << span.h;
  }
  *reinterpret_cast<V8fu*>(state->acc_r + at) += s.r * w;
  *reinterpret_cast<V8fu*>(state->acc_g + at) += s.g * w;
  *reinterpret_cast<V8fu*>(state->acc_b + at) += s.b * w;
  *reinterpret_cast<V8fu*>(state->acc_z + at) += s.depth * w;
  transmittance = update ? test_t : t;
  if (with_error) *reinterpret_cast<V8fu*>(state->weights + at) = w;
  return __builtin_popcount(static_cast<unsigned>(stop_bits));
}

// The chord [x0[i], x1[i]] of tile row i, i.e. of image row y_begin + i, of the Gaussian's
// ellipse q <= level (a dx^2 + 2 b dy dx + c dy^2 - level <= 0 with dx = px - x; a > 0: the
// conic is positive definite), clamped to the tile's columns as ClampToInt does; a row without
// a chord gets x1 < x0. All kTile rows at once without a branch, so that the loop vectorises
// (sqrt, divisions, ceil and floor are correctly rounded element-wise: the same values as one
// row at a time). Which rows the caller uses does not change a pixel either way: pixels outside
// the chord get alpha < 1/255 (level holds the rounding margin).
struct RowChords {
  alignas(64) int x0[kTile];
  alignas(64) int x1[kTile];
};

[[gnu::always_inline]] inline void ComputeRowChords(const Splat& s, int x_begin, int x_end,
                                                    int y_begin, RowChords* chords) {
  const float lo0 = static_cast<float>(x_begin), hi0 = static_cast<float>(x_end);
  const float lo1 = static_cast<float>(x_begin - 1), hi1 = static_cast<float>(x_end - 1);
  for (int i = 0; i < kTile; ++i) {
    const float dy = s.py - static_cast<float>(y_begin + i);
    const float bdy = s.conic_b * dy;
    const float disc = bdy * bdy - s.conic_a * (s.conic_c * dy * dy - s.level);
    const bool has_chord = disc >= 0.0f;  // false for NaN too
    const float root = __builtin_sqrtf(has_chord ? disc : 0.0f);
    const float dx_low = (-bdy - root) / s.conic_a, dx_high = (-bdy + root) / s.conic_a;
    float f0 = std::ceil(s.px - dx_high - 0.01f);
    float f1 = std::floor(s.px - dx_low + 0.01f);
    f0 = f0 > lo0 ? f0 : lo0;  // ClampToInt(f0, x_begin, x_end), NaN to the low bound
    f0 = f0 >= hi0 ? hi0 : f0;
    f1 = f1 > lo1 ? f1 : lo1;  // ClampToInt(f1, x_begin - 1, x_end - 1)
    f1 = f1 >= hi1 ? hi1 : f1;
    chords->x0[i] = has_chord ? static_cast<int>(f0) : x_end;
    chords->x1[i] = has_chord ? static_cast<int>(f1) : x_begin - 1;
  }
}

// One Gaussian's spans in a tile and their alpha (PrepareGaussian), made before the previous
// Gaussian is blended so that their arithmetic overlaps its blend (SpanAlpha only reads the
// Gaussian; the spans read row_done, which that blend can only grow: a span whose pixels all
// stop meanwhile is blended as a no-op, every pixel of it being done).
struct PreparedGaussian {
  BlendSpan spans[2 * kTile];
  V8f power[2 * kTile], alpha[2 * kTile];
  int span_count = 0;
  int y0 = 0, y1 = -1;  // y1 < y0: no row of the tile within reach
};

[[gnu::always_inline]] inline void PrepareGaussian(const Splat& s, int x_begin, int y_begin,
                                                   int x_end, int y_end, const TileState& state,
                                                   PreparedGaussian* p) {
  p->y0 = ClampToInt(std::ceil(s.py - s.ext_y), y_begin, y_end - 1);
  p->y1 = ClampToInt(std::floor(s.py + s.ext_y), y_begin - 1, y_end - 1);
  p->span_count = 0;
  if (p->y1 < p->y0) return;
  RowChords chords;
  ComputeRowChords(s, x_begin, x_end, y_begin, &chords);
  int span_count = 0;
  for (int y = p->y0; y <= p->y1; ++y) {
    const int row_index = y - y_begin;
    const uint32_t row_done = state.row_done[row_index];
    if (row_done == (1u << kTile) - 1) continue;
    const int x0 = chords.x0[row_index], x1 = chords.x1[row_index];
    if (x1 < x0) continue;
    const float dy = s.py - static_cast<float>(y);
    const float bdy = s.conic_b * dy;
    // Eight pixels [h, h + 8) that hold the chord [x0, x1] when it is at most 8 wide,
    // otherwise the two halves of the row.
    const int lo = x0 - x_begin, hi = x1 - x_begin;
    const int h_first = hi - lo < 8 ? std::min(lo, kTile - 8) : 0;
    const int h_last = hi - lo < 8 ? h_first : 8;
    for (int h = h_first; h <= h_last; h += 8) {
      if (((row_done >> h) & 0xffu) == 0xffu) continue;
      p->spans[span_count++] = {row_index * kTile, h, dy, bdy};
    }
  }
  p->span_count = span_count;
  for (int k = 0; k < span_count; ++k) {
    SpanAlpha(s, p->spans[k], state.pixel_x, &p->power[k], &p->alpha[k]);
  }
}

// Blends the Gaussians entries[begin, end) (front to back) into one tile, the reference's
// per-pixel loop. Rows are cut to the chord of the Gaussian's alpha >= 1/255 ellipse; the
// 8 pixels around a chord of at most 8 pixels, or both 8-pixel halves of the row for a longer
// one (unless all their pixels have stopped), are the Gaussian's spans. Spans are evaluated
// without branches on 8-float vectors (an AVX2 + FMA variant and an SSE2 one, core/isa.h; the
// arithmetic is the same IEEE float operations in both), the next Gaussian's while this one
// is blended. Pixels outside the chord get alpha < 1/255 and change nothing, stopped pixels
// change nothing, and the spans of one Gaussian share no pixel, so neither the skipping nor
// the order changes a bit. `sums` (optional) receives per entry the sums of w * error and of w
// over valid error pixels.
[[gnu::always_inline]] inline void BlendTileBody(const Splat* splats, const uint32_t* entries,
                                                 uint32_t begin, uint32_t end, int x_begin,
                                                 int y_begin, int x_end, int y_end, bool with_error,
                                                 TileState* state, float* sums_we, float* sums_w) {
  if (begin >= end) return;
  PreparedGaussian prepared[2];
  int cur = 0;
  PrepareGaussian(splats[entries[begin]], x_begin, y_begin, x_end, y_end, *state, &prepared[0]);
  for (uint32_t e = begin; e < end && state->done_count < kTilePixels; ++e, cur ^= 1) {
    if (e + 8 < end) __builtin_prefetch(&splats[entries[e + 8]]);
    if (e + 1 < end) {
      PrepareGaussian(splats[entries[e + 1]], x_begin, y_begin, x_end, y_end, *state,
                      &prepared[cur ^ 1]);
    }
    const Splat& s = splats[entries[e]];
    const PreparedGaussian& p = prepared[cur];
    if (p.y1 < p.y0) {  // no row of the tile within reach: nothing blended
      if (with_error) sums_we[e] = sums_w[e] = 0.0f;
      continue;
    }
    if (with_error) {
      for (int i = (p.y0 - y_begin) * kTile; i < (p.y1 + 1 - y_begin) * kTile; ++i) {
        state->weights[i] = 0.0f;
      }
    }
    int stops = 0;
    for (int k = 0; k < p.span_count; ++k) {
      stops += SpanBlend(s, p.spans[k], p.power[k], p.alpha[k], with_error, state);
    }
    state->done_count += stops;
    if (with_error) {
      // Per row in order, as the reference's per-pixel sums (zero weights add nothing).
      float sum_we = 0, sum_w = 0;
      for (int y = p.y0; y <= p.y1; ++y) {
        const int row = (y - y_begin) * kTile;
        float row_we = 0, row_w = 0;
        for (int i = 0; i < kTile; ++i) {
          row_we += state->weights[row + i] * state->error[row + i];
          row_w += state->weights[row + i] * state->error_valid[row + i];
        }
        sum_we += row_we;
        sum_w += row_w;
      }
      sums_we[e] = sum_we;
      sums_w[e] = sum_w;
    }
  }
}
REPHOTO_ISA_DISPATCH_AVX2(void, BlendTile,
                          (const Splat* splats, const uint32_t* entries, uint32_t begin,
                           uint32_t end, int x_begin, int y_begin, int x_end, int y_end,
                           bool with_error, TileState* state, float* sums_we, float* sums_w),
                          (splats, entries, begin, end, x_begin, y_begin, x_end, y_end, with_error,
                           state, sums_we, sums_w))

// Rasterizes on a pinhole grid. `error` (optional, width x height floats, NaN = skip) with
// `accumulator` adds per-Gaussian weights.
void RasterizePinhole(const GaussianModel& model, const Pinhole& cam, const camera::Pose& pose,
                      const GaussianRenderOptions& options, Image* color, Image* depth,
                      const float* error, GaussianErrorAccumulator* accumulator,
                      GaussianRenderStats* stats) {
  const auto start = Clock::now();
  const int grid_x = (cam.width + kTile - 1) / kTile;
  const int grid_y = (cam.height + kTile - 1) / kTile;
  const Eigen::Matrix3f rot = pose.rotation.cast<float>();
  const Eigen::Vector3f trans = pose.translation.cast<float>();
  const Eigen::Vector3f center = pose.Center().cast<float>();
  const size_t n = model.size();

  // Projection in chunks; per chunk the number of visible Gaussians.
  constexpr int64_t kChunk = 8192;
  const int64_t chunks = (static_cast<int64_t>(n) + kChunk - 1) / kChunk;
  auto splats = UninitializedArray<Splat>(n);
  auto rects = UninitializedArray<TileRect>(n);
  auto visible = UninitializedArray<uint8_t>(n);
  std::vector<uint32_t> chunk_offsets(chunks + 1, 0);
  ParallelFor(0, chunks, 1, [&](int64_t cb, int64_t ce) {
    for (int64_t c = cb; c < ce; ++c) {
      chunk_offsets[c + 1] = ProjectRange(
          model, c * kChunk, std::min<int64_t>(static_cast<int64_t>(n), (c + 1) * kChunk), cam, rot,
          trans, center, options.mode, grid_x, grid_y, splats.get(), rects.get(), visible.get());
    }
  });
  for (int64_t c = 0; c < chunks; ++c) chunk_offsets[c + 1] += chunk_offsets[c];
  const auto sort_start = Clock::now();
  if (stats)
    stats->project_ms = std::chrono::duration<double, std::milli>(sort_start - start).count();

  // Front to back by view depth, ties by index (keys in index order, stable sort).
  const size_t visible_count = chunk_offsets[chunks];
  auto keys = UninitializedArray<uint32_t>(visible_count);
  auto order_array = UninitializedArray<uint32_t>(visible_count);
  ParallelFor(0, chunks, 1, [&](int64_t cb, int64_t ce) {
    for (int64_t c = cb; c < ce; ++c) {
      uint32_t at = chunk_offsets[c];
      for (int64_t g = c * kChunk; g < std::min<int64_t>(n, (c + 1) * kChunk); ++g) {
        if (!visible[g]) continue;
        std::memcpy(&keys[at], &splats[g].depth, sizeof(uint32_t));
        order_array[at++] = static_cast<uint32_t>(g);
      }
    }
  });
  {
    auto keys_tmp = UninitializedArray<uint32_t>(visible_count);
    auto order_tmp = UninitializedArray<uint32_t>(visible_count);
    RadixSort(visible_count, keys, order_array, keys_tmp, order_tmp);
  }
  keys.reset();
  const uint32_t* order = order_array.get();
  // Gaussians in depth order: each tile's list then walks memory forwards.
  auto sorted = UninitializedArray<Splat>(visible_count);
  auto sorted_rects = UninitializedArray<TileRect>(visible_count);
  ParallelFor(0, static_cast<int64_t>(visible_count), 65536, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      sorted[i] = splats[order[i]];
      sorted_rects[i] = rects[order[i]];
    }
  });
  splats.reset();
  rects.reset();

  // Per-tile lists: the (tile, Gaussian) entries sorted by tile (ChunkedBuckets over chunks of
  // the depth order, so every tile's list is in depth order).
  const int64_t tiles = static_cast<int64_t>(grid_x) * grid_y;
  // Up to 32 chunks of at least 16k Gaussians, and at most 16 MB of per-chunk tile counters
  // (a 16k x 16k image has a million tiles).
  const int64_t list_chunks = std::clamp<int64_t>(
      std::min<int64_t>(static_cast<int64_t>(visible_count / 16384), (int64_t{4} << 20) / tiles), 1,
      32);
  ChunkedBuckets lists(list_chunks, tiles);
  auto for_each = [&](int64_t c, const auto& fn) {
    const uint32_t i1 = static_cast<uint32_t>(visible_count * (c + 1) / list_chunks);
    for (uint32_t i = static_cast<uint32_t>(visible_count * c / list_chunks); i < i1; ++i) {
      const TileRect& r = sorted_rects[i];
      for (int ty = r.y0; ty < r.y1; ++ty) {
        for (int tx = r.x0; tx < r.x1; ++tx) fn(static_cast<int64_t>(ty) * grid_x + tx, i);
      }
    }
  };
  lists.Count(for_each);
  std::vector<uint32_t> tile_offsets(static_cast<size_t>(tiles) + 1);
  const size_t entry_count = lists.Prefix(tile_offsets.data());
  auto entries = UninitializedArray<uint32_t>(std::max<size_t>(entry_count, 1));
  lists.PlaceAll(for_each, [&](uint32_t to, uint32_t i) { entries[to] = i; });
  sorted_rects.reset();
  const auto blend_start = Clock::now();
  if (stats) {
    stats->sort_ms = std::chrono::duration<double, std::milli>(blend_start - sort_start).count();
    stats->visible = visible_count;
    stats->tile_entries = entry_count;
  }

  std::vector<float> entry_weighted_error(accumulator ? entry_count : 0, 0.0f);
  std::vector<float> entry_weight(accumulator ? entry_count : 0, 0.0f);

  color->Resize(cam.width, cam.height, 4);
  depth->Resize(cam.width, cam.height, 1);
  const Eigen::Vector3f background = options.background;
  ParallelFor(0, static_cast<int64_t>(grid_x) * grid_y, 1, [&](int64_t tb, int64_t te) {
    TileState state;
    for (int64_t tile = tb; tile < te; ++tile) {
      const int tx = static_cast<int>(tile % grid_x), ty = static_cast<int>(tile / grid_x);
      const int x_begin = tx * kTile, y_begin = ty * kTile;
      const int x_end = std::min(cam.width, x_begin + kTile);
      const int y_end = std::min(cam.height, y_begin + kTile);
      state.Reset(x_begin, x_end - x_begin, y_end - y_begin);
      if (error != nullptr) state.SetError(error, cam.width, x_begin, y_begin);
      BlendTile(sorted.get(), entries.get(), tile_offsets[tile], tile_offsets[tile + 1], x_begin,
                y_begin, x_end, y_end, error != nullptr, &state,
                error != nullptr ? entry_weighted_error.data() : nullptr,
                error != nullptr ? entry_weight.data() : nullptr);
      for (int y = y_begin; y < y_end; ++y) {
        float* out = color->row(y) + static_cast<size_t>(x_begin) * 4;
        float* out_depth = depth->row(y) + x_begin;
        for (int x = x_begin; x < x_end; ++x, out += 4, ++out_depth) {
          const int i = (y - y_begin) * kTile + (x - x_begin);
          const float t = state.transmittance[i];
          out[0] = state.acc_r[i] + t * background[0];
          out[1] = state.acc_g[i] + t * background[1];
          out[2] = state.acc_b[i] + t * background[2];
          out[3] = 1.0f - t;
          *out_depth =
              t < 1.0f ? state.acc_z[i] / (1.0f - t) : std::numeric_limits<float>::quiet_NaN();
        }
      }
    }
  });
  if (accumulator != nullptr) {
    // In (tile, depth) order: the same sums for any thread count.
    for (size_t e = 0; e < entry_count; ++e) {
      const uint32_t g = order[entries[e]];
      accumulator->weighted_error[g] += entry_weighted_error[e];
      accumulator->weight[g] += entry_weight[e];
    }
  }
  if (stats) stats->blend_ms = MillisecondsSince(blend_start);
}

// Array sizes only (O(1)); values were validated when the model was read.
void CheckModel(const GaussianModel& model, std::string_view context) {
  const size_t n = model.size();
  REPHOTO_CHECK(model.sh_degree >= 0 && model.sh_degree <= 3 && model.scales.size() == n &&
                    model.rotations.size() == n && model.opacities.size() == n &&
                    model.sh.size() == n * model.ShCoefficients() * 3 && n < (1ull << 32),
                "{}: inconsistent Gaussian model (array sizes or SH degree)", context);
}

Pinhole PinholeOf(const camera::Camera& camera) {
  return {camera.width,
          camera.height,
          static_cast<float>(camera.FocalLengthX()),
          static_cast<float>(camera.FocalLengthY()),
          static_cast<float>(camera.PrincipalPointX()),
          static_cast<float>(camera.PrincipalPointY())};
}

// For a distorted camera: the undistorted position (pinhole pixel coordinates, corner
// convention, with the camera's fx, fy, cx, cy) of every pixel centre, NaN where there is no
// ray; and the pinhole grid that covers them.
struct Undistortion {
  std::vector<Eigen::Vector2f> positions;  // per pixel; grid coordinates (offset applied)
  Pinhole grid;
};

Undistortion ComputeUndistortion(const camera::Camera& camera) {
  Undistortion u;
  const Pinhole base = PinholeOf(camera);
  const size_t pixels = static_cast<size_t>(camera.width) * camera.height;
  u.positions.resize(pixels);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  ParallelFor(0, camera.height, 8, [&](int64_t yb, int64_t ye) {
    for (int64_t y = yb; y < ye; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const auto ray = camera.CamFromImg(Eigen::Vector2d(x + 0.5, y + 0.5));
        Eigen::Vector2f& at = u.positions[static_cast<size_t>(y) * camera.width + x];
        if (!ray || (*ray).z() <= 0) {
          at = Eigen::Vector2f(nan, nan);
          continue;
        }
        at = Eigen::Vector2f(static_cast<float>(base.fx * ray->x() / ray->z() + base.cx),
                             static_cast<float>(base.fy * ray->y() / ray->z() + base.cy));
      }
    }
  });
  // Grid covering the positions, at most 4x the image per axis around the image itself.
  float min_x = 0, min_y = 0, max_x = static_cast<float>(camera.width),
        max_y = static_cast<float>(camera.height);
  for (const Eigen::Vector2f& p : u.positions) {
    if (!std::isfinite(p.x())) continue;
    min_x = std::min(min_x, p.x());
    max_x = std::max(max_x, p.x());
    min_y = std::min(min_y, p.y());
    max_y = std::max(max_y, p.y());
  }
  const float limit_x = 1.5f * camera.width, limit_y = 1.5f * camera.height;
  min_x = std::max(min_x, -limit_x);
  min_y = std::max(min_y, -limit_y);
  max_x = std::min(max_x, camera.width + limit_x);
  max_y = std::min(max_y, camera.height + limit_y);
  const int offset_x = static_cast<int>(std::floor(min_x)) - 1;
  const int offset_y = static_cast<int>(std::floor(min_y)) - 1;
  u.grid = base;
  u.grid.width = static_cast<int>(std::ceil(max_x)) + 1 - offset_x;
  u.grid.height = static_cast<int>(std::ceil(max_y)) + 1 - offset_y;
  u.grid.cx -= static_cast<float>(offset_x);
  u.grid.cy -= static_cast<float>(offset_y);
  for (Eigen::Vector2f& p : u.positions) {
    p -= Eigen::Vector2f(static_cast<float>(offset_x), static_cast<float>(offset_y));
    if (!(p.x() >= 0 && p.y() >= 0 && p.x() <= u.grid.width && p.y() <= u.grid.height)) {
      p = Eigen::Vector2f(nan, nan);
    }
  }
  return u;
}

// The undistortion map of `camera`, from a small process-wide cache: views of one camera (the
// usual case) compute it once (it costs one Newton solve per pixel). Thread-safe.
std::shared_ptr<const Undistortion> UndistortionFor(const camera::Camera& camera) {
  static std::mutex mutex;
  static std::vector<std::pair<camera::Camera, std::shared_ptr<const Undistortion>>> cache;
  {
    const std::lock_guard<std::mutex> lock(mutex);
    for (const auto& [key, value] : cache) {
      if (key == camera) return value;
    }
  }
  auto computed = std::make_shared<const Undistortion>(ComputeUndistortion(camera));
  const std::lock_guard<std::mutex> lock(mutex);
  constexpr size_t kCachedCameras = 4;
  if (cache.size() == kCachedCameras) cache.erase(cache.begin());
  cache.emplace_back(camera, computed);
  return computed;
}

void Resample(const Undistortion& u, const Image& grid_color, const Image& grid_depth,
              const camera::Camera& camera, const Eigen::Vector3f& background,
              GaussianRendering* out) {
  out->color.Resize(camera.width, camera.height, 4);
  out->depth.Resize(camera.width, camera.height, 1);
  const int gw = grid_color.width(), gh = grid_color.height();
  ParallelFor(0, camera.height, 8, [&](int64_t yb, int64_t ye) {
    for (int64_t y = yb; y < ye; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const Eigen::Vector2f p = u.positions[static_cast<size_t>(y) * camera.width + x];
        float* c = &out->color.at(x, static_cast<int>(y), 0);
        float& d = out->depth.at(x, static_cast<int>(y));
        if (!std::isfinite(p.x())) {
          c[0] = background[0];
          c[1] = background[1];
          c[2] = background[2];
          c[3] = 0.0f;
          d = std::numeric_limits<float>::quiet_NaN();
          continue;
        }
        // Bilinear between grid pixel centres (clamped at the border).
        const float fx = p.x() - 0.5f, fy = p.y() - 0.5f;
        const int x0 = std::clamp(static_cast<int>(std::floor(fx)), 0, gw - 1);
        const int y0 = std::clamp(static_cast<int>(std::floor(fy)), 0, gh - 1);
        const int x1 = std::min(x0 + 1, gw - 1), y1 = std::min(y0 + 1, gh - 1);
        const float ax = std::clamp(fx - x0, 0.0f, 1.0f), ay = std::clamp(fy - y0, 0.0f, 1.0f);
        for (int ch = 0; ch < 4; ++ch) {
          const float top = grid_color.at(x0, y0, ch) * (1 - ax) + grid_color.at(x1, y0, ch) * ax;
          const float bottom =
              grid_color.at(x0, y1, ch) * (1 - ax) + grid_color.at(x1, y1, ch) * ax;
          c[ch] = top * (1 - ay) + bottom * ay;
        }
        const int nx = std::clamp(static_cast<int>(p.x()), 0, gw - 1);
        const int ny = std::clamp(static_cast<int>(p.y()), 0, gh - 1);
        d = grid_depth.at(nx, ny);
      }
    }
  });
}

}  // namespace

void RenderGaussians(const GaussianModel& model, const camera::Camera& camera,
                     const camera::Pose& cam_from_world, const GaussianRenderOptions& options,
                     GaussianRendering* out, GaussianRenderStats* stats) {
  camera.Validate("RenderGaussians");
  CheckModel(model, "RenderGaussians");
  if (camera.IsPinhole()) {
    RasterizePinhole(model, PinholeOf(camera), cam_from_world, options, &out->color, &out->depth,
                     nullptr, nullptr, stats);
    return;
  }
  const std::shared_ptr<const Undistortion> cached = UndistortionFor(camera);
  const Undistortion& u = *cached;
  GaussianRendering grid;
  RasterizePinhole(model, u.grid, cam_from_world, options, &grid.color, &grid.depth, nullptr,
                   nullptr, stats);
  const auto start = Clock::now();
  Resample(u, grid.color, grid.depth, camera, options.background, out);
  if (stats) stats->blend_ms += MillisecondsSince(start);
}

GaussianRendering RenderGaussians(const GaussianModel& model, const camera::Camera& camera,
                                  const camera::Pose& cam_from_world,
                                  const GaussianRenderOptions& options,
                                  GaussianRenderStats* stats) {
  GaussianRendering out;
  RenderGaussians(model, camera, cam_from_world, options, &out, stats);
  return out;
}

void AccumulateGaussianErrors(const GaussianModel& model, const camera::Camera& camera,
                              const camera::Pose& cam_from_world,
                              const GaussianRenderOptions& options, const Image& error,
                              GaussianErrorAccumulator* accumulator) {
  camera.Validate("AccumulateGaussianErrors");
  CheckModel(model, "AccumulateGaussianErrors");
  REPHOTO_CHECK(
      error.width() == camera.width && error.height() == camera.height && error.channels() == 1,
      "AccumulateGaussianErrors: error image is {}x{}x{}, camera is {}x{} (1 channel)",
      error.width(), error.height(), error.channels(), camera.width, camera.height);
  if (accumulator->weight.empty() && accumulator->weighted_error.empty()) {
    accumulator->Reset(model.size());
  }
  REPHOTO_CHECK(accumulator->weight.size() == model.size() &&
                    accumulator->weighted_error.size() == model.size(),
                "AccumulateGaussianErrors: accumulator holds {} Gaussians, model {}",
                accumulator->weight.size(), model.size());
  GaussianRendering grid;
  if (camera.IsPinhole()) {
    RasterizePinhole(model, PinholeOf(camera), cam_from_world, options, &grid.color, &grid.depth,
                     error.data(), accumulator, nullptr);
    return;
  }
  // Move each pixel's error to the nearest grid pixel (mean where several land on one).
  const std::shared_ptr<const Undistortion> cached = UndistortionFor(camera);
  const Undistortion& u = *cached;
  const size_t grid_pixels = static_cast<size_t>(u.grid.width) * u.grid.height;
  std::vector<float> sum(grid_pixels, 0.0f);
  std::vector<int> count(grid_pixels, 0);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Eigen::Vector2f p = u.positions[static_cast<size_t>(y) * camera.width + x];
      const float e = error.at(x, y);
      if (!std::isfinite(p.x()) || !std::isfinite(e)) continue;
      const int gx = std::clamp(static_cast<int>(p.x()), 0, u.grid.width - 1);
      const int gy = std::clamp(static_cast<int>(p.y()), 0, u.grid.height - 1);
      sum[static_cast<size_t>(gy) * u.grid.width + gx] += e;
      ++count[static_cast<size_t>(gy) * u.grid.width + gx];
    }
  }
  for (size_t i = 0; i < grid_pixels; ++i) {
    sum[i] = count[i] > 0 ? sum[i] / count[i] : std::numeric_limits<float>::quiet_NaN();
  }
  RasterizePinhole(model, u.grid, cam_from_world, options, &grid.color, &grid.depth, sum.data(),
                   accumulator, nullptr);
}

std::optional<GaussianMode> ParseGaussianMode(std::string_view text) {
  if (text == "classic") return GaussianMode::kClassic;
  if (text == "antialiased") return GaussianMode::kAntialiased;
  return std::nullopt;
}

Eigen::Vector3f ParseBackground(std::string_view text, std::string_view source) {
  if (text == "black") return Eigen::Vector3f::Zero();
  if (text == "white") return Eigen::Vector3f::Ones();
  Eigen::Vector3f color;
  size_t begin = 0;
  for (int c = 0; c < 3; ++c) {
    const size_t end = text.find(',', begin);
    const bool ok_comma = (c < 2) == (end != std::string_view::npos);
    const std::string token(text.substr(begin, end == std::string_view::npos ? end : end - begin));
    char* stop = nullptr;
    color[c] = ok_comma ? std::strtof(token.c_str(), &stop) : -1.0f;
    REPHOTO_CHECK_USAGE(
        ok_comma && !token.empty() && *stop == '\0' && color[c] >= 0 && color[c] <= 1,
        "{} {}: expected R,G,B in [0, 1], black or white", source, text);
    begin = end + 1;
  }
  return color;
}

}  // namespace rephoto::splat
