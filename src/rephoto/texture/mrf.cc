#include "rephoto/texture/mrf.h"

#include <algorithm>
#include <boost/graph/boykov_kolmogorov_max_flow.hpp>
#include <boost/graph/compressed_sparse_row_graph.hpp>
#include <boost/property_map/property_map.hpp>
#include <cmath>
#include <cstdint>
#include <limits>

#include "rephoto/core/error.h"

namespace rephoto::texture {
namespace {

constexpr double kCostScale = 1e6;  // costs become integer capacities in units of 1e-6

using Capacity = int64_t;
using Graph = boost::compressed_sparse_row_graph<boost::directedS>;
using Vertex = boost::graph_traits<Graph>::vertex_descriptor;
using Edge = boost::graph_traits<Graph>::edge_descriptor;

// An s-t graph: `nodes` inner vertices plus the source and the sink, stored as a compressed
// sparse row graph with the max-flow's properties in flat arrays (no allocation per vertex).
class CutGraph {
 public:
  void Reset(size_t nodes) {
    nodes_ = nodes;
    arcs_.clear();
  }
  size_t source() const { return nodes_; }
  size_t sink() const { return nodes_ + 1; }
  // Capacity forward (u -> v) and backward (v -> u) on one pair of mutually reverse arcs. Each
  // unordered pair {u, v} may be added once.
  void AddEdge(size_t u, size_t v, Capacity forward, Capacity backward) {
    arcs_.push_back({u, v, forward});
    arcs_.push_back({v, u, backward});
  }
  // Cutting source -> u costs `to_sink_side` (u ends on the sink side), u -> sink costs
  // `to_source_side`.
  void AddTerminal(size_t u, Capacity to_sink_side, Capacity to_source_side) {
    if (to_sink_side > 0) AddEdge(source(), u, to_sink_side, 0);
    if (to_source_side > 0) AddEdge(u, sink(), to_source_side, 0);
  }
  void Solve() {
    // Counting sort of the arcs by source (stable); arc 2t and 2t + 1 are each other's reverse.
    const size_t vertices = nodes_ + 2;
    row_.assign(vertices + 1, 0);
    for (const Arc& a : arcs_) ++row_[a.from + 1];
    for (size_t v = 0; v < vertices; ++v) row_[v + 1] += row_[v];
    position_.resize(arcs_.size());
    pairs_.resize(arcs_.size());
    capacity_.resize(arcs_.size());
    {
      std::vector<size_t>& fill = fill_;
      fill.assign(row_.begin(), row_.end() - 1);
      for (size_t k = 0; k < arcs_.size(); ++k) {
        const size_t at = fill[arcs_[k].from]++;
        position_[k] = at;
        pairs_[at] = {arcs_[k].from, arcs_[k].to};
        capacity_[at] = arcs_[k].capacity;
      }
    }
    graph_ = Graph(boost::edges_are_sorted, pairs_.begin(), pairs_.end(), vertices);
    residual_.resize(arcs_.size());
    reverse_.resize(arcs_.size());
    for (size_t k = 0; k < arcs_.size(); ++k) {
      reverse_[position_[k]] = Edge(arcs_[k].to, position_[k ^ 1]);
    }
    colors_.resize(vertices);
    distances_.resize(vertices);
    predecessors_.resize(vertices);
    const auto edge_index = boost::get(boost::edge_index, graph_);
    const auto vertex_index = boost::get(boost::vertex_index, graph_);
    boost::boykov_kolmogorov_max_flow(
        graph_, boost::make_iterator_property_map(capacity_.begin(), edge_index),
        boost::make_iterator_property_map(residual_.begin(), edge_index),
        boost::make_iterator_property_map(reverse_.begin(), edge_index),
        boost::make_iterator_property_map(predecessors_.begin(), vertex_index),
        boost::make_iterator_property_map(colors_.begin(), vertex_index),
        boost::make_iterator_property_map(distances_.begin(), vertex_index), vertex_index, source(),
        sink());
  }
  // After Solve: true when u lies on the source side of the minimum cut.
  bool OnSourceSide(size_t u) const { return colors_[u] == boost::black_color; }

 private:
  struct Arc {
    size_t from, to;
    Capacity capacity;
  };
  size_t nodes_ = 0;
  std::vector<Arc> arcs_;
  std::vector<std::pair<size_t, size_t>> pairs_;
  std::vector<size_t> row_, fill_, position_;
  Graph graph_;
  std::vector<Capacity> capacity_, residual_;
  std::vector<Edge> reverse_, predecessors_;
  std::vector<boost::default_color_type> colors_;
  std::vector<int64_t> distances_;
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
  std::vector<float> current_cost(n, 0.0f);
  for (size_t i = 0; i < n; ++i) {
    float best = std::numeric_limits<float>::infinity();
    for (uint32_t k = p.offsets[i]; k < p.offsets[i + 1]; ++k) {
      if (p.costs[k] < best) best = p.costs[k], result.labels[i] = p.labels[k];
    }
    if (result.labels[i] >= 0) current_cost[i] = best;
  }
  // Per label, the nodes that may take it with their costs (node order).
  std::vector<int> all_labels = p.labels;
  std::sort(all_labels.begin(), all_labels.end());
  all_labels.erase(std::unique(all_labels.begin(), all_labels.end()), all_labels.end());
  std::vector<std::vector<std::pair<uint32_t, float>>> takers(all_labels.size());
  for (size_t i = 0; i < n; ++i) {
    for (uint32_t k = p.offsets[i]; k < p.offsets[i + 1]; ++k) {
      const size_t slot = static_cast<size_t>(
          std::lower_bound(all_labels.begin(), all_labels.end(), p.labels[k]) - all_labels.begin());
      takers[slot].emplace_back(static_cast<uint32_t>(i), p.costs[k]);
    }
  }
  result.initial_energy = PottsEnergy(p, result.labels);
  double energy = result.initial_energy;
  const Capacity smooth = Scaled(p.smoothness);

  std::vector<int64_t> graph_index(n, -1);
  std::vector<uint32_t> members;
  std::vector<float> member_alpha_cost;
  std::vector<Capacity> keep_cost, alpha_cost;  // unary terms of x = 0 (keep) and x = 1 (alpha)
  std::vector<uint8_t> changed(n, 0);
  CutGraph graph;
  for (int cycle = 0; cycle < options.max_cycles; ++cycle) {
    ++result.cycles;
    bool improved = false;
    for (size_t slot = 0; slot < all_labels.size(); ++slot) {
      const int alpha = all_labels[slot];
      members.clear();
      member_alpha_cost.clear();
      for (const auto& [i, cost] : takers[slot]) {
        if (result.labels[i] == alpha) continue;
        graph_index[i] = static_cast<int64_t>(members.size());
        members.push_back(i);
        member_alpha_cost.push_back(cost);
      }
      if (members.empty()) continue;
      graph.Reset(members.size());
      keep_cost.assign(members.size(), 0);
      alpha_cost.assign(members.size(), 0);
      for (size_t m = 0; m < members.size(); ++m) {
        const uint32_t i = members[m];
        keep_cost[m] += Scaled(current_cost[i]);
        alpha_cost[m] += Scaled(member_alpha_cost[m]);
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
      // Energy change of the move, from the changed nodes and their edges (each edge once).
      double delta = 0;
      for (size_t m = 0; m < members.size(); ++m) {
        if (!graph.OnSourceSide(m)) {
          changed[members[m]] = 1;
          delta += static_cast<double>(member_alpha_cost[m]) - current_cost[members[m]];
        }
      }
      for (size_t m = 0; m < members.size(); ++m) {
        const uint32_t i = members[m];
        if (!changed[i]) continue;
        for (uint32_t e = degree[i]; e < degree[i + 1]; ++e) {
          const uint32_t j = neighbours[e];
          const int lj = result.labels[j];
          if (lj < 0 || (changed[j] && j < i)) continue;
          const int new_j = changed[j] ? alpha : lj;
          delta +=
              p.smoothness * ((alpha != new_j ? 1.0 : 0.0) - (result.labels[i] != lj ? 1.0 : 0.0));
        }
      }
      if (delta < -1e-9) {
        for (size_t m = 0; m < members.size(); ++m) {
          const uint32_t i = members[m];
          if (!changed[i]) continue;
          result.labels[i] = alpha;
          current_cost[i] = member_alpha_cost[m];
        }
        energy += delta;
        ++result.moves;
        improved = true;
      }
      for (uint32_t i : members) graph_index[i] = -1, changed[i] = 0;
    }
    if (!improved) break;
  }
  energy = PottsEnergy(p, result.labels);  // exact, without the accumulated rounding
  result.energy = energy;
  return result;
}

}  // namespace rephoto::texture
