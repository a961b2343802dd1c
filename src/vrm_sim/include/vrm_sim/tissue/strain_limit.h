#pragma once
// Provot's strain limit (thesis Alg. 5.1, Provot 1995) and the BFS spring sorting from the interaction points
// (thesis Alg. 5.2) that lets one Provot pass propagate a large deformation outwards like ChainMail.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "vrm_sim/tissue/system.h"

namespace vrm_sim {
namespace tissue {

// CSR node → incident springs: springs()[offsets()[i] .. offsets()[i + 1]) touch node i, in ascending spring index,
// and others()[k] is the other end of springs()[k]. One per membrane and topology, shared by its spring sorters and
// its bound solver. The simulator adopts the MGE's own node → spring view (mge::NeighbourSlots in slot order, rebuilt
// from the graph on a topology change, issue 40); build() derives the same arrays from the spring array alone (a
// counting sort), for systems without a graph.
class NodeSpringAdjacency {
 public:
  NodeSpringAdjacency() = default;
  NodeSpringAdjacency(const NodeSpringAdjacency&) = delete;  // the borrowed pointers may point into this one
  NodeSpringAdjacency& operator=(const NodeSpringAdjacency&) = delete;
  NodeSpringAdjacency(NodeSpringAdjacency&&) = default;  // a moved vector keeps its buffer
  NodeSpringAdjacency& operator=(NodeSpringAdjacency&&) = default;

  void build(const SystemView& system);
  // Borrows `offsets` (node_count + 1 entries) and `springs`, which must stay valid and unchanged until the next
  // build() or adopt(); computes the other ends.
  void adopt(const SystemView& system, const std::uint32_t* offsets, const std::uint32_t* springs);

  std::size_t nodeCount() const { return node_count_; }
  const std::uint32_t* offsets() const { return offsets_; }
  const std::uint32_t* springs() const { return springs_; }
  const std::uint32_t* others() const { return others_.data(); }

 private:
  std::size_t node_count_ = 0;
  const std::uint32_t* offsets_ = nullptr;
  const std::uint32_t* springs_ = nullptr;
  std::vector<std::uint32_t> own_offsets_, own_springs_, others_;
};

// Springs grouped by graph distance from a set of seed nodes: set S_d holds the springs whose nearer end is d
// springs away from the nearest seed. Each spring is in exactly one set; springs not connected to a seed form a
// final set. Sorting is O(nodes + springs): one BFS over a node→spring adjacency plus a counting sort.
class SpringSorter {
 public:
  // Call after every topology change (and before the first sort): with the membrane's shared adjacency (which must
  // outlive the sorter's use of it), or with one of the sorter's own built from the spring array.
  void rebuild(const SystemView& system, const NodeSpringAdjacency& shared);
  void rebuild(const SystemView& system);
  void sort(const SystemView& system, const std::vector<std::uint32_t>& seeds);
  const NodeSpringAdjacency& adjacency() const { return shared_ != nullptr ? *shared_ : own_; }

  // Spring indices, S_0 first. levelOffsets()[d]..levelOffsets()[d+1] is S_d; the last set is the unreachable one.
  const std::vector<std::uint32_t>& order() const { return order_; }
  const std::vector<std::size_t>& levelOffsets() const { return level_offsets_; }
  // For order()[k]: 1 if the spring's second node is the one nearer to a seed.
  const std::vector<std::uint8_t>& innerIsSecond() const { return inner_is_second_; }
  // Graph distance of every node to the nearest seed (-1 = unreachable).
  const std::vector<int>& nodeDistances() const { return distance_; }
  // springs[order()[k]] for every k: the pass reads its springs' ends in sequence instead of through the order.
  const std::vector<std::array<std::uint32_t, 2>>& orderedEnds() const { return ordered_ends_; }

 private:
  void reserve(const SystemView& system);

  const NodeSpringAdjacency* shared_ = nullptr;
  NodeSpringAdjacency own_;
  std::vector<int> distance_;
  std::vector<std::uint32_t> queue_;
  std::vector<std::uint32_t> order_;
  std::vector<std::array<std::uint32_t, 2>> ordered_ends_;
  std::vector<std::size_t> level_offsets_;
  std::vector<std::uint8_t> inner_is_second_;
  std::vector<int> spring_level_;
  std::vector<std::uint8_t> spring_inner_second_;  // per spring, inner_is_second_ before the ordering
  std::vector<std::size_t> level_fill_;
};

struct ProvotStatistics {
  std::size_t corrected = 0;      // springs shortened in the pass
  std::size_t skipped_fixed = 0;  // over-stretched springs between two constrained nodes (left alone)
};

// One pass of Alg. 5.1: every spring longer than tau·l is shortened to tau·l about its midpoint, towards its
// constrained end if one end is constrained, and left unchanged if both are. With `sorter` (after sort()), springs
// are visited in BFS order from the interaction. With `outer_only` the end nearer to the interaction is also treated
// as fixed, so the correction flows outwards in one pass (ChainMail-like) — exact for a chain pulled at one end, but
// with many instrument contacts it drags outer nodes into the instrument and the collision response then throws them
// through it (measured: strain grows without bound on a 64² membrane), so the simulator uses it only on request.
// Springs with a zero rest length are skipped (no meaningful strain). With `velocities`, a moved node loses the
// velocity component against its correction (Provot's velocity adjustment: an inelastic stop, never adding energy);
// without it the integrator's next step throws the node out again and an instability grows beneath the limit (issue
// 40).
ProvotStatistics provotPass(const SystemView& system, double tau, const SpringSorter* sorter = nullptr,
                            bool outer_only = false, Eigen::Vector3d* velocities = nullptr);

// Issue 40, "stable means bounded": the largest stretch L/l a step may leave, 1 + 1.5·(τ − 1) and never above 2, for
// τ the tear strain (tearing) or the strain limit τ_c (1.15 for τ_c = 1.1); +inf for τ <= 1 or non-finite (no bound).
double strainBound(double tau);
// What boundPass() shortens a spring beyond the bound to: 80 % of the way from τ to the bound (1.14 for τ_c = 1.1),
// so the corrections leave slack and a sweep seldom pushes a neighbour back over the bound; at least 2 % of the bound's
// stretch below it where τ is at or above the bound (a tear strain above 2).
double strainBoundTarget(double tau);

struct BoundPassOptions {
  double bound = 0.0;   // springs longer than bound·l are corrected ...
  double target = 0.0;  // ... to target·l (<= bound)
  // Over-relaxation of a correction (successive over-relaxation of Gauss-Seidel, 1 = none): the spring is shortened
  // by `relaxation` times its excess over target·l, to no less than its rest length.
  double relaxation = 1.0;
  // BFS order from `sorter` (after sort()) with only the spring's outer end moved, so a kinematic pull or push
  // propagates outwards through the whole membrane in one sweep, like ChainMail (the inner end moves only when the
  // outer one is fixed, or both halfway in the unreachable set); null: spring order, both ends halfway.
  const SpringSorter* sorter = nullptr;
  // Without a sorter: the springs in reverse order (alternating directions, Gauss-Seidel converges faster).
  bool reverse = false;
  // Per node: never moved by this pass (null: the system's constrained nodes).
  const std::uint8_t* fixed = nullptr;
  // Tearing: a stretch spring longer than tear_strain·l, with no end in `pressed` (per node) and not a bending spring
  // (`bending`, per spring), is left alone — it tears after the step (topology.h).
  double tear_strain = 0.0;
  const std::uint8_t* pressed = nullptr;
  const std::uint8_t* bending = nullptr;
  // Or, per spring, instead of `pressed` and `bending`: the springs that may tear (those the dynamics stretched past
  // the tear strain before the projection began), so that a spring the projection itself stretches beyond the bound is
  // corrected rather than torn.
  const std::uint8_t* tearable = nullptr;
  // Optional: a moved node loses the part of its velocity that points against its correction (an inelastic stop, as a
  // ChainMail link; never adds energy), so it does not fly on past the bound in the next step.
  Eigen::Vector3d* velocities = nullptr;
  // Optional, per node: set to 1 when the pass moved the node.
  std::uint8_t* moved = nullptr;
};

struct BoundPassStatistics {
  std::size_t corrected = 0;      // springs shortened
  std::size_t skipped_fixed = 0;  // beyond the bound between two fixed nodes (left alone)
  std::size_t left_to_tear = 0;   // beyond the bound, left to tear (BoundPassOptions::tear_strain)
};

// One sweep of the bound projection (issue 40): Alg. 5.1 restricted to springs beyond the bound, in the order and with
// the moving ends of `options` (see BoundPassOptions). A sweep that corrects nothing proves the bound holds for every
// spring but the skipped ones.
BoundPassStatistics boundPass(const SystemView& system, const BoundPassOptions& options);

// Issue 40: Gauss-Seidel on the bound constraints (boundPass()'s rule per spring) over the region of a violation only.
// seed() lists the springs beyond the bound and those of their nodes; a sweep visits the listed springs, and every node
// it moves brings its own springs into the list, so the region grows as far as the correction travels and a sweep
// costs that region, not the membrane. Run until a sweep corrects nothing (converged: no spring beyond the bound
// that may be corrected) or a budget; unlike the BFS sweeps it converges wherever the constraints can be met.
class ActiveBoundSolver {
 public:
  // Sized once per topology; the node -> springs adjacency is kept by reference (the membrane's shared one).
  void reset(std::size_t spring_count, const NodeSpringAdjacency& adjacency);
  // Starts a solve: the springs beyond options.bound and their nodes' springs; false if there is none.
  bool seed(const SystemView& system, double bound);
  // One sweep over the listed springs (forward, or backward with `reverse`), growing the list as it moves nodes.
  BoundPassStatistics sweep(const SystemView& system, const BoundPassOptions& options, bool reverse);
  // A node the caller moved between sweeps (an instrument pushed it back out) joins the region.
  void activate(std::uint32_t node);
  const std::vector<std::uint32_t>& activeNodes() const { return nodes_; }
  std::size_t activeSprings() const { return springs_.size(); }

 private:
  const NodeSpringAdjacency* adjacency_ = nullptr;
  std::vector<std::uint8_t> node_active_, spring_listed_;
  std::vector<std::uint32_t> nodes_, springs_;
  std::vector<std::uint32_t> beyond_;  // seed()'s springs beyond the bound
};

// Whether any spring (rest length >= kMinSpringLength) is longer than bound·l; +inf bounds nothing.
bool anyBeyond(const SystemView& system, double bound);

}  // namespace tissue
}  // namespace vrm_sim
