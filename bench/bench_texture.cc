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

#include "bench_cpu.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_encode.h"
#include "rephoto/render/colorize.h"
#include "rephoto/render/render.h"
#include "rephoto/synth/demo_scene.h"
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

}  // namespace
}  // namespace rephoto

BENCHMARK_MAIN();
