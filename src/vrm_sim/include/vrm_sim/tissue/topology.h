#pragma once
// Topology changes of a membrane (issue 3): cutting with the vitrector and tearing of over-stretched springs. Both
// select elements on the contiguous arrays and hand them to mge::Membrane::removeElements(), which removes them and
// everything that only made sense with them in one batch, so the MGE graph, the node / spring / triangle arrays and
// the render mesh (built from triangleNodeSlots()) stay consistent. Thesis §5.2.4 (last paragraph): a cut deletes
// whole elements; nothing is re-meshed, so the complexity of the tissue never grows through topology changes.

#include <cstddef>
#include <limits>

#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/contact.h"

namespace vrm_sim {
namespace tissue {

// Distance from `point` to the segment a–b (a == b: to the point a).
double segmentDistance(const Eigen::Vector3d& point, const Eigen::Vector3d& a, const Eigen::Vector3d& b);

// Removes the tissue inside the capsule (a sphere if a == b): every node within `radius` of the segment (with all its
// triangles and springs), every triangle whose centroid is inside, then orphaned edge springs and nodes left without
// springs and triangles. A capsule with a non-finite point or radius, or radius <= 0, cuts nothing.
mge::RemovalSummary cutCapsule(mge::Membrane& membrane, const Capsule& capsule);

struct TearResult {
  std::size_t broken_springs = 0;  // springs that exceeded the threshold
  mge::RemovalSummary removed;     // including the broken springs
};

// Every stretch (non-bending) spring longer than tear_strain · rest length breaks; the triangles that use a broken
// spring as an edge go with it (with their bending springs and orphaned edges), and nodes left without springs and
// triangles are removed. tear_strain <= 0 or non-finite disables tearing. Springs with a zero rest length or a
// non-finite length never break (the latter is the stability watchdog's business).
// `pressed` (optional, one flag per node slot): springs at a node an instrument presses or holds in this step do not
// break up to `bound` (strainBound(), issue 40) — a blunt push dents tissue for one step, and tissue tears beside the
// jaws, not in them — but no spring stays beyond the bound: past it they break too.
// `over_last_step` (optional, one flag per spring slot, read and rewritten): a spring breaks at the tear strain only if
// it was past it at the end of the previous step too (a one-step transient of a projection or a contact does not
// tear; a pull that holds the stretch does, one step later); past `bound` it breaks at once.
TearResult tearOverstretched(mge::Membrane& membrane, double tear_strain, const std::uint8_t* pressed = nullptr,
                             double bound = std::numeric_limits<double>::infinity(),
                             std::vector<std::uint8_t>* over_last_step = nullptr);

struct TopologyCheckOptions {
  bool allow_isolated_nodes = false;  // a fresh chain / mesh may have none anyway
};

// Membrane::checkConsistency() plus what a topology change must not break: finite positions and velocities,
// non-negative finite masses; every triangle links exactly three edge springs, spanning its three corner pairs;
// every bending spring is linked by exactly two triangles; no spring or triangle repeats a node; (optionally) no node
// without springs and triangles.
mge::InvariantReport checkTopology(const mge::Membrane& membrane, const TopologyCheckOptions& options = {});

}  // namespace tissue
}  // namespace vrm_sim
