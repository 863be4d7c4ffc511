// `rephoto live` latency (issue 31): from a 1 MP photo with a known pose (sidecar) landing in
// the watched folder to the page's state (/api/live) holding its prediction and refreshed
// suggestions, with 50 photos already in. The photos are the demo scene (live/demo_capture.h)
// at 1152 x 864 (1.0 MP) on a spiral around the object (3 rings of azimuths, heights 1.0 to
// 2.0). Setup (the first 50 photos through the same pipeline) is not timed; each iteration adds
// one more photo (so the 2nd iteration has 51 in, ...) and times LiveSession::HandleReady,
// which returns after live.json and the in-memory state were replaced: what the page's next
// poll (1 s) shows. The split (register / predict / depth / model / suggest seconds) is
// reported as counters from the photo's record.
//
// BM_LiveColmapPhotoWith50In: the same with COLMAP registration instead of sidecars.
//
// Run: build/bench/rephoto_bench_live --benchmark_repetitions=1
//      (--benchmark_filter=BM_LivePhotoWith50In for the sidecar case alone)
// Threads: the library's pool (all cores; 2 on the target machine).
#include <benchmark/benchmark.h>

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>

#include "bench_cpu.h"
#include "rephoto/live/colmap_registrar.h"
#include "rephoto/live/demo_capture.h"
#include "rephoto/live/live_session.h"

namespace {

namespace fs = std::filesystem;
using namespace rephoto;

camera::Pose SpiralPose(int k) {
  const double azimuth = k * 2 * M_PI / 17;
  const double height = 1.0 + (k % 3) * 0.5;
  return live::LookAt({3.2 * std::cos(azimuth), 3.2 * std::sin(azimuth), height}, {0, 0, 0.45});
}

void BM_LivePhotoWith50In(benchmark::State& state) {
  const fs::path base = fs::temp_directory_path() / ("rephoto_bench_live_" + std::to_string(getpid()));
  fs::remove_all(base);
  const fs::path watch = base / "watch", run = base / "run";
  fs::create_directories(watch);
  live::DemoCapture capture(1152, 864);
  live::LiveOptions o;
  o.watch = watch;
  o.out = run;
  live::LiveSession session(o);
  int k = 0;
  for (; k < 50; ++k) {
    capture.Drop(watch, "p" + std::to_string(k), SpiralPose(k), k);
    session.HandleReady("p" + std::to_string(k) + ".png");
  }
  nlohmann::json last;
  for (auto _ : state) {
    state.PauseTiming();
    const std::string stem = "p" + std::to_string(k);
    capture.Drop(watch, stem, SpiralPose(k), k);
    ++k;
    state.ResumeTiming();
    session.HandleReady(stem + ".png");
    state.PauseTiming();
    last = session.Api()["photos"].back();
    state.ResumeTiming();
  }
  for (const char* key : {"register", "predict", "depth", "model", "suggest", "total"})
    state.counters[key] = last["seconds"].value(key, 0.0);
  state.counters["completeness"] = last["completeness"].is_number() ? last["completeness"].get<double>() : 0.0;
  fs::remove_all(base);
}
BENCHMARK(BM_LivePhotoWith50In)->Unit(benchmark::kSecond)->Iterations(3)->UseRealTime();

// The same with COLMAP registration (`rephoto live --colmap`, colmap_registrar.h with its
// defaults): the photos land without a sidecar, COLMAP places them (features, matching: every
// pair up to 30 photos, then chosen pairs; image_registrator, point_triangulator). Setup (50
// photos in) takes minutes. Counters: the split of the last timed photo, and `registered`, the
// fraction of the timed photos COLMAP placed (a photo it could not place still updates the
// page, with its status). Needs Debian's colmap.
void BM_LiveColmapPhotoWith50In(benchmark::State& state) {
  if (std::system("command -v colmap >/dev/null") != 0) {
    state.SkipWithError("colmap is not installed (scripts/install-deps.sh)");
    return;
  }
  const fs::path base =
      fs::temp_directory_path() / ("rephoto_bench_live_colmap_" + std::to_string(getpid()));
  fs::remove_all(base);
  const fs::path watch = base / "watch", run = base / "run";
  fs::create_directories(watch);
  live::DemoCapture capture(1152, 864);
  live::ColmapRegistrarOptions co;
  co.workspace = run / "colmap";
  const std::unique_ptr<live::Registrar> registrar = live::MakeColmapRegistrar(co);
  live::LiveOptions o;
  o.watch = watch;
  o.out = run;
  o.registrar = registrar.get();
  live::LiveSession session(o);
  const auto drop = [&](int k) {
    const std::string stem = "p" + std::to_string(k);
    capture.Drop(watch, stem, SpiralPose(k), k);
    fs::remove(watch / (stem + ".json"));  // COLMAP places it
    return stem + ".png";
  };
  int k = 0;
  for (; k < 50; ++k) session.HandleReady(drop(k));
  nlohmann::json last;
  double registered = 0;
  int timed = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const std::string name = drop(k++);
    state.ResumeTiming();
    session.HandleReady(name);
    state.PauseTiming();
    last = session.Api()["photos"].back();
    registered += last["status"] == "registered" ? 1 : 0;
    ++timed;
    state.ResumeTiming();
  }
  for (const char* key : {"register", "predict", "depth", "model", "suggest", "total"})
    state.counters[key] = last["seconds"].value(key, 0.0);
  state.counters["registered"] = timed ? registered / timed : 0;
  int placed = 0;
  const nlohmann::json api = session.Api();
  for (const auto& p : api["photos"]) placed += p["status"] == "registered" ? 1 : 0;
  state.counters["placed_of_all"] = placed;
  fs::remove_all(base);
}
BENCHMARK(BM_LiveColmapPhotoWith50In)->Unit(benchmark::kSecond)->Iterations(3)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
