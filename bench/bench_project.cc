// Error projection speed (project/project.h) on the demo-size model: the procedural demo mesh
// at its default density (~860k triangles, ~430k vertices: ground 500 x 500 cells + object 300
// bands), 24 views at 640 x 480 with random error images (10 % NaN), as `rephoto evaluate` or
// `rephoto project` run it after a demo-size evaluation; and 16 views at 1280 x 960, the demo's
// own photos (more faces span 4 pixels there and are sampled inside).
//   BM_ProjectPrebuiltModel/<faces>/<short side>: ProjectErrors with the render model built
//     beforehand (the BVH the evaluation rendered with): depth maps + reading EXRs + projection,
//     per 24 (480) or 16 (960) views; faces 0 = vertices only.
//   BM_ProjectFromMesh: the Mesh overload (builds the geometry-only BVH itself), as the CLI.
//   BM_WriteProjectedPly: writing the binary PLY.
// Counters: render_s / project_s = the ProjectResult timings per iteration; cpu_s = process CPU.
//
// Run: build-*/bench/rephoto_bench_project --benchmark_repetitions=3
//        --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <vector>

#include "rephoto/core/process.h"
#include "rephoto/io/image_io.h"
#include "rephoto/project/project.h"
#include "rephoto/render/render_model.h"
#include "rephoto/synth/demo_scene.h"

namespace {

namespace fs = std::filesystem;
using rephoto::project::ProjectView;

using rephoto::ProcessCpuSeconds;

struct Fixture {
  rephoto::mesh::Mesh mesh;
  std::vector<ProjectView> views;
  fs::path dir;

  Fixture(int short_side, int camera_count) {
    rephoto::synth::DemoSceneOptions options;  // default mesh density
    options.image_width = short_side * 4 / 3;
    options.image_height = short_side;
    options.camera_count = camera_count;
    mesh = rephoto::synth::MakeDemoMesh(options);
    const rephoto::scene::Scene scene = rephoto::synth::MakeDemoScene(options, "images");
    dir = fs::temp_directory_path() / ("rephoto_bench_project_" + std::to_string(::getpid()) + "_" +
                                       std::to_string(short_side));
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> value(0.0f, 1.0f);
    for (const rephoto::scene::View& view : scene.views) {
      const rephoto::camera::Camera& camera = scene.CameraOf(view);
      rephoto::Image error(camera.width, camera.height, 1);
      for (size_t k = 0; k < error.size(); ++k) {
        const float v = value(rng);
        error.data()[k] = v < 0.1f ? std::nanf("") : v;
      }
      const fs::path path = dir / (view.name + ".1-ncc.exr");
      rephoto::io::WriteExr(path, error);
      views.push_back({camera, view.cam_from_world, path, view.name});
    }
  }
  ~Fixture() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

Fixture& GetFixture(int short_side = 480) {
  if (short_side == 960) {
    static Fixture large(960, 16);
    return large;
  }
  static Fixture fixture(480, 24);
  return fixture;
}

// Arguments: 1 with per-face errors (the default), 0 vertices only; the short side (480, 960).
void BM_ProjectPrebuiltModel(benchmark::State& state) {
  Fixture& f = GetFixture(static_cast<int>(state.range(1)));
  rephoto::project::ProjectOptions options;
  options.face_errors = state.range(0) != 0;
  rephoto::render::ModelOptions model_options;
  model_options.load_textures = false;
  const rephoto::render::RenderModel model(f.mesh, model_options);
  double render = 0, project = 0;
  const double cpu0 = ProcessCpuSeconds();
  size_t seen = 0;
  for (auto _ : state) {
    const rephoto::project::ProjectResult result =
        rephoto::project::ProjectErrors(model, f.views, options);
    render += result.render_seconds;
    project += result.project_seconds;
    seen = result.seen_vertices;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["render_s"] = render / n;
  state.counters["project_s"] = project / n;
  state.counters["cpu_s"] = (ProcessCpuSeconds() - cpu0) / n;
  state.counters["vertices"] = static_cast<double>(f.mesh.vertex_count());
  state.counters["triangles"] = static_cast<double>(f.mesh.face_count());
  state.counters["seen"] = static_cast<double>(seen);
}
BENCHMARK(BM_ProjectPrebuiltModel)
    ->Args({1, 480})
    ->Args({0, 480})
    ->Args({1, 960})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(2);

void BM_ProjectFromMesh(benchmark::State& state) {
  Fixture& f = GetFixture();
  const double cpu0 = ProcessCpuSeconds();
  for (auto _ : state) {
    benchmark::DoNotOptimize(rephoto::project::ProjectErrors(f.mesh, f.views, {}));
  }
  state.counters["cpu_s"] = (ProcessCpuSeconds() - cpu0) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_ProjectFromMesh)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);

void BM_WriteProjectedPly(benchmark::State& state) {
  Fixture& f = GetFixture();
  const rephoto::project::ProjectResult result =
      rephoto::project::ProjectErrors(f.mesh, f.views, {});
  for (auto _ : state) {
    rephoto::project::WriteProjectedPly(f.mesh, result, f.dir / "projected.ply");
  }
}
BENCHMARK(BM_WriteProjectedPly)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
