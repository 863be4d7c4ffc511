#include "rephoto/synth/demo_scene.h"

#include <cmath>
#include <numbers>

#include "rephoto/core/parallel.h"
#include "rephoto/degrade/simplex_noise.h"

namespace rephoto::synth {

using degrade::SimplexNoise;
using degrade::SplitMix64;
using degrade::UniformDouble;

namespace {

constexpr float kGroundHalfSize = 2.f;
constexpr float kObjectRadius = 0.5f;
const Eigen::Vector3f kObjectCentre(0.f, 0.f, 0.5f);

float Saturate(float v) { return std::min(1.f, std::max(0.f, v)); }

// Low-frequency bumps of the object: radius factor for a unit direction.
float ObjectRadiusFactor(const Eigen::Vector3f& direction, const SimplexNoise& noise) {
  return 1.f + 0.12f * noise.Noise(direction * 1.7f) + 0.05f * noise.Noise(direction * 4.5f + Eigen::Vector3f(9, 9, 9));
}

}  // namespace

Eigen::Vector3f DemoAlbedo(const Eigen::Vector3f& p, uint64_t seed) {
  // Thread-safe: SimplexNoise is immutable after construction; cache per seed per thread.
  thread_local uint64_t cached_seed = ~seed;
  thread_local SimplexNoise noise(0), detail(0);
  if (cached_seed != seed) {
    noise = SimplexNoise(seed * 2 + 11);
    detail = SimplexNoise(seed * 2 + 12);
    cached_seed = seed;
  }
  const float n1 = noise.Noise(p * 3.f);
  const float n2 = detail.Noise(p * 17.f);
  const float n3 = detail.Noise(p * 61.f + Eigen::Vector3f(5, 1, 3));
  if (p.z() < 0.02f && (p - kObjectCentre).norm() > kObjectRadius * 1.05f) {
    // Ground: 0.25 m stone tiles with grout lines, tinted by noise.
    const float u = p.x() / 0.25f, v = p.y() / 0.25f;
    const float fu = u - std::floor(u), fv = v - std::floor(v);
    const bool grout = fu < 0.04f || fv < 0.04f;
    const bool dark = (static_cast<int>(std::floor(u)) + static_cast<int>(std::floor(v))) & 1;
    Eigen::Vector3f c = dark ? Eigen::Vector3f(0.45f, 0.38f, 0.30f)
                             : Eigen::Vector3f(0.70f, 0.64f, 0.52f);
    c += Eigen::Vector3f(0.10f, 0.08f, 0.05f) * n1 + Eigen::Vector3f(0.08f, 0.08f, 0.08f) * n2 +
         Eigen::Vector3f(0.05f, 0.05f, 0.05f) * n3;
    if (grout) c = Eigen::Vector3f(0.2f, 0.2f, 0.22f) + 0.05f * Eigen::Vector3f::Constant(n3);
    return c.unaryExpr([](float v) { return Saturate(v); });
  }
  // Object: painted stripes around the vertical axis with spots and fine grain.
  const float angle = std::atan2(p.y(), p.x());
  const float stripes = 0.5f + 0.5f * std::sin(angle * 9.f + p.z() * 14.f);
  Eigen::Vector3f c = Eigen::Vector3f(0.75f, 0.22f, 0.15f) * stripes +
                      Eigen::Vector3f(0.15f, 0.35f, 0.70f) * (1.f - stripes);
  if (n1 > 0.45f) c = Eigen::Vector3f(0.92f, 0.85f, 0.35f);  // yellow spots
  c += Eigen::Vector3f(0.07f, 0.07f, 0.07f) * n2 + Eigen::Vector3f(0.05f, 0.05f, 0.05f) * n3;
  return c.unaryExpr([](float v) { return Saturate(v); });
}

mesh::Mesh MakeDemoMesh(const DemoSceneOptions& options) {
  mesh::Mesh m;
  const int g = options.ground_cells;
  const int bands = options.object_bands;
  const int segments = 2 * bands;
  const size_t ground_vertices = static_cast<size_t>(g + 1) * (g + 1);
  const size_t object_vertices = static_cast<size_t>(bands - 1) * segments + 2;
  m.positions.resize(ground_vertices + object_vertices);
  m.colors.resize(m.positions.size());

  // Ground grid.
  for (int y = 0; y <= g; ++y) {
    for (int x = 0; x <= g; ++x) {
      m.positions[static_cast<size_t>(y) * (g + 1) + x] =
          Eigen::Vector3f(-kGroundHalfSize + 2 * kGroundHalfSize * x / g,
                          -kGroundHalfSize + 2 * kGroundHalfSize * y / g, 0.f);
    }
  }
  for (int y = 0; y < g; ++y) {
    for (int x = 0; x < g; ++x) {
      const uint32_t a = static_cast<uint32_t>(y * (g + 1) + x), b = a + 1,
                     c = a + static_cast<uint32_t>(g + 1), d = c + 1;
      m.faces.push_back({a, b, d});  // counter-clockwise seen from above (+z)
      m.faces.push_back({a, d, c});
    }
  }

  // Object: a UV sphere with bumps. Vertex 0 of the object is the south pole, the last the
  // north pole, rings in between from south to north.
  const SimplexNoise shape(options.seed * 2 + 7);
  const uint32_t base = static_cast<uint32_t>(ground_vertices);
  auto place = [&](const Eigen::Vector3f& direction) {
    return kObjectCentre + kObjectRadius * ObjectRadiusFactor(direction, shape) * direction;
  };
  m.positions[base] = place(Eigen::Vector3f(0, 0, -1));
  for (int band = 1; band < bands; ++band) {
    const float theta = std::numbers::pi_v<float> * band / bands;  // from the south pole
    for (int s = 0; s < segments; ++s) {
      const float phi = 2 * std::numbers::pi_v<float> * s / segments;
      const Eigen::Vector3f direction(std::sin(theta) * std::cos(phi),
                                      std::sin(theta) * std::sin(phi), -std::cos(theta));
      m.positions[base + 1 + static_cast<size_t>(band - 1) * segments + s] = place(direction);
    }
  }
  const uint32_t north = base + static_cast<uint32_t>(object_vertices) - 1;
  m.positions[north] = place(Eigen::Vector3f(0, 0, 1));
  auto ring = [&](int band, int s) {
    return base + 1 + static_cast<uint32_t>((band - 1) * segments + (s % segments));
  };
  for (int s = 0; s < segments; ++s) {
    m.faces.push_back({base, ring(1, s + 1), ring(1, s)});  // outward normals
    m.faces.push_back({north, ring(bands - 1, s), ring(bands - 1, s + 1)});
  }
  for (int band = 1; band + 1 < bands; ++band) {
    for (int s = 0; s < segments; ++s) {
      const uint32_t a = ring(band, s), b = ring(band, s + 1), c = ring(band + 1, s),
                     d = ring(band + 1, s + 1);
      m.faces.push_back({a, b, d});
      m.faces.push_back({a, d, c});
    }
  }

  ParallelFor(0, static_cast<int64_t>(m.positions.size()), 8192, [&](int64_t b, int64_t e) {
    for (int64_t v = b; v < e; ++v) m.colors[v] = DemoAlbedo(m.positions[v], options.seed);
  });
  m.normals = mesh::ComputeVertexNormals(m);
  return m;
}

scene::Scene MakeDemoScene(const DemoSceneOptions& options,
                           const std::filesystem::path& image_root) {
  scene::Scene scene;
  camera::Camera cam;
  cam.model = camera::CameraModel::kOpenCv;
  cam.width = options.image_width;
  cam.height = options.image_height;
  const double f = options.image_width;
  cam.params = {f, f, 0.5 * options.image_width + 3.25, 0.5 * options.image_height - 2.5,
                -0.05, 0.01, 0.0, 0.0};
  scene.cameras[1] = cam;
  scene.image_root = image_root;

  uint64_t state = options.seed;
  for (int i = 0; i < options.camera_count; ++i) {
    const double angle = 2 * std::numbers::pi * i / options.camera_count +
                         0.05 * (UniformDouble(state) - 0.5);
    const double height = 1.5 + 0.3 * (UniformDouble(state) - 0.5);
    const Eigen::Vector3d centre(3.2 * std::cos(angle), 3.2 * std::sin(angle), height);
    const Eigen::Vector3d target(0.1 * (UniformDouble(state) - 0.5),
                                 0.1 * (UniformDouble(state) - 0.5), 0.45);
    const Eigen::Vector3d forward = (target - centre).normalized();
    const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
    const Eigen::Vector3d down = forward.cross(right);
    scene::View view;
    view.name = "view_" + std::string(i < 10 ? "00" : (i < 100 ? "0" : "")) + std::to_string(i) + ".png";
    view.image_path = image_root / view.name;
    view.camera_id = 1;
    view.cam_from_world.rotation.row(0) = right.transpose();
    view.cam_from_world.rotation.row(1) = down.transpose();
    view.cam_from_world.rotation.row(2) = forward.transpose();
    view.cam_from_world.translation = -view.cam_from_world.rotation * centre;
    scene.views.push_back(view);
  }
  return scene;
}

Image SimulatePhoto(const Image& rendering, double gain, double noise_sigma, uint64_t seed) {
  Image photo(rendering.width(), rendering.height(), 3);
  const int in_channels = rendering.channels();
  ParallelFor(0, rendering.height(), 8, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      uint64_t state = seed ^ (0x9E3779B97F4A7C15ULL * static_cast<uint64_t>(y + 1));
      const float* in = rendering.row(static_cast<int>(y));
      float* out = photo.row(static_cast<int>(y));
      for (int x = 0; x < rendering.width(); ++x) {
        for (int c = 0; c < 3; ++c) {
          // Box-Muller from two portable uniforms.
          const double u1 = std::max(UniformDouble(state), 1e-300), u2 = UniformDouble(state);
          const double gauss = std::sqrt(-2 * std::log(u1)) * std::cos(2 * std::numbers::pi * u2);
          const double v = gain * in[x * in_channels + std::min(c, in_channels - 1)] +
                           noise_sigma * gauss;
          out[x * 3 + c] =
              static_cast<float>(std::round(std::clamp(v, 0.0, 1.0) * 255.0) / 255.0);
        }
      }
    }
  });
  return photo;
}

}  // namespace rephoto::synth
