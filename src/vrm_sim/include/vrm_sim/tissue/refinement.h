#pragma once
// Local refinement at the interaction (thesis §5.2.4). A coarse triangle near the interaction is replaced by its
// level-n midpoint subdivision (2ⁿ segments per edge; (2ⁿ+1)(2ⁿ+2)/2 nodes, 3·2ⁿ⁻¹(2ⁿ+1) springs, 4ⁿ triangles,
// eqs. 5.16–5.18). Every call refines one region, time-stamped; when the element budget (fine springs) is exhausted,
// the region used longest ago is coarsened again, which restores its coarse triangles, springs and node masses
// exactly. Lattice nodes on an edge shared with an unrefined triangle are *virtual* (Fig. 5.4): they are pinned for
// the integrators (fixed flag) and follow the coarse spring, which stays, by linear interpolation.
//
// Parameters: rest lengths follow the coarse triangle's rest shape (l0/2ⁿ along its edges, eq. 5.15); masses keep
// the density (eq. 5.19): the coarse triangle's share of its corners' masses is spread over the fine lattice by area,
// a virtual node's share going to the two ends of its coarse spring. Stiffness: a triangulated sheet keeps its
// membrane stiffness with D⁽ⁿ⁾ = D (the energy of a uniform strain per area does not depend on the spacing); the
// thesis' D⁽ⁿ⁾ = 2ⁿ·D (5.14) is the rule for springs in series (a chain) and makes a refined sheet 2ⁿ× stiffer —
// available as `chain_stiffness_scaling`, measured in the tests. Δt⁽ⁿ⁾ = Δt/2ⁿ (5.20) is the explicit stability
// bound's business (the simulator's watchdog halves Δt when needed), not done here.
//
// Limits: membranes with bending springs are rejected (their restoration is not implemented); all regions use the
// same level, so neighbouring refined triangles share their edge lattice.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <unordered_map>
#include <vector>

namespace vrm_sim {
namespace mge {
class Membrane;
class Node;
class Spring;
class Triangle;
}  // namespace mge

namespace tissue {

struct RefinementConfig {
  int levels = 0;                        // LOD n (0 = off)
  double radius = 1e-3;                  // m: coarse triangles with their centroid this close to the point are refined
  std::size_t element_budget = 2000;     // fine springs (eq. 5.17 per triangle) in all refined regions together
  bool chain_stiffness_scaling = false;  // D⁽ⁿ⁾ = 2ⁿ·D (5.14) instead of D
};

class LocalRefinement {
 public:
  // Records the membrane's current triangles as the coarse level. Throws std::invalid_argument for levels outside
  // [0, 4], a non-positive or non-finite radius, or a membrane with bending springs.
  LocalRefinement(mge::Membrane& membrane, const RefinementConfig& config);

  // Refines the coarse triangles around `point` (one region, stamped `time`); already refined ones only get the new
  // stamp. Coarsens the oldest regions first if the budget requires. True if the topology changed.
  bool refineAt(const Eigen::Vector3d& point, std::uint64_t time);
  // Coarsens every region. True if the topology changed.
  bool coarsenAll();
  // Puts the virtual nodes back onto their coarse springs (positions and velocities); call after every step.
  void updateVirtualNodes();
  // After a cut or tear: re-reads node slots; coarse triangles that lost a node are dropped when coarsened.
  void onTopologyChanged();

  std::size_t regionCount() const { return regions_.size(); }
  std::size_t refinedTriangleCount() const;
  std::size_t fineSpringsInUse() const { return springs_in_use_; }
  std::size_t virtualNodeCount() const { return virtual_slots_.size(); }
  const RefinementConfig& config() const { return config_; }

  // Eqs. 5.16–5.18.
  static std::size_t nodesPerTriangle(int level);
  static std::size_t springsPerTriangle(int level);
  static std::size_t trianglesPerTriangle(int level);

 private:
  struct CoarseTriangle {
    std::array<std::uint64_t, 3> corners{};  // node ids, in the triangle's order
    std::array<double, 3> rest{};            // rest lengths of edges c0c1, c1c2, c2c0
    std::array<double, 3> stiffness{};
    std::array<double, 3> mass_share{};  // of each corner's original mass
    double mass = 0.0;                   // Σ mass_share
    bool refined = false;
    bool alive = true;  // false once cut
    int region = -1;
    std::vector<std::uint64_t> lattice;  // refined: node id per lattice point (i, j), see latticeIndex()
  };
  struct Edge {
    std::vector<std::uint64_t> nodes;  // interior lattice nodes from the smaller-id end to the larger
    int refined_users = 0;
    int coarse_users = 0;
    double rest = 0.0, stiffness = 0.0;
  };
  struct Region {
    std::uint64_t time = 0;
    std::vector<std::size_t> triangles;
  };

  void refineTriangle(std::size_t index);
  void coarsenTriangle(std::size_t index);
  void coarsenRegion(int region);
  mge::Node* nodeById(std::uint64_t id) const;
  bool cornersAlive(std::size_t index) const;
  Eigen::Vector3d centroid(std::size_t index) const;
  bool springBetweenCorners(const CoarseTriangle& coarse, mge::Spring& spring) const;
  mge::Triangle* findCoarseTriangle(const CoarseTriangle& coarse) const;
  void recomputeMassesAndVirtuals();
  std::uint64_t edgeKey(std::uint64_t a, std::uint64_t b) const;
  std::size_t latticeIndex(int i, int j) const;
  void rebuildIdMap();

  mge::Membrane* membrane_;
  RefinementConfig config_;
  int segments_ = 1;  // 2ⁿ
  std::vector<CoarseTriangle> coarse_;
  std::map<std::pair<std::uint64_t, std::uint64_t>, Edge> edges_;
  std::unordered_map<std::uint64_t, double> original_mass_;  // coarse corner node id → mass
  std::unordered_map<std::uint64_t, bool> original_fixed_;
  std::map<int, Region> regions_;
  int next_region_ = 0;
  std::size_t springs_in_use_ = 0;
  // Node id → element, kept up to date through refinement and coarsening (rebuilt after external changes).
  std::unordered_map<std::uint64_t, mge::Node*> node_of_;
  std::vector<std::array<mge::Node*, 3>> corner_nodes_;  // per coarse triangle; nullptr = cut away
  struct VirtualNode {
    std::uint32_t node, a, b;
    double w;
  };
  std::vector<VirtualNode> virtual_slots_;
};

}  // namespace tissue
}  // namespace vrm_sim
