// Helpers shared by the benchmark programs: process CPU time per iteration, the common view.
#pragma once

#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>

#include "rephoto/camera/camera.h"
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

// The benchmarks' view of their unit-sphere scenes: from distance 2.3, slightly from above.
inline camera::Pose BenchPose() {
  const Eigen::Vector3d center(0.4, -2.2, 0.6);
  const Eigen::Vector3d forward = (-center).normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d(0, 0, 1)).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  camera::Pose pose;
  pose.rotation.row(0) = right.transpose();
  pose.rotation.row(1) = down.transpose();
  pose.rotation.row(2) = forward.transpose();
  pose.translation = -pose.rotation * center;
  return pose;
}

}  // namespace rephoto::bench
