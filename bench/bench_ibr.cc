// Image-based rendering speed (rephoto/ibr): view-dependent texturing and image-based rendering
// of a 1920x1080 novel view from 20 training photos of the procedural demo scene (OPENCV
// cameras with distortion; photos are the ground truth rendered with one sample per pixel,
// written as PNG once per run), and plane-sweep depth for one 1000-pixel-wide view against 4
// neighbours (96 planes, 7x7 NCC, the default PlaneSweepOptions).
// Construction (photo decoding, proxy depth maps) is not timed; IBR uses ground-truth depth
// maps at the photos' resolution (its render cost does not depend on where depth came from).
//
// Run: build-*/bench/rephoto_bench_ibr --benchmark_repetitions=5
//        --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>
#include <memory>

#include "bench_cpu.h"
#include "rephoto/ibr/depth_map_io.h"
#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/ibr/plane_sweep.h"
#include "rephoto/io/image_io.h"
#include "rephoto/render/render.h"
#include "rephoto/synth/demo_scene.h"

namespace {

namespace fs = std::filesystem;
using namespace rephoto;

struct Fixture {
  synth::DemoSceneOptions options;
  mesh::Mesh mesh;
  scene::Scene scene;
  fs::path folder;
  std::vector<ibr::TrainingView> training;  // views 1..20; view 0 is the novel view
  std::unique_ptr<ibr::ImageBasedRenderer> vdt, ibr;

  Fixture() {
    options.image_width = 1920;
    options.image_height = 1080;
    options.camera_count = 21;
    folder = fs::temp_directory_path() / ("rephoto-bench-ibr-" + std::to_string(::getpid()));
    fs::create_directories(folder);
    mesh = synth::MakeDemoMesh(options);
    scene = synth::MakeDemoScene(options, folder);
    const render::RenderModel model(mesh);
    render::RenderOptions render_options;
    render_options.samples_per_pixel = 1;
    for (size_t i = 0; i < scene.views.size(); ++i) {
      const scene::View& view = scene.views[i];
      const render::Rephoto r =
          render::RenderRephoto(model, scene.CameraOf(view), view.cam_from_world, render_options);
      if (i == 0) continue;
      io::WritePng(view.image_path, r.color);
      const fs::path depth = folder / (view.name + ".bin");
      ibr::WriteColmapDepthMap(depth, r.depth);
      training.push_back(
          {view.name, scene.CameraOf(view), view.cam_from_world, view.image_path, depth});
    }
  }
  ~Fixture() {
    std::error_code ec;
    fs::remove_all(folder, ec);
  }
};

using rephoto::bench::CpuCounter;

Fixture& GetFixture() {
  static Fixture fixture;
  return fixture;
}

void BM_VdtRender1080p20Views(benchmark::State& state) {
  Fixture& f = GetFixture();
  if (!f.vdt) {
    std::vector<ibr::TrainingView> training = f.training;
    for (auto& t : training) t.depth_map.clear();
    f.vdt = std::make_unique<ibr::ImageBasedRenderer>(
        ibr::ImageBasedRenderer::Vdt(f.mesh, training, {}));
  }
  const scene::View& view = f.scene.views[0];
  render::Rephoto out;
  CpuCounter cpu(state);
  for (auto _ : state) {
    f.vdt->Render(f.scene.CameraOf(view), view.cam_from_world, &out);
    benchmark::DoNotOptimize(out.color.data());
  }
}
BENCHMARK(BM_VdtRender1080p20Views)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_IbrRender1080p20Views(benchmark::State& state) {
  Fixture& f = GetFixture();
  if (!f.ibr) {
    f.ibr = std::make_unique<ibr::ImageBasedRenderer>(ibr::ImageBasedRenderer::Ibr(f.training, {}));
  }
  const scene::View& view = f.scene.views[0];
  render::Rephoto out;
  CpuCounter cpu(state);
  for (auto _ : state) {
    f.ibr->Render(f.scene.CameraOf(view), view.cam_from_world, &out);
    benchmark::DoNotOptimize(out.color.data());
  }
}
BENCHMARK(BM_IbrRender1080p20Views)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PlaneSweep1000px4Neighbours(benchmark::State& state) {
  Fixture& f = GetFixture();
  static std::vector<Image> photos;
  if (photos.empty()) {
    for (int i = 1; i <= 5; ++i) photos.push_back(io::ReadImage(f.scene.views[i].image_path));
  }
  ibr::PlaneSweepOptions options;  // max_width 1000: the 1920 photos are reduced to 1000x563
  options.min_depth = 1.5;
  options.max_depth = 8;
  const camera::Camera camera = f.scene.cameras.at(1);
  const ibr::PlaneSweepView reference{camera, f.scene.views[3].cam_from_world, &photos[2]};
  std::vector<ibr::PlaneSweepView> neighbors;
  for (int i : {0, 1, 3, 4}) {
    neighbors.push_back({camera, f.scene.views[i + 1].cam_from_world, &photos[i]});
  }
  CpuCounter cpu(state);
  for (auto _ : state) {
    const ibr::PlaneSweepResult r = ibr::ComputePlaneSweepDepth(reference, neighbors, options);
    benchmark::DoNotOptimize(r.depth.data());
  }
}
BENCHMARK(BM_PlaneSweep1000px4Neighbours)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
