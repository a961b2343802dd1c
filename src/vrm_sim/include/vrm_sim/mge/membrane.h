#pragma once
// A deformable membrane as an MGE subgraph (thesis Fig. 3.1): a Transform (scene graph) → Tissue g2 → all nodes,
// springs and triangles; springs and triangles share the node elements. Next to the graph the membrane keeps the
// contiguous arrays that solvers and the renderer sweep over (§3.3.2): node positions / velocities / masses / fixed
// flags, spring node-slot pairs / rest lengths / stiffnesses, triangle node-slot triples. Removal (cutting, tearing)
// keeps graph and arrays consistent: array removal moves the last entry into the hole, and a moved node's springs
// and triangles — found through the reference edges, no search — get its new slot.

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_sim/mge/array_manager.h"
#include "vrm_sim/mge/elements.h"
#include "vrm_sim/mge/graph.h"
#include "vrm_sim/mge/list_access.h"
#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace mge {

struct MembraneOptions {
  // Total mass [kg], lumped onto the nodes with one third of each triangle's area (uniform if the area is zero).
  double total_mass = 1.0e-6;
  double stretch_stiffness = 1.0;  // [N/m], springs on mesh edges
  // Bending springs between the two opposite corners of every interior edge (an edge shared by two triangles).
  bool bending_springs = false;
  double bending_stiffness = 0.1;  // [N/m]
  // kDual: Node::position() etc. work on per-node copies and NodeArrays::sync() publishes them (thesis §3.3.2).
  StorageMode node_storage = StorageMode::kArray;
};

// What removeElements() took out of the membrane.
struct RemovalSummary {
  std::size_t nodes = 0, springs = 0, triangles = 0;
  double mass = 0.0;  // of the removed nodes [kg]
  bool any() const { return nodes + springs + triangles > 0; }
};

struct CutOptions {
  // Remove edge springs that no longer belong to any triangle (so no invisible spring is left in a cut).
  bool remove_orphan_springs = true;
  // Remove corner nodes left without springs and triangles.
  bool remove_orphan_nodes = false;
};

// The membrane's whole state in slot order (issue 39 §1, a checkpoint's tissue part): every node, spring and triangle
// with its id, its array values and its links, and the graph's next id. Restore() rebuilds a membrane whose slots,
// ids, arrays and every neighbour list equal the snapshot's, so later cuts, tears and refinement (which pick and
// remove elements by slot and by id) go on exactly as in the membrane it was taken from. What it leaves out is not
// semantic: the order of the label ranges inside an element's adjacency block, spare capacity, the arena.
// Why this is enough: every list the simulation builds is in creation (= id) order — the tissue's element lists, a
// node's springs and triangles, a spring's triangles — or positional (a spring's two ends, a triangle's corners, its
// edge and bending springs), and removal keeps the order of the rest (doc/checkpoint_state_inventory.md §3).
struct MembraneSnapshot {
  std::uint64_t transform_id = 0, tissue_id = 0;
  std::uint64_t next_id = 0;  // Graph::nextId() of the membrane's graph
  // Per node slot.
  std::vector<std::uint64_t> node_ids;
  std::vector<Eigen::Vector3d> positions, velocities;
  std::vector<double> masses;
  std::vector<std::uint8_t> fixed;
  // Per spring slot.
  std::vector<std::uint64_t> spring_ids;
  std::vector<std::array<std::uint32_t, 2>> spring_ends;  // node slots, in the spring's order
  std::vector<double> rest_lengths, stiffnesses;
  std::vector<std::uint8_t> bending;
  // Per triangle slot; its links are triangle_links[triangle_link_offsets[t] .. triangle_link_offsets[t + 1]): the
  // spring slots of its edge springs (the first triangle_edge_springs[t]), then of its bending springs, in list order.
  std::vector<std::uint64_t> triangle_ids;
  std::vector<std::array<std::uint32_t, 3>> triangle_corners;  // node slots
  std::vector<std::uint8_t> triangle_edge_springs;
  std::vector<std::uint32_t> triangle_link_offsets;  // triangle count + 1 entries
  std::vector<std::uint32_t> triangle_links;

  std::size_t nodeCount() const { return node_ids.size(); }
  std::size_t springCount() const { return spring_ids.size(); }
  std::size_t triangleCount() const { return triangle_ids.size(); }

  void transferState(StateArchive& archive) {
    archive.section("membrane");
    archive(transform_id)(tissue_id)(next_id)(node_ids)(positions)(velocities)(masses)(fixed)(spring_ids)(spring_ends);
    archive(rest_lengths)(stiffnesses)(bending)(triangle_ids)(triangle_corners)(triangle_edge_springs);
    archive(triangle_link_offsets)(triangle_links);
  }
};

class Membrane {
 public:
  // An empty membrane in its own graph.
  explicit Membrane(const MembraneOptions& options = {});
  // An empty membrane in a shared graph (e.g. the scene's), which must outlive the membrane.
  explicit Membrane(Graph& graph, const MembraneOptions& options = {});
  Membrane(const Membrane&) = delete;
  Membrane& operator=(const Membrane&) = delete;
  // Destroys all of the membrane's elements (removing their edges from a shared graph).
  ~Membrane();

  Graph& graph() { return *graph_; }
  const Graph& graph() const { return *graph_; }
  Tissue& tissue() { return *tissue_; }
  Transform& transform() { return *transform_; }
  const MembraneOptions& options() const { return options_; }

  // Element views in insertion order (the order in the arrays is slot order, see the accessors below).
  ListAccess<Node> nodes() { return tissue_->nodes(); }
  ListAccess<Spring> springs() { return tissue_->springs(); }
  ListAccess<Triangle> triangles() { return tissue_->triangles(); }

  std::size_t nodeCount() const { return node_arrays_.size(); }
  std::size_t springCount() const { return spring_arrays_.size(); }
  std::size_t triangleCount() const { return triangle_arrays_.size(); }

  // Contiguous arrays in slot order, for solvers and the renderer.
  NodeArrays& nodeArrays() { return node_arrays_; }
  const NodeArrays& nodeArrays() const { return node_arrays_; }
  Eigen::Vector3d* positions() { return node_arrays_.data<kNodePosition>(); }
  Eigen::Vector3d* velocities() { return node_arrays_.data<kNodeVelocity>(); }
  const double* masses() const { return node_arrays_.data<kNodeMass>(); }
  const std::uint8_t* fixedFlags() const { return node_arrays_.data<kNodeFixed>(); }
  const SpringArrays& springArrays() const { return spring_arrays_; }
  const std::array<std::uint32_t, 2>* springNodeSlots() const { return spring_arrays_.data<kSpringNodeSlots>(); }
  // Writable: plasticity lets the rest length follow the maximum length reached (§5.1).
  double* restLengths() { return spring_arrays_.data<kSpringRestLength>(); }
  double* stiffnesses() { return spring_arrays_.data<kSpringStiffness>(); }
  const std::array<std::uint32_t, 3>* triangleNodeSlots() const { return triangle_arrays_.data(); }
  Node& nodeAtSlot(std::size_t slot) const { return static_cast<Node&>(*node_arrays_.ownerAt(slot)); }
  Spring& springAtSlot(std::size_t slot) const { return static_cast<Spring&>(*spring_arrays_.ownerAt(slot)); }
  Triangle& triangleAtSlot(std::size_t slot) const { return static_cast<Triangle&>(*triangle_arrays_.ownerAt(slot)); }

  // Construction (used by buildMembrane and by local refinement).
  void reserve(std::size_t nodes, std::size_t springs, std::size_t triangles);
  Node& addNode(const Eigen::Vector3d& position, double mass, bool fixed = false);
  // rest_length defaults to the current distance of the two nodes.
  Spring& addSpring(Node& first, Node& second, double stiffness, bool bending = false,
                    std::optional<double> rest_length = std::nullopt);
  // Corners in order (the order gives the normal); throws std::invalid_argument for repeated corners.
  Triangle& addTriangle(Node& first, Node& second, Node& third);
  void linkEdgeSpring(Triangle& triangle, Spring& spring);
  void linkBendingSpring(Triangle& triangle, Spring& spring);

  // Removal (cutting, tearing). References to removed elements become invalid.
  void removeSpring(Spring& spring);
  // Also removes the triangle's bending springs, and per `options` orphaned edge springs and corner nodes.
  void removeTriangle(Triangle& triangle, const CutOptions& options = {});
  // Removes the node with all its triangles (as removeTriangle with default options) and springs.
  void removeNode(Node& node);
  // One topology change (a cut, a tear) in a single consistent batch: the given triangles, springs and nodes, plus
  // everything that only made sense with them — all triangles of the nodes, the bending springs of every removed
  // triangle, edge springs whose triangles are all removed, all springs of the nodes, and (with
  // remove_isolated_nodes) nodes left with neither springs nor triangles. The whole set is determined before the
  // first element goes, so overlapping inputs (a spring given and also orphaned) are removed exactly once. Repeated
  // entries are allowed.
  RemovalSummary removeElements(const std::vector<Triangle*>& triangles, const std::vector<Spring*>& springs,
                                const std::vector<Node*>& nodes, bool remove_isolated_nodes = true);

  // Fills `snapshot` with this membrane's state (its vectors keep their capacity, so a periodic checkpoint allocates
  // nothing once they have their size). O(elements), no graph change. Reads the arrays: in kDual mode, sync() first.
  void takeSnapshot(MembraneSnapshot& snapshot) const;
  // Replaces every node, spring and triangle by the snapshot's, with their ids and slots, and sets the graph's next
  // id. The membrane's transform and tissue element must be the snapshot's (same ids): a snapshot is restored into
  // a membrane built like the one it was taken from (the World rebuilds its scene first). Throws
  // std::invalid_argument naming the first inconsistency (sizes, slots out of range, repeated or colliding ids, a
  // next id not above them, non-finite or negative values) before anything is changed. The tissue element is made
  // anew (same id; detaching 10^5 nodes from the old hub one by one would cost O(n^2)): views bound to tissue() —
  // a ListAccess, NeighbourSlots — must be bound again.
  void restore(const MembraneSnapshot& snapshot);

  // Graph invariants plus: tissue lists and arrays describe the same elements; every array entry belongs to the
  // element whose connector holds that slot; spring/triangle node-slot entries equal the slots of their nodes.
  InvariantReport checkConsistency() const;

 private:
  void initialize();
  // Throws std::invalid_argument unless `element` is in this membrane's tissue list `tissue_label`.
  void requireOwn(const Element& element, Label tissue_label) const;
  void onNodeRelocated(std::size_t slot);
  void destroyAll();

  MembraneOptions options_;
  // Declared before the array managers: on destruction the managers go first and disconnect the elements, so the
  // owned graph can then drop its elements without per-element array bookkeeping.
  std::unique_ptr<Graph> owned_graph_;
  Graph* graph_;
  NodeArrays node_arrays_;
  SpringArrays spring_arrays_;
  TriangleArrays triangle_arrays_;
  Transform* transform_ = nullptr;
  Tissue* tissue_ = nullptr;
};

// Builds a membrane from a triangle mesh: one node per vertex (fixed_vertices pinned), one spring per unique edge,
// optional bending springs across interior edges, one triangle per mesh triangle. Throws std::invalid_argument for
// out-of-range or repeated vertex indices.
std::unique_ptr<Membrane> buildMembrane(const TriangleMesh& mesh, const MembraneOptions& options = {});
std::unique_ptr<Membrane> buildMembrane(Graph& graph, const TriangleMesh& mesh, const MembraneOptions& options = {});

}  // namespace mge
}  // namespace vrm_sim
