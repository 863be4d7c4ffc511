#include "rephoto/texture/mrf.h"

#include <algorithm>
#include <boost/graph/adjacency_list.hpp>
#include <boost/graph/boykov_kolmogorov_max_flow.hpp>
#include <cmath>
#include <cstdint>
#include <limits>

#include "rephoto/core/error.h"

namespace rephoto::texture {
namespace {

constexpr double kCostScale = 1e6;  // costs become integer capacities in units of 1e-6

using Capacity = int64_t;
using Traits = boost::adjacency_list_traits<boost::vecS, boost::vecS, boost::directedS>;
using Graph = boost::adjacency_list<
    boost::vecS, boost::vecS, boost::directedS,
    boost::property<boost::vertex_index_t, int64_t,
                    boost::property<boost::vertex_color_t, boost::default_color_type,
                                    boost::property<boost::vertex_distance_t, int64_t,
                                                    boost::property<boost::vertex_predecessor_t,
                                                                    Traits::edge_descriptor>>>>,
    boost::property<
        boost::edge_capacity_t, Capacity,
        boost::property<boost::edge_residual_capacity_t, Capacity,
                        boost::property<boost::edge_reverse_t, Traits::edge_descriptor>>>>;

// An s-t graph: `nodes` inner vertices plus the source and the sink.
class CutGraph {
 public:
  explicit CutGraph(size_t nodes)
      : graph_(nodes + 2),
        source_(nodes),
        sink_(nodes + 1),
        capacity_(boost::get(boost::edge_capacity, graph_)),
        reverse_(boost::get(boost::edge_reverse, graph_)) {}

  // Capacity forward (u -> v) and backward (v -> u) on one pair of mutually reverse edges.
  void AddEdge(size_t u, size_t v, Capacity forward, Capacity backward) {
    const auto e = boost::add_edge(u, v, graph_).first;
    const auto r = boost::add_edge(v, u, graph_).first;
    capacity_[e] = forward;
    capacity_[r] = backward;
    reverse_[e] = r;
    reverse_[r] = e;
  }
  // Cutting source -> u costs `to_sink_side` (u ends on the sink side), u -> sink costs
  // `to_source_side`.
  void AddTerminal(size_t u, Capacity to_sink_side, Capacity to_source_side) {
    if (to_sink_side > 0) AddEdge(source_, u, to_sink_side, 0);
    if (to_source_side > 0) AddEdge(u, sink_, to_source_side, 0);
  }
  void Solve() { boost::boykov_kolmogorov_max_flow(graph_, source_, sink_); }
  // After Solve: true when u lies on the source side of the minimum cut.
  bool OnSourceSide(size_t u) const {
    return boost::get(boost::vertex_color, graph_, u) == boost::black_color;
  }

 private:
  Graph graph_;
  size_t source_, sink_;
  boost::property_map<Graph, boost::edge_capacity_t>::type capacity_;
  boost::property_map<Graph, boost::edge_reverse_t>::type reverse_;
};

Capacity Scaled(double cost) { return static_cast<Capacity>(std::llround(cost * kCostScale)); }

// Position of `label` among node i's candidates, or -1.
int CandidateIndex(const PottsProblem& p, size_t i, int label) {
  for (uint32_t k = p.offsets[i]; k < p.offsets[i + 1]; ++k) {
    if (p.labels[k] == label) return static_cast<int>(k - p.offsets[i]);
  }
  return -1;
}

void CheckProblem(const PottsProblem& p) {
  REPHOTO_CHECK(!p.offsets.empty() && p.offsets.front() == 0, "potts: offsets must start at 0");
  REPHOTO_CHECK(p.offsets.back() == p.labels.size() && p.labels.size() == p.costs.size(),
                "potts: {} labels and {} costs for offsets ending at {}", p.labels.size(),
                p.costs.size(), p.offsets.back());
  for (size_t i = 0; i + 1 < p.offsets.size(); ++i) {
    REPHOTO_CHECK(p.offsets[i] <= p.offsets[i + 1], "potts: offsets decrease at node {}", i);
  }
  for (size_t k = 0; k < p.costs.size(); ++k) {
    REPHOTO_CHECK(std::isfinite(p.costs[k]) && p.costs[k] >= 0 && p.labels[k] >= 0,
                  "potts: candidate {}: label {} cost {} (labels and costs must be >= 0)", k,
                  p.labels[k], p.costs[k]);
  }
  REPHOTO_CHECK(std::isfinite(p.smoothness) && p.smoothness >= 0,
                "potts: smoothness {} must be finite and >= 0", p.smoothness);
  for (const auto& [a, b] : p.edges) {
    REPHOTO_CHECK(a < p.node_count() && b < p.node_count(), "potts: edge ({}, {}) out of range", a,
                  b);
  }
}

}  // namespace

double PottsEnergy(const PottsProblem& p, const std::vector<int>& labels) {
  REPHOTO_CHECK(labels.size() == p.node_count(), "potts: {} labels for {} nodes", labels.size(),
                p.node_count());
  double energy = 0;
  for (size_t i = 0; i < p.node_count(); ++i) {
    if (p.offsets[i] == p.offsets[i + 1]) continue;
    const int k = CandidateIndex(p, i, labels[i]);
    REPHOTO_CHECK(k >= 0, "potts: node {} has label {}, not one of its candidates", i, labels[i]);
    energy += p.costs[p.offsets[i] + k];
  }
  for (const auto& [a, b] : p.edges) {
    if (labels[a] >= 0 && labels[b] >= 0 && labels[a] != labels[b]) energy += p.smoothness;
  }
  return energy;
}

PottsResult SolvePotts(const PottsProblem& p, const PottsOptions& options) {
  CheckProblem(p);
  const size_t n = p.node_count();
  // Neighbour lists (CSR) of nodes that have candidates.
  std::vector<uint32_t> degree(n + 1, 0);
  for (const auto& [a, b] : p.edges) {
    if (a == b) continue;
    ++degree[a + 1];
    ++degree[b + 1];
  }
  for (size_t i = 0; i < n; ++i) degree[i + 1] += degree[i];
  std::vector<uint32_t> neighbours(degree[n]);
  {
    std::vector<uint32_t> fill(degree.begin(), degree.end() - 1);
    for (const auto& [a, b] : p.edges) {
      if (a == b) continue;
      neighbours[fill[a]++] = b;
      neighbours[fill[b]++] = a;
    }
  }

  PottsResult result;
  result.labels.assign(n, -1);
  std::vector<int> all_labels;
  for (size_t i = 0; i < n; ++i) {
    float best = std::numeric_limits<float>::infinity();
    for (uint32_t k = p.offsets[i]; k < p.offsets[i + 1]; ++k) {
      if (p.costs[k] < best) best = p.costs[k], result.labels[i] = p.labels[k];
    }
  }
  all_labels = p.labels;
  std::sort(all_labels.begin(), all_labels.end());
  all_labels.erase(std::unique(all_labels.begin(), all_labels.end()), all_labels.end());
  result.initial_energy = PottsEnergy(p, result.labels);
  double energy = result.initial_energy;
  const Capacity smooth = Scaled(p.smoothness);

  std::vector<int64_t> graph_index(n, -1);
  std::vector<uint32_t> members;
  std::vector<Capacity> keep_cost, alpha_cost;  // unary terms of x = 0 (keep) and x = 1 (alpha)
  for (int cycle = 0; cycle < options.max_cycles; ++cycle) {
    ++result.cycles;
    bool improved = false;
    for (const int alpha : all_labels) {
      members.clear();
      for (size_t i = 0; i < n; ++i) {
        if (result.labels[i] != alpha && result.labels[i] >= 0 &&
            CandidateIndex(p, i, alpha) >= 0) {
          graph_index[i] = static_cast<int64_t>(members.size());
          members.push_back(static_cast<uint32_t>(i));
        }
      }
      if (members.empty()) continue;
      CutGraph graph(members.size());
      keep_cost.assign(members.size(), 0);
      alpha_cost.assign(members.size(), 0);
      for (size_t m = 0; m < members.size(); ++m) {
        const uint32_t i = members[m];
        keep_cost[m] += Scaled(p.costs[p.offsets[i] + CandidateIndex(p, i, result.labels[i])]);
        alpha_cost[m] += Scaled(p.costs[p.offsets[i] + CandidateIndex(p, i, alpha)]);
        for (uint32_t e = degree[i]; e < degree[i + 1]; ++e) {
          const uint32_t j = neighbours[e];
          const int lj = result.labels[j];
          if (lj < 0) continue;
          if (graph_index[j] < 0) {  // fixed neighbour (it cannot take alpha, or already has it)
            keep_cost[m] += result.labels[i] != lj ? smooth : 0;
            alpha_cost[m] += alpha != lj ? smooth : 0;
          } else if (i < j) {
            // Pair term A = E(keep, keep) = s[l_i != l_j], B = E(keep, alpha) = s,
            // C = E(alpha, keep) = s, D = E(alpha, alpha) = 0 (Kolmogorov-Zabih construction):
            // E = A + (C - A) x_i + (D - C) x_j + (B + C - A - D)(1 - x_i) x_j.
            const Capacity a = result.labels[i] != lj ? smooth : 0;
            const size_t mj = static_cast<size_t>(graph_index[j]);
            alpha_cost[m] += smooth - a;
            keep_cost[mj] += smooth;                  // (D - C) x_j = -s x_j  ==  +s (1 - x_j) - s
            graph.AddEdge(m, mj, 2 * smooth - a, 0);  // x_i = 0 (source side), x_j = 1 (sink)
          }
        }
      }
      for (size_t m = 0; m < members.size(); ++m) {
        const Capacity low = std::min(keep_cost[m], alpha_cost[m]);
        // x = 1 (alpha) <=> sink side: cutting source -> m pays the alpha cost.
        graph.AddTerminal(m, alpha_cost[m] - low, keep_cost[m] - low);
      }
      graph.Solve();
      std::vector<int> proposal = result.labels;
      for (size_t m = 0; m < members.size(); ++m) {
        if (!graph.OnSourceSide(m)) proposal[members[m]] = alpha;
      }
      for (uint32_t i : members) graph_index[i] = -1;
      const double proposed = PottsEnergy(p, proposal);
      if (proposed < energy - 1e-9) {
        energy = proposed;
        result.labels = std::move(proposal);
        ++result.moves;
        improved = true;
      }
    }
    if (!improved) break;
  }
  result.energy = energy;
  return result;
}

}  // namespace rephoto::texture
