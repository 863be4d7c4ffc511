// A Potts labelling problem on a graph, solved by alpha-expansion (Boykov, Veksler and Zabih,
// "Fast approximate energy minimization via graph cuts", PAMI 2001) with each expansion move
// an exact minimum s-t cut by Boykov-Kolmogorov max-flow (Boost.Graph's
// boykov_kolmogorov_max_flow).
//
// Energy of a labelling l:
//   E(l) = sum_i cost(i, l_i) + smoothness * #{edges (i, j) : l_i != l_j}
// where node i may only take one of its candidate labels. Nodes without candidates keep the
// label -1 and contribute nothing (the Potts term of an edge to such a node is the same for
// every label of its neighbour, so it is left out).
// Costs are rounded to multiples of 1e-6 for the max-flow (integer capacities: no
// floating-point cycling); the reported energy is computed from the original costs.
// Deterministic: labels are expanded in increasing order; the result does not depend on the
// thread count (single-threaded).
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace rephoto::texture {

struct PottsProblem {
  // Candidates of node i: labels[offsets[i] .. offsets[i + 1]) with their costs at the same
  // positions (costs finite and >= 0; labels >= 0, distinct per node). offsets has
  // node_count + 1 entries.
  std::vector<uint32_t> offsets = {0};
  std::vector<int> labels;
  std::vector<float> costs;
  // Neighbouring node pairs (each pair once, any order).
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  float smoothness = 1.0f;  // Potts weight, >= 0

  size_t node_count() const { return offsets.size() - 1; }
};

struct PottsOptions {
  int max_cycles = 4;  // passes over all labels; stops earlier when a pass lowers nothing
};

struct PottsResult {
  std::vector<int> labels;    // one per node, a candidate label or -1 (no candidates)
  double initial_energy = 0;  // of the start: every node at its cheapest candidate
  double energy = 0;
  int cycles = 0;    // passes run
  size_t moves = 0;  // expansion moves that lowered the energy
};

// Energy of a labelling (labels not among a node's candidates: throws Error).
double PottsEnergy(const PottsProblem& problem, const std::vector<int>& labels);

// Minimizes E by alpha-expansion from the labelling that takes each node's cheapest candidate.
// Throws Error for malformed problems (sizes, negative or non-finite costs, edge out of range).
PottsResult SolvePotts(const PottsProblem& problem, const PottsOptions& options = {});

}  // namespace rephoto::texture
