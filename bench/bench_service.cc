// The benchmark service under load on 127.0.0.1 (rephoto serve's Server, in process, with its
// default 8 HTTP threads and 1 scoring worker): page views and API reads, concurrent uploads,
// page views while the worker scores a backlog, and one scoring on its own.
//   build/bench/rephoto_bench_service [--benchmark_filter=...]
// Dataset: a synthetic COLMAP scene of 6 photos of 320x240 (every:3 -> 2 test cameras),
// metrics 1-ncc, cb+cr, psnr. A submission is a tar of 2 RGBA PNGs (about 2 x 130 KB). The
// leaderboard holds 20 scored submissions before the page benchmarks run.
// Peer: BM_PublishedFile (a 10 KB published tar through the same HTTP stack, no database
// beyond one lookup) is the floor the pages are measured against.
// "Time" is wall-clock time / all requests (UseRealTime; the inverse of the throughput
// items_per_second); latency_ms is the mean time of one request as its client saw it, with T
// client threads keeping T requests in flight.
// The number of iterations is fixed (bounded load: every upload stays on disk and is scored).
#include <benchmark/benchmark.h>
#include <httplib.h>  // after Eigen (its <resolv.h> defines `_res`)

#include <chrono>
#include <filesystem>
#include <memory>
#include <random>
#include <thread>

#include "rephoto/service/server.h"
#include "rephoto/service/test_fixture.h"

namespace {
namespace fs = std::filesystem;
using namespace rephoto::service;

struct Service {
  Service() {
    base = fs::temp_directory_path() / ("rephoto-bench-service-" + std::to_string(getpid()));
    fs::remove_all(base);
    fs::create_directories(base / "root");
    std::mt19937_64 rng(1);
    testing::MakeTinyScene(base / "scene", 6, 320, 240, rng);
    ServerOptions options;
    options.port = 0;
    options.limits.max_per_window = 1000000;
    // 8 client threads from one address, as behind a proxy; no access log on stdout.
    options.max_connections_per_address = 64;
    options.access_log = "";
    server = std::make_unique<Server>(base / "root", options);
    testing::AddTinyDataset(server->store(), base / "scene", "tiny");
    token = server->store().AddParticipant("load");
    participant = *server->store().Authenticate(token);
    archive = testing::RendersFromPhotos(base / "root", "tiny", 0.05, rng);
    port = server->Bind();
    thread = std::thread([this] { server->Run(); });
    for (int i = 0; i < 20; ++i) {
      last_id =
          server->submissions().Submit(participant, "tiny", archive, "m" + std::to_string(i), "");
    }
    server->submissions().WaitIdle(600);
  }
  ~Service() {
    server->Stop();
    thread.join();
    server.reset();
    fs::remove_all(base);
  }
  fs::path base;
  std::unique_ptr<Server> server;
  std::thread thread;
  std::string token;
  ParticipantRecord participant;
  std::string archive;
  std::string last_id;
  int port = 0;
};

Service& GetService() {
  static Service service;
  return service;
}

// The mean wall-clock time of one request as its client thread saw it, averaged over threads
// ("Time" is wall time / all requests, i.e. the inverse of the throughput).
void ReportLatency(benchmark::State& state, double seconds) {
  state.SetItemsProcessed(state.iterations());
  state.counters["latency_ms"] = benchmark::Counter(
      1000 * seconds / static_cast<double>(state.iterations()), benchmark::Counter::kAvgThreads);
}

void Get(benchmark::State& state, const std::string& path) {
  Service& service = GetService();
  httplib::Client client("127.0.0.1", service.port);
  client.set_keep_alive(true);
  double seconds = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    const auto res = client.Get(path.c_str());
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!res || res->status != 200) state.SkipWithError(("GET " + path + " failed").c_str());
    benchmark::DoNotOptimize(res->body.data());
  }
  ReportLatency(state, seconds);
}

void BM_PublishedFile(benchmark::State& state) {
  Get(state, "/api/datasets/tiny/test-cameras.tar");
}
void BM_LeaderboardPage(benchmark::State& state) { Get(state, "/datasets/tiny/leaderboard"); }
void BM_LeaderboardJson(benchmark::State& state) { Get(state, "/api/datasets/tiny/leaderboard"); }
void BM_SubmissionPage(benchmark::State& state) {
  Get(state, "/submissions/" + GetService().last_id);
}

// Uploads: POST -> 202 (extraction, size checks, database row; scoring is queued).
void BM_Upload(benchmark::State& state) {
  Service& service = GetService();
  httplib::Client client("127.0.0.1", service.port);
  client.set_keep_alive(true);
  double seconds = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    const auto res = client.Post("/api/datasets/tiny/submissions?method=load",
                                 {{"Authorization", "Bearer " + service.token}}, service.archive,
                                 "application/x-tar");
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!res || res->status != 202) state.SkipWithError("upload refused");
  }
  ReportLatency(state, seconds);
}

// Page views while the scoring worker works through the uploads' backlog.
void BM_LeaderboardPageWhileScoring(benchmark::State& state) {
  Get(state, "/datasets/tiny/leaderboard");
}

// One submission scored on the calling thread (what the worker does for each upload).
void BM_ScoreOne(benchmark::State& state) {
  Service& service = GetService();
  service.server->submissions().WaitIdle(600);
  for (auto _ : state) service.server->submissions().Score(service.last_id);
  state.SetItemsProcessed(state.iterations());
}

BENCHMARK(BM_PublishedFile)->Threads(1)->Threads(8)->Iterations(400)->UseRealTime();
BENCHMARK(BM_LeaderboardJson)->Threads(1)->Threads(8)->Iterations(200)->UseRealTime();
BENCHMARK(BM_LeaderboardPage)->Threads(1)->Threads(8)->Iterations(100)->UseRealTime();
BENCHMARK(BM_SubmissionPage)->Threads(1)->Threads(8)->Iterations(200)->UseRealTime();
BENCHMARK(BM_Upload)->Threads(1)->Threads(8)->Iterations(25)->UseRealTime();
BENCHMARK(BM_LeaderboardPageWhileScoring)->Threads(8)->Iterations(50)->UseRealTime();
BENCHMARK(BM_ScoreOne)->Iterations(10)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
