#pragma once
// ChainMail (Gibson 1997; thesis §5.1, §5.3) for inelastic tissue: the springs of the membrane are rigid links that
// move freely within limits and drag their neighbours only when a limit is reached, so a deformation reaches
// equilibrium in one sweep instead of many integration steps.
//
// Limits per link, relative to its rest vector r0 (length l, direction u, both from the initial geometry, like
// Gibson's axis-aligned limits): the component along u stays in [min_stretch·l, max_stretch·l], the component
// perpendicular to u (shear) has length <= max_shear·l. Each link's valid set is convex and contains the rest state.
//
// Propagation: when a node moves by D, every other node k moves by t_k·D/|D| with t_k = max(0, |D| − dist_k), where
// dist_k is the shortest path from the moved node in the directed "slack" metric: w(i→j) = how far j may lag behind
// i along D before the link i–j leaves its limits (computed on the state before the move). Nodes are settled in order
// of dist (Dijkstra — Gibson's BFS from the sponsor generalised to links of unequal slack; with equal slack it is
// BFS order), each at most once, and only nodes with dist < |D| are visited, so the cost is proportional to the
// number of nodes that move. For every link, |t_i − t_j| <= the slack in that direction (triangle inequality), so a
// move from a state with all links within limits ends with all links within limits — exactly, not after iterating.
// A pinned (or held) node never moves: the move is shortened to the dist of the first one reached.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace vrm_sim {
namespace mge {
class Membrane;
}

namespace tissue {

struct ChainMailConfig {
  double min_stretch = 0.8;  // × rest length, <= 1
  double max_stretch = 1.2;  // × rest length, >= 1
  double max_shear = 0.2;    // × rest length, >= 0
  // Gibson's elastic relaxation after each simulator step: every free node moves this fraction of the way towards
  // the position its links' rest vectors give it, if all its links stay within limits. 0 = off.
  double relaxation = 0.0;
  int relaxation_iterations = 1;
};

struct ChainMailMove {
  Eigen::Vector3d achieved = Eigen::Vector3d::Zero();  // the moved node's displacement (shorter if limited)
  bool limited = false;                                // a pinned / held node stopped the move short
  std::size_t moved_nodes = 0;                         // nodes displaced, the moved one included
  std::size_t settled_nodes = 0;
  std::size_t link_checks = 0;  // slack evaluations
};

class ChainMail {
 public:
  // Takes the membrane's current geometry as the rest state. Throws std::invalid_argument for limits that exclude
  // the rest state (min_stretch > 1, max_stretch < 1, max_shear < 0) or are not finite.
  ChainMail(mge::Membrane& membrane, const ChainMailConfig& config);

  // After a topology change: re-reads the links; rest vectors of the surviving nodes are kept (by node id).
  void rebuild();

  // Moves `node` by `displacement` and lets the tissue follow (see above). `held` (size nodeCount(), may be null):
  // nodes that must not move, like pinned ones; the moved node itself may be held. A pinned moved node or a
  // non-finite displacement moves nothing.
  ChainMailMove move(std::uint32_t node, const Eigen::Vector3d& displacement, const std::uint8_t* held = nullptr);

  // One relaxation sweep (config().relaxation); returns the number of nodes that moved.
  std::size_t relax(const std::uint8_t* held = nullptr);

  // Slack of link `spring` in direction `direction` (unit): how far the end opposite to `from_first ? first : second`
  // may move by −t·direction relative to the other end before the link leaves its limits; 0 if it is at or beyond.
  double slack(std::size_t spring, bool from_first, const Eigen::Vector3d& direction) const;
  // Largest violation over all links, relative to their rest length (0 = all within limits).
  double maxViolation() const;
  double linkViolation(std::size_t spring) const;

  const ChainMailConfig& config() const { return config_; }
  const Eigen::Vector3d& restVector(std::size_t spring) const { return rest_vectors_[spring]; }

 private:
  bool active(std::size_t spring) const { return rest_lengths_[spring] > 0.0; }

  mge::Membrane* membrane_;
  ChainMailConfig config_;
  std::unordered_map<std::uint64_t, Eigen::Vector3d> rest_by_id_;
  std::vector<Eigen::Vector3d> rest_vectors_;  // per spring slot: rest position of second − of first end
  std::vector<double> rest_lengths_;           // 0 = not a link (bending spring or zero rest vector)
  std::vector<Eigen::Vector3d> rest_directions_;
  std::vector<std::uint32_t> adjacency_offsets_, adjacency_;  // CSR node → incident springs
  // Dijkstra scratch, kept between moves (no allocation in steady state).
  std::vector<double> dist_;
  std::vector<std::uint32_t> reached_, settled_mark_;  // == current_epoch_: dist_ valid / node settled in this move
  std::uint32_t current_epoch_ = 0;
  std::vector<std::pair<double, std::uint32_t>> heap_;
  std::vector<std::uint32_t> settled_;
};

}  // namespace tissue
}  // namespace vrm_sim
