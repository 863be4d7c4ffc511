#include "rephoto/texture/photo.h"

#include <algorithm>
#include <cmath>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/io/image_io.h"

namespace rephoto::texture {

void Photo::Load(const scene::Scene& scene, const scene::View& view) {
  is8_ = io::ReadImage8(view.image_path, &bytes_, &floats_);
  const int channels = is8_ ? bytes_.channels() : floats_.channels();
  REPHOTO_CHECK(channels >= 1 && channels <= 4 && width() > 0 && height() > 0,
                "{}: unsupported photo ({} channels)", view.image_path.string(), channels);
  camera_ = scene.CameraOf(view);
  if (camera_.width != width() || camera_.height != height()) {
    camera_ = camera_.Scaled(width(), height());
  }
  cam_from_world_ = view.cam_from_world;
}

Eigen::Vector3f Photo::Pixel(int x, int y) const {
  Eigen::Vector3f out;
  if (is8_) {
    const int c = bytes_.channels();
    const uint8_t* p = bytes_.data() + (static_cast<size_t>(y) * bytes_.width() + x) * c;
    for (int k = 0; k < 3; ++k) out[k] = static_cast<float>(p[c >= 3 ? k : 0]) * (1.0f / 255.0f);
  } else {
    const int c = floats_.channels();
    const float* p = floats_.data() + (static_cast<size_t>(y) * floats_.width() + x) * c;
    for (int k = 0; k < 3; ++k) out[k] = p[c >= 3 ? k : 0];
  }
  return out;
}

Eigen::Vector3f Photo::Sample(double px, double py) const {
  const double x = std::clamp(px - 0.5, 0.0, width() - 1.0);
  const double y = std::clamp(py - 0.5, 0.0, height() - 1.0);
  const int x0 = std::min(static_cast<int>(x), width() - 1);
  const int y0 = std::min(static_cast<int>(y), height() - 1);
  const int x1 = std::min(x0 + 1, width() - 1), y1 = std::min(y0 + 1, height() - 1);
  const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
  const Eigen::Vector3f top = (1 - ax) * Pixel(x0, y0) + ax * Pixel(x1, y0);
  const Eigen::Vector3f bottom = (1 - ax) * Pixel(x0, y1) + ax * Pixel(x1, y1);
  return (1 - ay) * top + ay * bottom;
}

void GradientMagnitude(const Photo& photo, Image* out) {
  const int w = photo.width(), h = photo.height();
  if (out->width() != w || out->height() != h || out->channels() != 1) *out = Image(w, h, 1);
  // Luma rows are computed on the fly: each band keeps a ring of three rows.
  ParallelFor(0, h, 64, [&](int64_t begin, int64_t end) {
    std::vector<float> rows[3];
    for (auto& r : rows) r.resize(w);
    auto luma_row = [&](int y, std::vector<float>& row) {
      y = std::clamp(y, 0, h - 1);
      for (int x = 0; x < w; ++x) {
        const Eigen::Vector3f c = photo.Pixel(x, y);
        row[x] = 0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2];
      }
    };
    luma_row(static_cast<int>(begin) - 1, rows[0]);
    luma_row(static_cast<int>(begin), rows[1]);
    for (int64_t y = begin; y < end; ++y) {
      luma_row(static_cast<int>(y) + 1, rows[2]);
      const float* a = rows[0].data();
      const float* b = rows[1].data();
      const float* c = rows[2].data();
      float* o = out->row(static_cast<int>(y));
      for (int x = 0; x < w; ++x) {
        const int l = std::max(x - 1, 0), r = std::min(x + 1, w - 1);
        const float gx = (a[r] - a[l]) + 2 * (b[r] - b[l]) + (c[r] - c[l]);
        const float gy = (c[l] - a[l]) + 2 * (c[x] - a[x]) + (c[r] - a[r]);
        o[x] = std::sqrt(gx * gx + gy * gy) * 0.125f;
      }
      std::swap(rows[0], rows[1]);
      std::swap(rows[1], rows[2]);
    }
  });
}

}  // namespace rephoto::texture
