// A real single-node Slurm cluster for tests (scripts/slurm-cluster.sh does the work).
//
// Under ctest, the fixture tests cluster/slurm_start and cluster/slurm_stop start one cluster
// for every test that needs it (rephoto_test_uses_slurm in src/rephoto/cluster/CMakeLists.txt
// sets FIXTURES_REQUIRED and REPHOTO_TEST_SLURM_DIR). A test program run by hand starts its
// own cluster in a temporary folder on first use and stops it (by PID) when it exits.
//
// RequireSlurmCluster points this process's SLURM_CONF at the cluster, so sbatch, squeue and
// the rest talk to it, and the jobs of tests inherit it. Not thread-safe: call it from the test
// body (the REPHOTO_REQUIRE_SLURM macro), not from several threads.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace rephoto::testing {

struct SlurmCluster {
  std::filesystem::path dir;   // the cluster's folder (slurm.conf, logs, state)
  std::filesystem::path conf;  // dir/slurm.conf
  std::string node;            // the one node's name
};

enum class SlurmAvailability { kRunning, kSkipped, kBroken };

// Finds or starts the cluster. kSkipped: not root or Slurm not installed (`why` says which);
// kBroken: it should run but does not (`why` names the log folder).
SlurmAvailability RequireSlurmCluster(SlurmCluster* cluster, std::string* why);

}  // namespace rephoto::testing

// Skips the current test (with the reason) when no cluster can run here, fails it when one
// should run but does not; otherwise declares `const SlurmCluster& slurm_cluster`.
#define REPHOTO_REQUIRE_SLURM(slurm_cluster)                                        \
  ::rephoto::testing::SlurmCluster slurm_cluster;                                   \
  do {                                                                              \
    std::string slurm_why_;                                                         \
    switch (::rephoto::testing::RequireSlurmCluster(&slurm_cluster, &slurm_why_)) { \
      case ::rephoto::testing::SlurmAvailability::kRunning:                         \
        break;                                                                      \
      case ::rephoto::testing::SlurmAvailability::kSkipped:                         \
        GTEST_SKIP() << "no Slurm test cluster: " << slurm_why_;                    \
      case ::rephoto::testing::SlurmAvailability::kBroken:                          \
        FAIL() << slurm_why_;                                                       \
    }                                                                               \
  } while (false)
