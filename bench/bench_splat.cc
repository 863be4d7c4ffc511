// Gaussian splatting rasterizer speed (rephoto/splat/rasterize.h): a synthetic SH-degree-3 model
// of N Gaussians (flattened Gaussians covering a bumpy sphere, 60 %, and a surrounding shell
// that fills the rest of the frame, 40 %, spaced so that neighbours overlap as in a trained
// model) rendered at W x H, with milliseconds per stage (project, sort, blend).
//
// Run: build/bench/rephoto_bench_splat --benchmark_counters_tabular=true
// Arguments: N in thousands / image width (height = width * 9 / 16).
// Counters: project_ms, sort_ms, blend_ms (mean per frame), visible (Gaussians after culling),
// tile_entries (Gaussian-tile pairs), peak_rss_mb (process peak resident memory so far, which
// includes the model: model_mb), cpu_ms_per_frame (all threads), render_hash (32-bit FNV-1a of
// the colour and depth bytes: the same on every ISA path and before/after a speed change).
// Threads: all cores (TBB default); REPHOTO_BENCH_THREADS=N limits them.
// Your own model: REPHOTO_BENCH_SPLAT=point_cloud.ply and REPHOTO_BENCH_SCENE=scene (e.g. the
// 3DGS output folder with cameras.json) run BM_RenderSplatFile at view REPHOTO_BENCH_VIEW (0).
#include <benchmark/benchmark.h>
#include <sys/resource.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <random>

#include "bench_cpu.h"
#include "rephoto/core/parallel.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"

namespace {

using rephoto::bench::BenchPose;

using rephoto::camera::Camera;
using rephoto::camera::CameraModel;
using rephoto::camera::Pose;
using rephoto::splat::GaussianModel;

GaussianModel MakeModel(size_t n) {
  GaussianModel model;
  model.sh_degree = 3;
  model.positions.resize(n);
  model.scales.resize(n);
  model.rotations.resize(n);
  model.opacities.resize(n);
  model.sh.resize(n * 16 * 3);
  const size_t on_sphere = n * 6 / 10;
  const double pi = 3.14159265358979323846;
  // Mean spacing of the Gaussians on each surface (area / count).
  const double sphere_spacing = std::sqrt(4 * pi / static_cast<double>(on_sphere));
  const double shell_spacing = std::sqrt(4 * pi * 36 / static_cast<double>(n - on_sphere));
  rephoto::ParallelFor(0, static_cast<int64_t>(n), 65536, [&](int64_t b, int64_t e) {
    std::mt19937 rng(static_cast<uint32_t>(b));
    std::uniform_real_distribution<float> uniform(0, 1);
    std::normal_distribution<float> normal(0, 1);
    for (int64_t g = b; g < e; ++g) {
      const bool sphere = static_cast<size_t>(g) < on_sphere;
      const double z = 2 * uniform(rng) - 1, phi = 2 * pi * uniform(rng);
      const double r = std::sqrt(1 - z * z);
      Eigen::Vector3d dir(r * std::cos(phi), r * std::sin(phi), z);
      const double bump = 1.0 + 0.03 * std::sin(17 * std::acos(z)) * std::cos(23 * phi);
      model.positions[g] = (dir * (sphere ? bump : 6.0)).cast<float>();
      const double spacing = sphere ? sphere_spacing : shell_spacing;
      model.scales[g] = Eigen::Vector3f(spacing * (0.4 + 0.8 * uniform(rng)),
                                        spacing * (0.4 + 0.8 * uniform(rng)), spacing * 0.1);
      model.rotations[g] =
          Eigen::Vector4f(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
      model.opacities[g] = 1.0f / (1.0f + std::exp(-(7 * uniform(rng) - 2)));
      float* sh = model.sh.data() + g * 48;
      for (int c = 0; c < 3; ++c) sh[c] = normal(rng);
      for (int k = 3; k < 48; ++k) sh[k] = 0.2f * normal(rng);
    }
  });
  return model;
}

const GaussianModel& Model(size_t n) {
  static std::map<size_t, std::unique_ptr<GaussianModel>> models;
  auto& model = models[n];
  if (!model) model = std::make_unique<GaussianModel>(MakeModel(n));
  return *model;
}

Camera BenchCamera(int width) {
  Camera camera;
  camera.model = CameraModel::kPinhole;
  camera.width = width;
  camera.height = width * 9 / 16;
  const double f = 1400.0 * width / 1920.0;
  camera.params = {f, f, width / 2.0, camera.height / 2.0};
  return camera;
}

double RenderHash(const rephoto::splat::GaussianRendering& out) {
  uint32_t hash = 2166136261u;
  auto add = [&](const float* data, size_t count) {
    const auto* bytes = reinterpret_cast<const unsigned char*>(data);
    for (size_t i = 0; i < count * sizeof(float); ++i) hash = (hash ^ bytes[i]) * 16777619u;
  };
  add(out.color.data(), out.color.pixel_count() * 4);
  add(out.depth.data(), out.depth.pixel_count());
  return static_cast<double>(hash);
}

double PeakRssMb() {
  struct rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // kB on Linux
}

void Render(benchmark::State& state, const GaussianModel& model, const Camera& camera,
            const Pose& pose) {
  std::unique_ptr<rephoto::ThreadLimit> limit;
  if (const char* threads = std::getenv("REPHOTO_BENCH_THREADS")) {
    limit = std::make_unique<rephoto::ThreadLimit>(std::atoi(threads));
  }
  rephoto::splat::GaussianRendering out;
  rephoto::splat::GaussianRenderStats stats, sum;
  rephoto::splat::RenderGaussians(model, camera, pose, {}, &out, &stats);  // warm buffers
  {
    rephoto::bench::CpuCounter cpu(state, "cpu_ms_per_frame");
    for (auto _ : state) {
      rephoto::splat::RenderGaussians(model, camera, pose, {}, &out, &stats);
      sum.project_ms += stats.project_ms;
      sum.sort_ms += stats.sort_ms;
      sum.blend_ms += stats.blend_ms;
      benchmark::DoNotOptimize(out.color.data());
    }
  }
  const double iterations = static_cast<double>(state.iterations());
  state.counters["project_ms"] = sum.project_ms / iterations;
  state.counters["sort_ms"] = sum.sort_ms / iterations;
  state.counters["blend_ms"] = sum.blend_ms / iterations;
  state.counters["visible"] = static_cast<double>(stats.visible);
  state.counters["tile_entries"] = static_cast<double>(stats.tile_entries);
  state.counters["model_mb"] =
      (model.size() * (3 + 3 + 4 + 1) * 4.0 + model.sh.size() * 4.0) / (1024 * 1024);
  state.counters["peak_rss_mb"] = PeakRssMb();
  double coverage = 0;
  for (size_t i = 0; i < out.color.pixel_count(); ++i) coverage += out.color.data()[4 * i + 3];
  state.counters["coverage"] = coverage / static_cast<double>(out.color.pixel_count());
  state.counters["render_hash"] = RenderHash(out);
}

void BM_RenderSplat(benchmark::State& state) {
  Render(state, Model(static_cast<size_t>(state.range(0)) * 1000),
         BenchCamera(static_cast<int>(state.range(1))), BenchPose());
}
BENCHMARK(BM_RenderSplat)
    ->Args({100, 1920})
    ->Args({1000, 1920})
    ->Args({3000, 1920})
    ->Args({1000, 1280})
    ->Args({1000, 3840})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(2.0)
    ->UseRealTime();

void BM_RenderSplatFile(benchmark::State& state) {
  const char* model_path = std::getenv("REPHOTO_BENCH_SPLAT");
  const char* scene_path = std::getenv("REPHOTO_BENCH_SCENE");
  if (model_path == nullptr || scene_path == nullptr) {
    state.SkipWithError("set REPHOTO_BENCH_SPLAT and REPHOTO_BENCH_SCENE");
    return;
  }
  static const GaussianModel model = rephoto::splat::ReadGaussians(model_path);
  rephoto::scene::ReadSceneOptions options;
  options.check_image_sizes = false;
  static const rephoto::scene::Scene scene = rephoto::scene::ReadScene(scene_path, options);
  const char* view_env = std::getenv("REPHOTO_BENCH_VIEW");
  const size_t view = view_env ? static_cast<size_t>(std::atoi(view_env)) : 0;
  if (view >= scene.views.size()) {
    state.SkipWithError("REPHOTO_BENCH_VIEW out of range");
    return;
  }
  Render(state, model, scene.CameraOf(scene.views[view]), scene.views[view].cam_from_world);
}
BENCHMARK(BM_RenderSplatFile)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
