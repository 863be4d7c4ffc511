// Alpha-expansion against exhaustive search on small random Potts problems, and hand-checked
// cases.
#include "rephoto/texture/mrf.h"

#include <gtest/gtest.h>

#include <functional>
#include <random>

#include "rephoto/testing/testing.h"

namespace rephoto::texture {
namespace {

// The exact minimum by enumerating every labelling.
double BruteForceMinimum(const PottsProblem& p) {
  const size_t n = p.node_count();
  std::vector<int> labels(n, -1), choice(n, 0);
  double best = 1e300;
  std::function<void(size_t)> visit = [&](size_t i) {
    if (i == n) {
      best = std::min(best, PottsEnergy(p, labels));
      return;
    }
    if (p.offsets[i] == p.offsets[i + 1]) {
      labels[i] = -1;
      visit(i + 1);
      return;
    }
    for (uint32_t k = p.offsets[i]; k < p.offsets[i + 1]; ++k) {
      labels[i] = p.labels[k];
      visit(i + 1);
    }
  };
  visit(0);
  return best;
}

PottsProblem RandomProblem(std::mt19937_64& rng, int nodes, int label_count, double smoothness) {
  PottsProblem p;
  std::uniform_real_distribution<float> cost(0, 1);
  std::bernoulli_distribution take(0.6), edge(0.35);
  for (int i = 0; i < nodes; ++i) {
    for (int l = 0; l < label_count; ++l) {
      if (take(rng)) {
        p.labels.push_back(l);
        p.costs.push_back(cost(rng));
      }
    }
    p.offsets.push_back(static_cast<uint32_t>(p.labels.size()));
  }
  for (int i = 0; i < nodes; ++i) {
    for (int j = i + 1; j < nodes; ++j) {
      if (edge(rng)) p.edges.emplace_back(i, j);
    }
  }
  p.smoothness = static_cast<float>(smoothness);
  return p;
}

TEST(Potts, ChainSmoothsAnOutlier) {
  // Five nodes in a chain, labels {0, 1}: node 2 prefers label 1 by 0.4, everybody else label
  // 0 by 1. With smoothness 0.5, switching node 2 to 0 saves 2 x 0.5 for 0.4: optimum all 0,
  // energy 0.4 (hand computation).
  PottsProblem p;
  for (int i = 0; i < 5; ++i) {
    p.labels.insert(p.labels.end(), {0, 1});
    if (i == 2) {
      p.costs.insert(p.costs.end(), {0.4f, 0.0f});
    } else {
      p.costs.insert(p.costs.end(), {0.0f, 1.0f});
    }
    p.offsets.push_back(static_cast<uint32_t>(p.labels.size()));
    if (i > 0) p.edges.emplace_back(i - 1, i);
  }
  p.smoothness = 0.5f;
  const PottsResult r = SolvePotts(p);
  EXPECT_EQ(r.labels, std::vector<int>(5, 0));
  EXPECT_NEAR(r.energy, 0.4, 1e-6);
  EXPECT_NEAR(r.initial_energy, 1.0, 1e-6);  // node 2 at label 1: 0 + 2 x 0.5
  // With smoothness 0.1 the outlier keeps its label: 0 + 0.2 < 0.4.
  p.smoothness = 0.1f;
  EXPECT_EQ(SolvePotts(p).labels, (std::vector<int>{0, 0, 1, 0, 0}));
}

TEST(Potts, NodesWithoutCandidatesKeepMinusOne) {
  PottsProblem p;
  p.labels = {3};
  p.costs = {0.5f};
  p.offsets = {0, 0, 1};
  p.edges = {{0, 1}};
  const PottsResult r = SolvePotts(p);
  EXPECT_EQ(r.labels, (std::vector<int>{-1, 3}));
  EXPECT_NEAR(r.energy, 0.5, 1e-6);
}

TEST(Potts, WithinTwiceTheOptimumAndLocallyOptimal) {
  // Alpha-expansion's guarantee for Potts is a factor 2 of the optimum; in practice it finds
  // the optimum of most small problems. Checked against exhaustive search.
  std::mt19937_64 rng = testing::MakeRng();
  int exact = 0;
  const int trials = 60;
  for (int t = 0; t < trials; ++t) {
    const PottsProblem p = RandomProblem(rng, 8, 3, 0.1 + 0.2 * (t % 5));
    const PottsResult r = SolvePotts(p);
    const double optimum = BruteForceMinimum(p);
    EXPECT_NEAR(r.energy, PottsEnergy(p, r.labels), 1e-9);
    EXPECT_LE(r.energy, r.initial_energy + 1e-9);
    EXPECT_LE(r.energy, 2 * optimum + 1e-6) << "trial " << t;
    if (r.energy <= optimum + 1e-5) ++exact;
    // No single node can lower the energy by changing its label (a special expansion move).
    for (size_t i = 0; i < p.node_count(); ++i) {
      for (uint32_t k = p.offsets[i]; k < p.offsets[i + 1]; ++k) {
        std::vector<int> changed = r.labels;
        changed[i] = p.labels[k];
        EXPECT_GE(PottsEnergy(p, changed), r.energy - 1e-5) << "trial " << t << " node " << i;
      }
    }
  }
  EXPECT_GE(exact, trials * 8 / 10);
  std::printf("alpha-expansion reached the exact optimum in %d of %d problems\n", exact, trials);
}

TEST(Potts, RejectsMalformedProblems) {
  PottsProblem p;
  p.labels = {0};
  p.costs = {-1.0f};
  p.offsets = {0, 1};
  EXPECT_NE(testing::ErrorOf([&] { SolvePotts(p); }).find("must be >= 0"), std::string::npos);
  p.costs = {1.0f};
  p.edges = {{0, 5}};
  EXPECT_NE(testing::ErrorOf([&] { SolvePotts(p); }).find("out of range"), std::string::npos);
}

}  // namespace
}  // namespace rephoto::texture
