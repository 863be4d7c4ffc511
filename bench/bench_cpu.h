// Process CPU time per benchmark iteration, shared by the benchmark programs.
#pragma once

#include <benchmark/benchmark.h>

#include <string>

#include "rephoto/core/process.h"

namespace rephoto::bench {

// Sets state.counters[name] to the process CPU milliseconds (all threads, user + system) per
// iteration between its construction and its destruction (construct it just before the
// benchmark loop). With other work on the machine the wall time depends on the load; CPU time
// much less so, and cpu_ms / 2 is the wall time on 2 idle cores for well-parallel code.
class CpuCounter {
 public:
  explicit CpuCounter(benchmark::State& state, std::string name = "cpu_ms")
      : state_(state), name_(std::move(name)), start_(ProcessCpuSeconds()) {}
  ~CpuCounter() {
    state_.counters[name_] =
        (ProcessCpuSeconds() - start_) * 1e3 / static_cast<double>(state_.iterations());
  }
  CpuCounter(const CpuCounter&) = delete;
  CpuCounter& operator=(const CpuCounter&) = delete;

 private:
  benchmark::State& state_;
  std::string name_;
  double start_;
};

}  // namespace rephoto::bench
