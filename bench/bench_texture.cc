// rephoto texture (texture/texture_mesh.h) on issue 22's size: a ~500k-face mesh (the demo
// scene's ground-truth mesh at ground_cells 420, object_bands 200: 512k faces) from photos of
// 4000x3000 (12 MP, rendered with one sample per pixel, JPEG quality 90) on the demo's camera ring,
// and, as the peer measured in the same run, render::ColorizeMesh (vertex colours) of the same mesh
// from the same photos. Per-stage seconds come from TextureReport (counters in seconds). Photos are
// rendered once and cached in $TMPDIR/rephoto_bench_texture_<views> (reused by later runs; delete
// to rebuild).
//   build/bench/rephoto_bench_texture --benchmark_filter='/10/'   (10 photos)
//   build/bench/rephoto_bench_texture --benchmark_filter='/50/'   (issue 22: 50 photos)
#include <benchmark/benchmark.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <random>

#include "bench_cpu.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_encode.h"
#include "rephoto/render/colorize.h"
#include "rephoto/render/render.h"
#include "rephoto/synth/demo_scene.h"
#include "rephoto/texture/mrf.h"
#include "rephoto/texture/texture_mesh.h"

namespace rephoto {
namespace {

struct Data {
  mesh::Mesh mesh;
  scene::Scene scene;
  std::vector<size_t> views;
};

synth::DemoSceneOptions Options(int views) {
  synth::DemoSceneOptions options;
  options.image_width = 4000;
  options.image_height = 3000;
  options.camera_count = views;
  options.ground_cells = 420;
  options.object_bands = 200;
  return options;
}

const Data& GetData(int view_count) {
  static std::map<int, Data> cache;
  auto found = cache.find(view_count);
  if (found != cache.end()) return found->second;
  Data& data = cache[view_count];
  const synth::DemoSceneOptions options = Options(view_count);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("rephoto_bench_texture_" + std::to_string(view_count));
  data.mesh = synth::MakeDemoMesh(options);
  data.scene = synth::MakeDemoScene(options, dir);
  std::unique_ptr<render::RenderModel> model;
  for (size_t i = 0; i < data.scene.views.size(); ++i) {
    const scene::View& view = data.scene.views[i];
    data.views.push_back(i);
    std::filesystem::path jpeg = view.image_path;
    jpeg.replace_extension(".jpg");
    data.scene.views[i].image_path = jpeg;
    if (std::filesystem::exists(jpeg)) continue;
    if (!model) model = std::make_unique<render::RenderModel>(data.mesh);
    render::RenderOptions one_sample;
    one_sample.samples_per_pixel = 1;
    const render::Rephoto r =
        render::RenderRephoto(*model, data.scene.CameraOf(view), view.cam_from_world, one_sample);
    const Image photo = synth::SimulatePhoto(r.color, 1.0, 0.01, 100 + i);
    std::vector<uint8_t> bytes(photo.size());
    for (size_t k = 0; k < bytes.size(); ++k) {
      bytes[k] = static_cast<uint8_t>(std::lround(photo.data()[k] * 255.0f));
    }
    const std::vector<uint8_t> encoded =
        io::EncodeJpegToMemory(bytes, photo.width(), photo.height(), 3, 90);
    WriteFileAtomically(jpeg, [&](const std::filesystem::path& temporary) {
      std::FILE* file = std::fopen(temporary.c_str(), "wb");
      std::fwrite(encoded.data(), 1, encoded.size(), file);
      std::fclose(file);
    });
  }
  return data;
}

void BM_TextureMesh(benchmark::State& state) {
  const Data& data = GetData(static_cast<int>(state.range(0)));
  texture::TextureReport report;
  {
    bench::CpuCounter cpu(state);
    for (auto _ : state) {
      report = texture::TextureMesh(data.mesh, data.scene, data.views).report;
    }
  }
  state.counters["faces"] = static_cast<double>(report.faces);
  state.counters["visibility_s"] = report.seconds_visibility;
  state.counters["consistency_s"] = report.seconds_consistency;
  state.counters["selection_s"] = report.seconds_selection;
  state.counters["leveling_s"] = report.seconds_leveling;
  state.counters["atlas_s"] = report.seconds_atlas;
  state.counters["total_s"] = report.seconds_total;
  state.counters["atlas_mtexels"] = static_cast<double>(report.atlas_texels) * 1e-6;
  state.counters["textured_faces"] = static_cast<double>(report.textured_faces);
}
BENCHMARK(BM_TextureMesh)
    ->Arg(10)
    ->Arg(50)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(1);

void BM_ColorizeMeshPeer(benchmark::State& state) {
  const Data& data = GetData(static_cast<int>(state.range(0)));
  bench::CpuCounter cpu(state);
  for (auto _ : state) {
    benchmark::DoNotOptimize(render::ColorizeMesh(data.mesh, data.scene, data.views));
  }
}
BENCHMARK(BM_ColorizeMeshPeer)
    ->Arg(10)
    ->Arg(50)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(1);

// The view-selection MRF alone: a 724 x 724 grid of nodes (~524k, like the faces above) with
// 4-neighbour edges, `range(0)` labels, each node a candidate of a random half of them (at
// least one) with costs from smooth random fields (so that regions prefer one label).
void BM_SolvePottsGrid(benchmark::State& state) {
  const int side = 724, labels = static_cast<int>(state.range(0));
  texture::PottsProblem problem;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> uniform(0, 1);
  std::vector<Eigen::Vector2f> centres(labels);
  for (auto& c : centres) c = Eigen::Vector2f(uniform(rng), uniform(rng)) * side;
  for (int y = 0; y < side; ++y) {
    for (int x = 0; x < side; ++x) {
      const size_t start = problem.labels.size();
      for (int l = 0; l < labels; ++l) {
        const float d = (centres[l] - Eigen::Vector2f(x, y)).norm() / side;
        if (d < 0.5f || (problem.labels.size() == start && l == labels - 1)) {
          problem.labels.push_back(l);
          problem.costs.push_back(std::min(1.0f, d + 0.3f * uniform(rng)));
        }
      }
      problem.offsets.push_back(static_cast<uint32_t>(problem.labels.size()));
      const uint32_t i = static_cast<uint32_t>(y * side + x);
      if (x > 0) problem.edges.emplace_back(i - 1, i);
      if (y > 0) problem.edges.emplace_back(i - side, i);
    }
  }
  texture::PottsResult result;
  for (auto _ : state) result = texture::SolvePotts(problem);
  state.counters["nodes"] = static_cast<double>(problem.node_count());
  state.counters["candidates"] = static_cast<double>(problem.labels.size());
  state.counters["moves"] = static_cast<double>(result.moves);
  state.counters["cycles"] = result.cycles;
}
BENCHMARK(BM_SolvePottsGrid)->Arg(10)->Arg(50)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace rephoto

BENCHMARK_MAIN();
