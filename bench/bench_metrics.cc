// Time per metric and for the paper's set (1-ncc, cb+cr, zssd, dssim, census) on a synthetic
// photo/rendering pair with a validity mask, at 640x480, 1920x1080 and 4000x3000.
//
//   build-*/bench/rephoto_bench_metrics --benchmark_repetitions=5
//     --benchmark_report_aggregates_only=true
//
// The *BytesInBands cases run the same metrics on the pair rounded to 8 bits (RGB photo, RGBA
// rendering) through ComputeMetricsInBands, as `rephoto compare` does for JPEG/PNG files; older
// builds have no such cases: compare them with the float cases of an older binary run in turns.
//
// SSIM kernels: the *FusedKernel and *FiveQuantitiesKernel cases run DSSIM with the fused SSIM
// kernel (the default) and the earlier one it replaced, in one binary.
//
// Kernels: the names of the cases stay the same from build to build, so an older binary's
// figures compare case by case with a newer one's (run both in turns). Census and the SSIM
// filters have a 16-wide AVX-512 version and 8-wide AVX2/baseline versions (picked at run time,
// core/isa.h); to measure the AVX2 code that CPUs without AVX-512 run, run the benchmark with
// REPHOTO_ISA=avx2 in the environment (REPHOTO_ISA=baseline for the SSE2 path).
//
// Images, masks and result buffers are allocated and touched once, outside the timed loop (the
// first touch of fresh pages costs ~10 us per 4 KiB page on the target machines and would
// otherwise dominate).
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <span>
#include <utility>

#include "rephoto/core/parallel.h"
#include "rephoto/metrics/compat.h"
#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/metrics.h"

namespace {

using rephoto::Image;
using rephoto::Mask;
using rephoto::metrics::Metric;

struct Pair {
  Image photo, rephoto;
  // The same pair as 8-bit files hold it (the rendering rounded to 8 bits), RGBA rendering:
  // what `rephoto compare` gives ComputeMetricsInBands for JPEG photos and PNG renderings.
  rephoto::Image8 photo8, rephoto8;
  Mask valid;
  std::vector<rephoto::metrics::MetricResult> results;
};

// Textured photo; the rendering is a blurred, slightly shifted and noisier copy; the mask
// removes a disc (an uncovered region) and scattered pixels.
Pair& GetPair(int width, int height) {
  static std::map<std::pair<int, int>, std::unique_ptr<Pair>> cache;
  auto& slot = cache[{width, height}];
  if (slot) return *slot;
  slot = std::make_unique<Pair>();
  Pair& p = *slot;
  p.photo = Image(width, height, 3);
  p.rephoto = Image(width, height, 3);
  p.valid = Mask(width, height, 1, 1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> noise(-0.02f, 0.02f);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v = 0.5f + 0.25f * std::sin(0.05f * x + c) * std::cos(0.031f * y) +
                        0.1f * std::sin(0.7f * x * (c + 1)) * std::sin(0.4f * y);
        p.photo.at(x, y, c) = std::round(std::clamp(v + noise(rng), 0.0f, 1.0f) * 255) / 255;
        p.rephoto.at(x, y, c) = std::clamp(0.9f * v + 0.05f + noise(rng), 0.0f, 1.0f);
      }
      const float dx = x - 0.3f * width, dy = y - 0.6f * height;
      if (dx * dx + dy * dy < 0.01f * width * width || (x * 7 + y * 13) % 101 == 0) {
        p.valid.at(x, y) = 0;
      }
    }
  }
  p.photo8 = rephoto::Image8(width, height, 3);
  p.rephoto8 = rephoto::Image8(width, height, 4);
  for (size_t i = 0; i < p.photo.pixel_count(); ++i) {
    for (int c = 0; c < 3; ++c) {
      p.photo8.data()[3 * i + c] =
          static_cast<uint8_t>(std::lround(p.photo.data()[3 * i + c] * 255));
      p.rephoto8.data()[4 * i + c] =
          static_cast<uint8_t>(std::lround(p.rephoto.data()[3 * i + c] * 255));
    }
    p.rephoto8.data()[4 * i + 3] = 255;
  }
  return p;
}

void Run(benchmark::State& state, const std::vector<Metric>& metrics) {
  const int width = static_cast<int>(state.range(0));
  const int height = static_cast<int>(state.range(1));
  Pair& p = GetPair(width, height);
  rephoto::metrics::MetricOptions options;
  // Warm-up: sizes the result images and per-thread scratch.
  rephoto::metrics::ComputeMetrics(p.photo, p.rephoto, p.valid, metrics, options, &p.results);
  for (auto _ : state) {
    rephoto::metrics::ComputeMetrics(p.photo, p.rephoto, p.valid, metrics, options, &p.results);
    benchmark::DoNotOptimize(p.results.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(width) * height);
}

// ComputeMetricsInBands on the 8-bit pair without a sink: the metric work of
// `rephoto compare --no-error-images` on a JPEG photo and a PNG rendering.
void RunBytesInBands(benchmark::State& state, const std::vector<Metric>& metrics) {
  const int width = static_cast<int>(state.range(0));
  const int height = static_cast<int>(state.range(1));
  Pair& p = GetPair(width, height);
  rephoto::metrics::MetricOptions options;
  const rephoto::metrics::ErrorBandSink sink;  // none: means only, as without error images
  rephoto::metrics::ComputeMetricsInBands(p.photo8, p.rephoto8, p.valid, metrics, options, sink,
                                          &p.results);
  for (auto _ : state) {
    rephoto::metrics::ComputeMetricsInBands(p.photo8, p.rephoto8, p.valid, metrics, options, sink,
                                            &p.results);
    benchmark::DoNotOptimize(p.results.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(width) * height);
}

void Sizes(benchmark::internal::Benchmark* b) {
  b->Args({640, 480})->Args({1920, 1080})->Args({4000, 3000});
  // Real time is what users wait for; the CPU column is the whole process (all threads), which
  // stays meaningful when other jobs compete for the cores.
  b->UseRealTime()->MeasureProcessCPUTime()->Unit(benchmark::kMillisecond);
}

void BM_Set(benchmark::State& state) {
  Run(state, {Metric::kOneMinusNcc, Metric::kCbCr, Metric::kZssd, Metric::kDssim, Metric::kCensus});
}
BENCHMARK(BM_Set)->Apply(Sizes);

// The same set on one thread: the per-core cost, and a figure that other jobs competing for
// the second core disturb less.
void BM_SetOneThread(benchmark::State& state) {
  rephoto::ThreadLimit limit(1);
  BM_Set(state);
}
BENCHMARK(BM_SetOneThread)
    ->Args({4000, 3000})
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

#define REPHOTO_METRIC_BENCH(name, metric)                          \
  void BM_##name(benchmark::State& state) { Run(state, {metric}); } \
  BENCHMARK(BM_##name)->Apply(Sizes)

REPHOTO_METRIC_BENCH(OneMinusNcc, Metric::kOneMinusNcc);
REPHOTO_METRIC_BENCH(CbCr, Metric::kCbCr);
REPHOTO_METRIC_BENCH(Zssd, Metric::kZssd);
REPHOTO_METRIC_BENCH(Dssim, Metric::kDssim);
REPHOTO_METRIC_BENCH(Census, Metric::kCensus);
REPHOTO_METRIC_BENCH(Psnr, Metric::kPsnr);
REPHOTO_METRIC_BENCH(Ssim, Metric::kSsim);
REPHOTO_METRIC_BENCH(Icid, Metric::kIcid);

// The same metrics on the 8-bit pair through ComputeMetricsInBands (the compare path).
void BigSize(benchmark::internal::Benchmark* b) {
  b->Args({4000, 3000})->UseRealTime()->MeasureProcessCPUTime()->Unit(benchmark::kMillisecond);
}
const std::vector<Metric> kPaperSet = {Metric::kOneMinusNcc, Metric::kCbCr, Metric::kZssd,
                                       Metric::kDssim, Metric::kCensus};
void BM_SetBytesInBands(benchmark::State& state) { RunBytesInBands(state, kPaperSet); }
BENCHMARK(BM_SetBytesInBands)->Apply(BigSize);
void BM_SetBytesInBandsOneThread(benchmark::State& state) {
  rephoto::ThreadLimit limit(1);
  RunBytesInBands(state, kPaperSet);
}
BENCHMARK(BM_SetBytesInBandsOneThread)->Apply(BigSize);
#define REPHOTO_BYTES_BENCH(name, metric)                                                     \
  void BM_##name##BytesInBandsOneThread(benchmark::State& state) {                            \
    rephoto::ThreadLimit limit(1);                                                            \
    RunBytesInBands(state, {metric});                                                         \
  }                                                                                           \
  BENCHMARK(BM_##name##BytesInBandsOneThread)->Apply(BigSize);                                \
  void BM_##name##BytesInBands(benchmark::State& state) { RunBytesInBands(state, {metric}); } \
  BENCHMARK(BM_##name##BytesInBands)->Apply(BigSize)
REPHOTO_BYTES_BENCH(Census, Metric::kCensus);
// 1-NCC and ZSSD share one pass (their window sums).
void BM_NccZssdBytesInBandsOneThread(benchmark::State& state) {
  rephoto::ThreadLimit limit(1);
  RunBytesInBands(state, {Metric::kOneMinusNcc, Metric::kZssd});
}
BENCHMARK(BM_NccZssdBytesInBandsOneThread)->Apply(BigSize);
REPHOTO_BYTES_BENCH(Dssim, Metric::kDssim);
REPHOTO_BYTES_BENCH(Icid, Metric::kIcid);

// DSSIM with each SSIM kernel named (internal::SsimKernel): FusedKernel is what the cases above
// run (the default since the fused kernel came in); FiveQuantitiesKernel is the earlier one (x, y,
// x^2, y^2, xy filtered separately, the window re-read per output row), so before and after
// stay comparable within one binary. 8-bit pair through ComputeMetricsInBands, one thread, and
// the float pair through ComputeMetrics on all threads.
template <rephoto::metrics::internal::SsimKernel kKernel>
void DssimWithKernel(benchmark::State& state, bool bytes) {
  rephoto::metrics::internal::SetSsimKernel(kKernel);
  if (bytes) {
    rephoto::ThreadLimit limit(1);
    RunBytesInBands(state, {Metric::kDssim});
  } else {
    Run(state, {Metric::kDssim});
  }
  rephoto::metrics::internal::SetSsimKernel(rephoto::metrics::internal::SsimKernel::kFused);
}
using rephoto::metrics::internal::SsimKernel;
void BM_DssimFusedKernelBytesInBandsOneThread(benchmark::State& state) {
  DssimWithKernel<SsimKernel::kFused>(state, true);
}
BENCHMARK(BM_DssimFusedKernelBytesInBandsOneThread)->Apply(BigSize);
void BM_DssimFiveQuantitiesKernelBytesInBandsOneThread(benchmark::State& state) {
  DssimWithKernel<SsimKernel::kFiveQuantities>(state, true);
}
BENCHMARK(BM_DssimFiveQuantitiesKernelBytesInBandsOneThread)->Apply(BigSize);
void BM_DssimFusedKernel(benchmark::State& state) {
  DssimWithKernel<SsimKernel::kFused>(state, false);
}
BENCHMARK(BM_DssimFusedKernel)->Apply(BigSize);
void BM_DssimFiveQuantitiesKernel(benchmark::State& state) {
  DssimWithKernel<SsimKernel::kFiveQuantities>(state, false);
}
BENCHMARK(BM_DssimFiveQuantitiesKernel)->Apply(BigSize);

// All eight metrics (the whole set) on the 8-bit pair, one thread, with each SSIM kernel.
template <SsimKernel kKernel>
void BM_AllMetricsBytesInBandsOneThread(benchmark::State& state) {
  rephoto::metrics::internal::SetSsimKernel(kKernel);
  rephoto::ThreadLimit limit(1);
  RunBytesInBands(state, rephoto::metrics::AllMetrics());
  rephoto::metrics::internal::SetSsimKernel(SsimKernel::kFused);
}
BENCHMARK(BM_AllMetricsBytesInBandsOneThread<SsimKernel::kFused>)
    ->Name("BM_AllMetricsFusedKernelBytesInBandsOneThread")
    ->Apply(BigSize);
BENCHMARK(BM_AllMetricsBytesInBandsOneThread<SsimKernel::kFiveQuantities>)
    ->Name("BM_AllMetricsFiveQuantitiesKernelBytesInBandsOneThread")
    ->Apply(BigSize);

}  // namespace

// --compat 3dgs's PSNR and SSIM (metrics/compat.h: whole image, double sums, 11x11 Gaussian
// window with zero padding) of the float pair on one thread, as `evaluate --compat` computes
// them once per test view beside rephoto's own metrics.
void BM_Compat3dgsOneThread(benchmark::State& state) {
  rephoto::ThreadLimit limit(1);
  Pair& p = GetPair(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  for (auto _ : state) {
    const auto result = rephoto::metrics::ComputeCompatMetrics(
        rephoto::metrics::CompatPreset::k3dgs, p.photo, p.rephoto);
    benchmark::DoNotOptimize(result.ssim);
  }
}
BENCHMARK(BM_Compat3dgsOneThread)
    ->Args({4000, 3000})
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

// Hardware floors of two kernels on the AVX2 path, for the ratio kernel / floor in one run
// (docs/speed.md): the arithmetic the kernel cannot avoid at 12 MP, one thread, in registers
// (no stores, no shuffles; census's neighbour loads from L1), 8-wide AVX2 instructions with enough
// independent chains to hide their latency. What each kernel must at least execute per pixel:
// - DSSIM (fused, Gaussian 11 x 11): 4 quantities x 3 channels x 2 passes, each output of a
//   pass one multiply for the centre tap and, for the 5 symmetric pairs, an add and an FMA:
//   144 multiply(-add)s and 120 adds per pixel, i.e. per 8 pixels 144 8-wide FMAs and 120
//   8-wide adds (a CPU with separate add and FMA pipes, as Zen, overlaps them);
// - census (9 x 9 window): 80 neighbours x 2 images loaded and compared with the centre (160
//   loads, 160 compares), the two masks XORed (80) and the differing bits counted (80 integer
//   subtractions of the all-ones mask), per 8 pixels in 8-wide instructions.
// A kernel at 2x its floor spends as much time on loads, shuffles and bookkeeping as on the
// arithmetic it must do; a goal below the floor cannot be met with the same arithmetic.
#if defined(__x86_64__)
#include <immintrin.h>
namespace {
constexpr int64_t kFloorPixels = int64_t{4000} * 3000;

__attribute__((target("avx2,fma"), noinline)) float DssimFmaFloorAvx2(int64_t pixels) {
  // 8 FMA chains and 6 add chains (enough to cover their latencies at 2 per cycle; 16
  // registers with the two constants). One group: 24 FMAs and 20 adds; 6 groups per 8 pixels.
  __m256 acc[8], sum[6];
  for (int j = 0; j < 8; ++j) acc[j] = _mm256_set1_ps(0.001f * j);
  for (int j = 0; j < 6; ++j) sum[j] = _mm256_set1_ps(0.002f * j);
  const __m256 w = _mm256_set1_ps(0.999f), b = _mm256_set1_ps(1e-7f);
  const int64_t groups = pixels / 8 * 6;
  for (int64_t g = 0; g < groups; ++g) {
    for (int k = 0; k < 3; ++k) {
      for (int j = 0; j < 8; ++j) acc[j] = _mm256_fmadd_ps(acc[j], w, b);
      for (int j = 0; j < 6; ++j) sum[j] = _mm256_add_ps(sum[j], b);
    }
    sum[0] = _mm256_add_ps(sum[0], b);
    sum[1] = _mm256_add_ps(sum[1], b);
  }
  __m256 s = acc[0];
  for (int j = 1; j < 8; ++j) s = _mm256_add_ps(s, acc[j]);
  for (int j = 0; j < 6; ++j) s = _mm256_add_ps(s, sum[j]);
  float out[8];
  _mm256_storeu_ps(out, s);
  return out[0];
}

__attribute__((target("avx2,fma"), noinline)) int CensusFloorAvx2(int64_t pixels) {
  // Per neighbour, as the kernel: its value in both images loaded (from L1 here), compared
  // with the centres, the two masks XORed, the all-ones lanes subtracted from a count.
  alignas(32) float p[80 * 8], q[80 * 8];
  for (int i = 0; i < 80 * 8; ++i) {
    p[i] = static_cast<float>((i * 37) % 101) / 101.f;
    q[i] = static_cast<float>((i * 53) % 103) / 103.f;
  }
  __m256 c0 = _mm256_set1_ps(0.5f), c1 = _mm256_set1_ps(0.45f);
  const __m256 step = _mm256_set1_ps(1e-7f);
  __m256i count[4];
  for (int j = 0; j < 4; ++j) count[j] = _mm256_setzero_si256();
  for (int64_t g = 0; g < pixels / 8; ++g) {  // 8 pixels: 80 neighbours
    for (int k = 0; k < 80; k += 4) {
      for (int j = 0; j < 4; ++j) {
        const __m256 a = _mm256_cmp_ps(_mm256_load_ps(p + 8 * (k + j)), c0, _CMP_LT_OQ);
        const __m256 d = _mm256_cmp_ps(_mm256_load_ps(q + 8 * (k + j)), c1, _CMP_LT_OQ);
        count[j] = _mm256_sub_epi32(count[j], _mm256_castps_si256(_mm256_xor_ps(a, d)));
      }
    }
    c0 = _mm256_add_ps(c0, step);  // the next pixels' centres
    c1 = _mm256_add_ps(c1, step);
  }
  __m256i s =
      _mm256_add_epi32(_mm256_add_epi32(count[0], count[1]), _mm256_add_epi32(count[2], count[3]));
  int out[8];
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), s);
  return out[0];
}

void BM_DssimFmaFloorAvx2(benchmark::State& state) {
  if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) {
    state.SkipWithError("no AVX2+FMA");
    return;
  }
  for (auto _ : state) {
    int64_t pixels = kFloorPixels;
    benchmark::DoNotOptimize(pixels);  // not a constant: the loop runs every iteration
    benchmark::DoNotOptimize(DssimFmaFloorAvx2(pixels));
  }
}
BENCHMARK(BM_DssimFmaFloorAvx2)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

void BM_CensusFloorAvx2(benchmark::State& state) {
  if (!__builtin_cpu_supports("avx2")) {
    state.SkipWithError("no AVX2");
    return;
  }
  for (auto _ : state) {
    int64_t pixels = kFloorPixels;
    benchmark::DoNotOptimize(pixels);
    benchmark::DoNotOptimize(CensusFloorAvx2(pixels));
  }
}
BENCHMARK(BM_CensusFloorAvx2)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);
}  // namespace
#endif

BENCHMARK_MAIN();
