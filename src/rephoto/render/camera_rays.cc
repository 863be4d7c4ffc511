#include "rephoto/render/camera_rays.h"

#include <limits>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "rephoto/core/isa.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/recent_cache.h"

namespace rephoto::render {

CameraRays::CameraRays(const camera::Camera& camera) : camera_(camera) {
  camera_.Validate("camera");
  pinhole_ = camera_.IsPinhole();
  const auto& p = camera_.params;
  if (camera_.model == camera::CameraModel::kSimplePinhole) {
    inv_fx_ = inv_fy_ = static_cast<float>(1.0 / p[0]);
    cx_ = static_cast<float>(p[1]);
    cy_ = static_cast<float>(p[2]);
  } else if (camera_.model == camera::CameraModel::kPinhole) {
    inv_fx_ = static_cast<float>(1.0 / p[0]);
    inv_fy_ = static_cast<float>(1.0 / p[1]);
    cx_ = static_cast<float>(p[2]);
    cy_ = static_cast<float>(p[3]);
  }
  if (pinhole_) return;
  stride_ = static_cast<size_t>(camera_.width) + 1;
  lattice_.resize(stride_ * (static_cast<size_t>(camera_.height) + 1));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  ParallelFor(0, camera_.height + 1, 16, [&](int64_t begin, int64_t end) {
    for (int64_t j = begin; j < end; ++j) {
      for (size_t i = 0; i < stride_; ++i) {
        const auto ray =
            camera_.CamFromImg(Eigen::Vector2d(static_cast<double>(i), static_cast<double>(j)));
        Eigen::Vector2f& out = lattice_[static_cast<size_t>(j) * stride_ + i];
        if (ray && (*ray).z() > 1e-9) {
          out = Eigen::Vector2f(static_cast<float>(ray->x() / ray->z()),
                                static_cast<float>(ray->y() / ray->z()));
        } else {
          out = Eigen::Vector2f(nan, nan);
        }
      }
    }
  });
}

namespace {

#if REPHOTO_HAVE_ISA_TARGETS
// The table's corners (x0, y0, x1, y1) of row `row[i] + dy`, columns `column[i]` and + 1, for
// lanes i and i + 4 in the two 128-bit halves, transposed: lane order 0 1 2 3 | 4 5 6 7.
REPHOTO_TARGET_AVX2 inline void Corners(const float* table, size_t stride, const int* row,
                                        const int* column, size_t dy, __m256* x0, __m256* y0,
                                        __m256* x1, __m256* y1) {
  __m256 q[4];
  for (int i = 0; i < 4; ++i) {
    const float* lo = table + 2 * ((static_cast<size_t>(row[i]) + dy) * stride + column[i]);
    const float* hi = table + 2 * ((static_cast<size_t>(row[i + 4]) + dy) * stride + column[i + 4]);
    q[i] = _mm256_loadu2_m128(hi, lo);
  }
  const __m256 t0 = _mm256_unpacklo_ps(q[0], q[1]), t1 = _mm256_unpackhi_ps(q[0], q[1]);
  const __m256 t2 = _mm256_unpacklo_ps(q[2], q[3]), t3 = _mm256_unpackhi_ps(q[2], q[3]);
  *x0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
  *y0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
  *x1 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
  *y1 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));
}

// CameraRays::Ray for 8 positions: the same floor, clamp and bilinear weights, each product and
// sum one AVX2 instruction in Ray's order (this file is built without contraction). Each
// lane's two corners of a row are adjacent in the table (16 bytes); the 8 lanes' quadruples
// are transposed to (x0, y0, x1, y1) vectors.
REPHOTO_TARGET_AVX2 void TableRays8(const float* table, size_t stride, int width, int height,
                                    const float* px, const float* py, float* xn, float* yn,
                                    int* ok) {
  const __m256 x = _mm256_loadu_ps(px), y = _mm256_loadu_ps(py);
  const __m256i zero = _mm256_setzero_si256();
  const __m256i ix = _mm256_max_epi32(
      zero,
      _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_floor_ps(x)), _mm256_set1_epi32(width - 1)));
  const __m256i iy = _mm256_max_epi32(
      zero,
      _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_floor_ps(y)), _mm256_set1_epi32(height - 1)));
  const __m256 ax = _mm256_sub_ps(x, _mm256_cvtepi32_ps(ix));
  const __m256 ay = _mm256_sub_ps(y, _mm256_cvtepi32_ps(iy));
  alignas(32) int column[8], row[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(column), ix);
  _mm256_store_si256(reinterpret_cast<__m256i*>(row), iy);
  // Lanes i and i + 4 sit in the two halves, so the transposed order is 0 1 2 3 | 4 5 6 7.
  __m256 c0x, c0y, c1x, c1y, c2x, c2y, c3x, c3y;
  Corners(table, stride, row, column, 0, &c0x, &c0y, &c1x, &c1y);
  Corners(table, stride, row, column, 1, &c2x, &c2y, &c3x, &c3y);
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256 bx = _mm256_sub_ps(one, ax), by = _mm256_sub_ps(one, ay);
  // top = (1 - ax) * c[0] + ax * c[1]; bottom likewise; value = (1 - ay) * top + ay * bottom.
  const __m256 top_x = _mm256_add_ps(_mm256_mul_ps(bx, c0x), _mm256_mul_ps(ax, c1x));
  const __m256 top_y = _mm256_add_ps(_mm256_mul_ps(bx, c0y), _mm256_mul_ps(ax, c1y));
  const __m256 bottom_x = _mm256_add_ps(_mm256_mul_ps(bx, c2x), _mm256_mul_ps(ax, c3x));
  const __m256 bottom_y = _mm256_add_ps(_mm256_mul_ps(bx, c2y), _mm256_mul_ps(ax, c3y));
  const __m256 vx = _mm256_add_ps(_mm256_mul_ps(by, top_x), _mm256_mul_ps(ay, bottom_x));
  const __m256 vy = _mm256_add_ps(_mm256_mul_ps(by, top_y), _mm256_mul_ps(ay, bottom_y));
  _mm256_storeu_ps(xn, vx);
  _mm256_storeu_ps(yn, vy);
  // isfinite(vx): the exponent bits are not all set.
  const __m256i exponent = _mm256_set1_epi32(0x7f800000);
  const __m256i finite = _mm256_xor_si256(
      _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_castps_si256(vx), exponent), exponent),
      _mm256_set1_epi32(-1));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(ok), _mm256_srli_epi32(finite, 31));
}
#endif

}  // namespace

void CameraRays::TableRays(int n, const float* px, const float* py, float* xn, float* yn,
                           int* ok) const {
  int i = 0;
#if REPHOTO_HAVE_ISA_TARGETS
  if (core::ActiveIsa() != core::Isa::kBaseline) {
    const float* table = lattice_.data()->data();
    for (; i + 8 <= n; i += 8) {
      TableRays8(table, stride_, camera_.width, camera_.height, px + i, py + i, xn + i, yn + i,
                 ok + i);
    }
  }
#endif
  for (; i < n; ++i) ok[i] = Ray(px[i], py[i], xn + i, yn + i) ? 1 : 0;
}

std::shared_ptr<const CameraRays> SharedCameraRays(const camera::Camera& camera) {
  static RecentCache<camera::Camera, CameraRays> cache(4);
  return cache.Get(camera, [&] { return CameraRays(camera); });
}

}  // namespace rephoto::render
