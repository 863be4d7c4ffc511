// LPIPS (src/rephoto/lpips) with AlexNet, the lpips package's default, at 1 MP (1152x864) and
// 12 MP (4000x3000), and VGG16 at 1 MP: one call = both images through the network, the
// whole-image value and the masked value (spatial map averaged over a mask).
//
//   REPHOTO_LPIPS_WEIGHTS=DIR build/bench/rephoto_bench_lpips --benchmark_repetitions=5
//     --benchmark_report_aggregates_only=true
//
// DIR holds alex.pth + alexnet-owt-7be5be79.pth (and vgg.pth + vgg16-397923af.pth): the real
// files, or random ones of the same shapes from src/rephoto/lpips/lpips_reference.py (the
// values do not change the time). bench/peers/lpips_vs_torch.sh runs this side by side with
// PyTorch on the same sizes and weights. Threads: the TBB arena's (all cores unless
// --benchmark_filter'ed runs set REPHOTO_THREADS... ; use `taskset`/2-core machines as is).
// Images are allocated once outside the timed loop; the activations are allocated per call,
// as in real use (and as PyTorch does).
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <memory>
#include <random>

#include "rephoto/core/image.h"
#include "rephoto/lpips/lpips.h"

namespace {

using rephoto::Image;
using rephoto::Mask;
using rephoto::lpips::LpipsModel;
using rephoto::lpips::LpipsNet;

struct Pair {
  Image a, b;
  Mask mask;
};

const Pair& PairOf(int width, int height) {
  static std::map<std::pair<int, int>, std::unique_ptr<Pair>> pairs;
  std::unique_ptr<Pair>& pair = pairs[{width, height}];
  if (!pair) {
    pair = std::make_unique<Pair>();
    pair->a.Resize(width, height, 3);
    pair->b.Resize(width, height, 3);
    pair->mask.Resize(width, height, 1);
    std::mt19937 rng(30);
    std::uniform_real_distribution<float> noise(-0.05f, 0.05f);
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const size_t i = static_cast<size_t>(y) * width + x;
        for (int c = 0; c < 3; ++c) {
          const float v = 0.5f + 0.4f * std::sin(0.01f * (x + 2 * c) + 0.013f * y);
          pair->a.data()[3 * i + c] = v;
          pair->b.data()[3 * i + c] = std::min(1.f, std::max(0.f, v + noise(rng)));
        }
        pair->mask.data()[i] = (x + y) % 7 != 0;
      }
    }
  }
  return *pair;
}

void BM_Lpips(benchmark::State& state, LpipsNet net, int width, int height) {
  const char* dir = std::getenv(rephoto::lpips::kLpipsWeightsEnv);
  if (dir == nullptr) {
    state.SkipWithError("set REPHOTO_LPIPS_WEIGHTS to a directory with the weight files");
    return;
  }
  const auto model = LpipsModel::LoadShared(dir, net);
  const Pair& pair = PairOf(width, height);
  for (auto _ : state) {
    const rephoto::lpips::LpipsValue value = model->Compute(pair.a, pair.b, &pair.mask);
    benchmark::DoNotOptimize(value);
  }
  state.counters["MP"] = width * height / 1e6;
}

BENCHMARK_CAPTURE(BM_Lpips, Alex1MP, LpipsNet::kAlex, 1152, 864)
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_Lpips, Alex12MP, LpipsNet::kAlex, 4000, 3000)
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_Lpips, Vgg1MP, LpipsNet::kVgg, 1152, 864)
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
