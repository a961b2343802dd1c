#include "vrm_sim/tissue/topology.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>
#include <vector>

#include "vrm_sim/tissue/system.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {

namespace {
constexpr std::uint32_t kNoSlot = 0xffffffffu;
}  // namespace

double segmentDistance(const Eigen::Vector3d& point, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d axis = b - a;
  const double length2 = axis.squaredNorm();
  const double s = length2 > 0.0 ? std::clamp((point - a).dot(axis) / length2, 0.0, 1.0) : 0.0;
  return (point - (a + s * axis)).norm();
}

mge::RemovalSummary cutCapsule(mge::Membrane& membrane, const Capsule& capsule) {
  if (!(capsule.radius > 0.0) || !std::isfinite(capsule.radius) || !capsule.a.allFinite() || !capsule.b.allFinite()) {
    return {};
  }
  const Eigen::Vector3d* x = membrane.positions();
  std::vector<mge::Node*> nodes;
  for (std::size_t i = 0; i < membrane.nodeCount(); ++i) {
    if (segmentDistance(x[i], capsule.a, capsule.b) <= capsule.radius) nodes.push_back(&membrane.nodeAtSlot(i));
  }
  // A capsule thinner than the mesh spacing may hold no node but still cut through triangles.
  std::vector<mge::Triangle*> triangles;
  const std::array<std::uint32_t, 3>* corners = membrane.triangleNodeSlots();
  for (std::size_t t = 0; t < membrane.triangleCount(); ++t) {
    const Eigen::Vector3d centroid = (x[corners[t][0]] + x[corners[t][1]] + x[corners[t][2]]) / 3.0;
    if (segmentDistance(centroid, capsule.a, capsule.b) <= capsule.radius) {
      triangles.push_back(&membrane.triangleAtSlot(t));
    }
  }
  if (nodes.empty() && triangles.empty()) return {};
  return membrane.removeElements(triangles, {}, nodes);
}

TearResult tearOverstretched(mge::Membrane& membrane, double tear_strain, const std::uint8_t* pressed, double bound,
                             std::vector<std::uint8_t>* over_last_step) {
  TearResult result;
  if (!(tear_strain > 0.0) || !std::isfinite(tear_strain)) return result;
  const Eigen::Vector3d* x = membrane.positions();
  const std::array<std::uint32_t, 2>* ends = membrane.springNodeSlots();
  const double* rest = membrane.restLengths();
  if (over_last_step != nullptr) over_last_step->resize(membrane.springCount(), 0);
  std::vector<mge::Spring*> broken;
  for (std::size_t s = 0; s < membrane.springCount(); ++s) {
    if (!(rest[s] >= kMinSpringLength)) continue;
    const double length = (x[ends[s][1]] - x[ends[s][0]]).norm();
    const bool over = length > tear_strain * rest[s] && std::isfinite(length);
    if (over_last_step != nullptr) {
      const bool was_over = (*over_last_step)[s] != 0;
      (*over_last_step)[s] = over ? 1 : 0;
      if (over && !was_over && !(length > bound * rest[s])) continue;
    }
    if (!over) continue;
    if (pressed != nullptr && (pressed[ends[s][0]] || pressed[ends[s][1]]) && !(length > bound * rest[s])) continue;
    mge::Spring& spring = membrane.springAtSlot(s);
    if (!spring.bending()) broken.push_back(&spring);
  }
  if (broken.empty()) return result;
  result.broken_springs = broken.size();
  // The triangles that used a broken spring as an edge cannot stay: their edge is gone.
  std::vector<mge::Triangle*> triangles;
  const mge::Label users = mge::referenceLabel(mge::labels::kTriangleEdgeSprings);
  for (mge::Spring* spring : broken) {
    for (std::size_t k = 0; k < spring->neighbourCount(users); ++k) {
      triangles.push_back(static_cast<mge::Triangle*>(spring->neighbour(users, k)));
    }
  }
  result.removed = membrane.removeElements(triangles, broken, {});
  return result;
}

mge::InvariantReport checkTopology(const mge::Membrane& membrane, const TopologyCheckOptions& options) {
  mge::InvariantReport report = membrane.checkConsistency();
  if (!report.ok()) return report;
  auto fail = [&report](const std::string& what) { report.errors.push_back(what); };
  const std::size_t n = membrane.nodeCount();
  const mge::NodeArrays& nodes = membrane.nodeArrays();
  for (std::size_t i = 0; i < n; ++i) {
    const std::string which = "node " + std::to_string(i);
    if (!nodes.at<mge::kNodePosition>(i).allFinite()) fail(which + ": non-finite position");
    if (!nodes.at<mge::kNodeVelocity>(i).allFinite()) fail(which + ": non-finite velocity");
    const double mass = nodes.at<mge::kNodeMass>(i);
    if (!(mass >= 0.0) || !std::isfinite(mass)) fail(which + ": invalid mass");
    const mge::Node& node = membrane.nodeAtSlot(i);
    if (!options.allow_isolated_nodes && node.neighbourCount(mge::referenceLabel(mge::labels::kSpringNodes)) == 0 &&
        node.neighbourCount(mge::referenceLabel(mge::labels::kTriangleNodes)) == 0) {
      fail(which + ": isolated (no springs, no triangles)");
    }
  }
  const std::array<std::uint32_t, 2>* spring_ends = membrane.springNodeSlots();
  for (std::size_t s = 0; s < membrane.springCount(); ++s) {
    if (spring_ends[s][0] == spring_ends[s][1]) fail("spring " + std::to_string(s) + " repeats a node");
    const mge::Spring& spring = membrane.springAtSlot(s);
    const std::size_t users = spring.neighbourCount(mge::referenceLabel(mge::labels::kTriangleBendingSprings));
    if (spring.bending() && users != 2) {
      fail("bending spring " + std::to_string(s) + " linked by " + std::to_string(users) + " triangles");
    }
  }
  const std::array<std::uint32_t, 3>* corners = membrane.triangleNodeSlots();
  for (std::size_t t = 0; t < membrane.triangleCount(); ++t) {
    const std::string which = "triangle " + std::to_string(t);
    const auto& c = corners[t];
    if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) fail(which + " repeats a node");
    const mge::Triangle& triangle = membrane.triangleAtSlot(t);
    const std::vector<mge::Element*> edges = triangle.neighbours(mge::labels::kTriangleEdgeSprings);
    if (edges.size() != 3) {
      fail(which + " has " + std::to_string(edges.size()) + " edge springs");
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      const auto* spring = static_cast<const mge::Spring*>(edges[k]);
      const auto& e = spring_ends[spring->slot()];
      const std::uint32_t p = c[k], q = c[(k + 1) % 3];
      if (!((e[0] == p && e[1] == q) || (e[0] == q && e[1] == p))) fail(which + ": edge spring off its edge");
    }
  }
  return report;
}

// ---------------------------------------------------------------------------------------------------------------------
// TissueSimulator hooks (declared in tissue_simulator.h; here so that the topology code stays in one place).

std::vector<std::uint64_t> TissueSimulator::graspedNodeIds() const {
  std::vector<std::uint64_t> ids;
  for (const Grasp& grasp : grasps_) {
    for (std::uint32_t node : grasp.nodes) ids.push_back(membrane_->nodeAtSlot(node).id());
  }
  return ids;
}

void TissueSimulator::finishRemoval(const std::vector<std::uint64_t>& grasped_ids) {
  // Slots moved: grasps are kept by node identity (a cut next to the jaws must not drop the grasped tissue).
  const std::vector<Grasp> before = grasps_;
  if (refinement_) refinement_->onTopologyChanged();  // virtual nodes' fixed flags before the constraints
  onTopologyChanged();
  ++statistics_.topology_changes;
  if (grasped_ids.empty()) return;
  std::unordered_map<std::uint64_t, std::uint32_t> slot_of;
  for (std::uint64_t id : grasped_ids) slot_of.emplace(id, kNoSlot);
  for (std::size_t i = 0; i < membrane_->nodeCount(); ++i) {
    auto found = slot_of.find(membrane_->nodeAtSlot(i).id());
    if (found != slot_of.end()) found->second = static_cast<std::uint32_t>(i);
  }
  std::size_t next = 0;
  for (std::size_t g = 0; g < before.size() && g < grasps_.size(); ++g) {
    grasps_[g].active = before[g].active;
    for (std::size_t k = 0; k < before[g].nodes.size(); ++k) {
      const std::uint32_t slot = slot_of[grasped_ids[next++]];
      if (slot == kNoSlot) continue;  // cut away
      grasps_[g].nodes.push_back(slot);
      grasps_[g].local.push_back(before[g].local[k]);
      grasped_[slot] = 1;
    }
  }
  rebuildConstraints();
}

void TissueSimulator::topologyBeforeStep() {
  for (const InstrumentInput& instrument : current_instruments_) {
    if (!instrument.cuts || !(instrument.cut_radius > 0.0)) continue;
    Capsule volume;
    volume.radius = instrument.cut_radius;
    volume.a = instrument.pose * Eigen::Vector3d(0.0, 0.0, -instrument.cut_offset);
    volume.b =
        instrument.pose * Eigen::Vector3d(0.0, 0.0, -(instrument.cut_offset + std::max(instrument.cut_length, 0.0)));
    const std::vector<std::uint64_t> grasped_ids = graspedNodeIds();
    const mge::RemovalSummary removed = cutCapsule(*membrane_, volume);
    if (!removed.any()) continue;
    statistics_.cut_nodes += removed.nodes;
    statistics_.removed_nodes += removed.nodes;
    finishRemoval(grasped_ids);
  }
  if (refinement_) {
    for (const InstrumentInput& instrument : current_instruments_) {
      const std::vector<std::uint64_t> grasped_ids = graspedNodeIds();
      if (refinement_->refineAt(instrument.pose.translation(), statistics_.steps + 1)) finishRemoval(grasped_ids);
    }
  }
}

std::size_t TissueSimulator::adhesionPoints() const { return forces_.anchors.size(); }

void TissueSimulator::releaseOverloadedAdhesions() {
  if (forces_.anchors.empty()) return;
  const Eigen::Vector3d* x = membrane_->positions();
  for (const Anchor& anchor : forces_.anchors) {
    statistics_.max_adhesion_force =
        std::max(statistics_.max_adhesion_force, anchor.stiffness * (x[anchor.node] - anchor.point).norm());
  }
  if (!(config_.adhesion_break_force > 0.0)) return;
  const auto before = forces_.anchors.size();
  const bool tears = config_.adhesion_tear_force > 0.0;
  forces_.anchors.erase(std::remove_if(forces_.anchors.begin(), forces_.anchors.end(),
                                       [&](Anchor& anchor) {
                                         const double force = anchor.stiffness * (x[anchor.node] - anchor.point).norm();
                                         const bool torn = tears && force > config_.adhesion_tear_force;
                                         if (torn) {
                                           ++statistics_.adhesion_tears;
                                           adhesion_tear_points_.push_back(anchor.point);
                                         } else if (!(force > config_.adhesion_break_force)) {
                                           anchor.overloaded_for = 0.0;
                                           return false;
                                         } else if (config_.adhesion_release_time > 0.0) {
                                           // Peeling takes time: it lets go once overloaded long enough.
                                           anchor.overloaded_for += config_.dt;
                                           if (anchor.overloaded_for < config_.adhesion_release_time) return false;
                                         }
                                         // For good: a later topology change rebuilds anchors from the fixed flags.
                                         anchored_[anchor.node] = 0;
                                         membrane_->nodeAtSlot(anchor.node).setFixed(false);
                                         return true;
                                       }),
                        forces_.anchors.end());
  if (forces_.anchors.size() == before) return;
  statistics_.released_adhesions += before - forces_.anchors.size();
  rebuildConstraints();
}

void TissueSimulator::markPressed() {
  pressed_.assign(membrane_->nodeCount(), 0);
  if (frame_pressed_.size() == pressed_.size()) pressed_ = frame_pressed_;
  for (const NodeDeformation& contact : contacts_) {
    if (contact.node < pressed_.size()) pressed_[contact.node] = 1;
  }
  // The jaws hold what they grasped: tissue tears beside them, not inside them (their kinematic pinch would
  // otherwise break the springs it squeezes past in the step it closes).
  for (std::uint32_t node : grasped_nodes_) pressed_[node] = 1;
}

void TissueSimulator::topologyAfterStep() {
  releaseOverloadedAdhesions();
  if (refinement_) refinement_->updateVirtualNodes();
  if (!(config_.tear_strain > 0.0)) return;
  const std::vector<std::uint64_t> grasped_ids = graspedNodeIds();
  markPressed();
  // Issue 40: a pressed spring the bound projection could not bring back within the bound tears too.
  // Issue 40: a stretch past the tear strain tears when it holds for two steps (or at once past the bound).
  const TearResult torn =
      tearOverstretched(*membrane_, config_.tear_strain, pressed_.data(), statistics_.strain_bound, &over_tear_);
  if (torn.broken_springs == 0) return;
  statistics_.torn_springs += torn.broken_springs;
  statistics_.removed_nodes += torn.removed.nodes;
  finishRemoval(grasped_ids);
}

}  // namespace tissue
}  // namespace vrm_sim
