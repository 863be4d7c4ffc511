// Image I/O costs that dominate `rephoto compare` on large photos: decoding a photo, writing a
// float error image (EXR) and a jet-coloured RGBA PNG per metric.
//   build-*/bench/rephoto_bench_io [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "rephoto/core/image.h"
#include "rephoto/io/image_io.h"

namespace {

namespace fs = std::filesystem;

fs::path BenchDir() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / "rephoto-bench-io";
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

// A smooth error-like field with noise and a NaN border (like a window metric's output).
rephoto::Image ErrorField(int width, int height) {
  rephoto::Image image(width, height, 1);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> noise(0.f, 0.05f);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const bool border = x < 4 || y < 4 || x >= width - 4 || y >= height - 4;
      image.at(x, y) =
          border ? NAN : 0.3f + 0.2f * std::sin(x * 0.01f) * std::cos(y * 0.013f) + noise(rng);
    }
  }
  return image;
}

void BM_WriteExrError(benchmark::State& state) {
  const auto image = ErrorField(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  for (auto _ : state) rephoto::io::WriteExr(BenchDir() / "error.exr", image);
  state.counters["MB"] = fs::file_size(BenchDir() / "error.exr") / 1e6;
}

void BM_WriteJetPng(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0)), height = static_cast<int>(state.range(1));
  const auto field = ErrorField(width, height);
  std::vector<uint8_t> rgba(static_cast<size_t>(width) * height * 4);
  for (size_t i = 0; i < field.size(); ++i) {
    const float v = field.data()[i];
    const uint8_t t = std::isnan(v) ? 0 : static_cast<uint8_t>(v * 255);
    rgba[4 * i] = t;
    rgba[4 * i + 1] = static_cast<uint8_t>(255 - t);
    rgba[4 * i + 2] = static_cast<uint8_t>(t / 2);
    rgba[4 * i + 3] = std::isnan(v) ? 0 : 255;
  }
  for (auto _ : state) rephoto::io::WritePng8(BenchDir() / "error.png", rgba, width, height, 4);
  state.counters["MB"] = fs::file_size(BenchDir() / "error.png") / 1e6;
}

void BM_ReadPng(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0)), height = static_cast<int>(state.range(1));
  rephoto::Image photo(width, height, 3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c)
        photo.at(x, y, c) = 0.5f + 0.4f * std::sin(x * 0.02f + y * 0.03f * c);
    }
  }
  const fs::path path = BenchDir() / "photo.png";
  rephoto::io::WritePng(path, photo);
  rephoto::Image image;
  for (auto _ : state) rephoto::io::ReadImage(path, &image);
}

// A real JPEG photo (3072x2048) when the shared datasets are present.
void BM_ReadJpeg(benchmark::State& state) {
  // <repo>/bench/bench_io.cc -> <repo>/../shared/data
  const fs::path data =
      fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared/data";
  const fs::path path = data / "strecha_fountain_p11/images/0000.jpg";
  if (!fs::exists(path)) {
    state.SkipWithError("shared data not found");
    return;
  }
  rephoto::Image image;
  for (auto _ : state) rephoto::io::ReadImage(path, &image);
  state.counters["MP"] = image.pixel_count() / 1e6;
}

BENCHMARK(BM_WriteExrError)->Args({4000, 3000})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WriteJetPng)->Args({4000, 3000})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadPng)->Args({4000, 3000})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadJpeg)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
