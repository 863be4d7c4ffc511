// Geometric evaluation speed (geometry/geometry.h) at the size issue 21 asks for: a model of
// about 1M triangles against a reference of about 1M triangles, 1M samples on each surface.
// The model is a latitude-longitude sphere (500 bands x 1000 segments, 998k triangles) whose
// vertices are moved radially by up to 0.5 % (a smooth pattern, like a reconstruction's error);
// the reference a sphere of another tessellation (499 x 1002, 998k triangles) shifted by 0.002.
//   BM_EvaluateGeometry: EvaluateGeometry with 1M samples per surface (both BVHs, sampling,
//     2M exact closest-point queries, statistics).
//   BM_EvaluateGeometryWithVertexDistances: the same plus the distance of every vertex of both
//     meshes (what `rephoto geometry` computes for its coloured PLYs).
// Counters: cpu_ms = process CPU time per iteration (core/process.h).
//
// Run: build/bench/rephoto_bench_geometry --benchmark_repetitions=3
//        --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>

#include "bench_cpu.h"
#include "rephoto/geometry/geometry.h"
#include "rephoto/geometry/shapes.h"

namespace {

using rephoto::geometry::GeometryOptions;

struct Fixture {
  rephoto::mesh::Mesh model;
  rephoto::mesh::Mesh reference;
  Fixture() {
    model = rephoto::geometry::MakeUvSphere(1.0, 500, 1000);
    for (Eigen::Vector3f& p : model.positions) {
      const float bump = 0.005f * std::sin(7 * p.x()) * std::cos(5 * p.y() + 3 * p.z());
      p *= 1.0f + bump;
    }
    reference = rephoto::geometry::MakeUvSphere(1.0, 499, 1002, {0.002, 0, 0});
  }
};

const Fixture& GetFixture() {
  static const Fixture fixture;
  return fixture;
}

void Run(benchmark::State& state, bool vertex_distances) {
  const Fixture& f = GetFixture();
  GeometryOptions options;
  options.samples = 1'000'000;
  options.tolerances = {0.001, 0.002, 0.005};
  options.vertex_distances = vertex_distances;
  state.counters["model_faces"] = static_cast<double>(f.model.face_count());
  state.counters["reference_faces"] = static_cast<double>(f.reference.face_count());
  rephoto::bench::CpuCounter cpu(state);
  for (auto _ : state) {
    const rephoto::geometry::GeometryResult result =
        rephoto::geometry::EvaluateGeometry(f.model, f.reference, options);
    benchmark::DoNotOptimize(result.accuracy);
    state.counters["f_score_5mm"] = result.tolerances[2].f_score;
  }
}

void BM_EvaluateGeometry(benchmark::State& state) { Run(state, false); }
void BM_EvaluateGeometryWithVertexDistances(benchmark::State& state) { Run(state, true); }

BENCHMARK(BM_EvaluateGeometry)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);
BENCHMARK(BM_EvaluateGeometryWithVertexDistances)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
