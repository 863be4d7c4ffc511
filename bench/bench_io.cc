// Image I/O costs that dominate `rephoto compare` on large photos: decoding a photo, writing a
// float error image (EXR) and a jet-coloured RGBA PNG per metric; PNG decoding against libspng.
//   build-*/bench/rephoto_bench_io [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <cstdio>
#include <random>
#include <vector>

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

// PNG decoding from memory, rephoto's decoder (libspng, with libdeflate inflating the common
// variants: io/png_inflate.h) against libspng alone, in the same run:
//   source 0: a smooth 4000x3000 RGB field written by io::WritePng ("up" filter, libdeflate);
//   source 1: the same with sensor-like noise (+-4 levels), as the demo's photos;
//   source 2: the 20 photos of ../shared/data/llff_fern/images_8 (504x378, written by another
//             encoder: mostly Paeth rows), all decoded per iteration.
// decoder 0: io::DecodeImage; 1: io::internal::DecodeImageByLibspng.
void BM_DecodePng(benchmark::State& state) {
  const int source = static_cast<int>(state.range(0));
  const bool libspng = state.range(1) == 1;
  std::vector<std::vector<uint8_t>> files;
  const auto read = [](const fs::path& path) {
    std::vector<uint8_t> bytes(fs::file_size(path));
    std::FILE* f = std::fopen(path.c_str(), "rb");
    const size_t n = f ? std::fread(bytes.data(), 1, bytes.size(), f) : 0;
    if (f) std::fclose(f);
    bytes.resize(n);
    return bytes;
  };
  if (source < 2) {
    rephoto::Image photo(4000, 3000, 3);
    std::mt19937 rng(2);
    std::uniform_int_distribution<int> noise(-4, 4);
    for (int y = 0; y < photo.height(); ++y) {
      for (int x = 0; x < photo.width(); ++x) {
        for (int c = 0; c < 3; ++c) {
          photo.at(x, y, c) = 0.5f + 0.4f * std::sin(x * 0.02f + y * 0.03f * c) +
                              (source == 1 ? noise(rng) / 255.f : 0.f);
        }
      }
    }
    const fs::path path = BenchDir() / "decode.png";
    rephoto::io::WritePng(path, photo);
    files.push_back(read(path));
  } else {
    const fs::path dir =
        fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared/data/llff_fern/images_8";
    if (!fs::is_directory(dir)) {
      state.SkipWithError("shared data not found");
      return;
    }
    for (const auto& entry : fs::directory_iterator(dir)) files.push_back(read(entry.path()));
  }
  rephoto::Image image;
  double pixels = 0;
  for (auto _ : state) {
    pixels = 0;
    for (const std::vector<uint8_t>& file : files) {
      if (libspng) {
        rephoto::io::internal::DecodeImageByLibspng(file, "bench.png", &image);
      } else {
        rephoto::io::DecodeImage(file, "bench.png", &image);
      }
      pixels += image.pixel_count();
    }
  }
  state.counters["MP"] = pixels / 1e6;
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
BENCHMARK(BM_DecodePng)
    ->ArgsProduct({{0, 1, 2}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_ReadJpeg)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
