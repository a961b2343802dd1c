#include "vrm_sim/tissue/tissue_simulator.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "vrm_sim/mge/labels.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/mge/neighbour_slots.h"

namespace vrm_sim {
namespace tissue {

InstrumentCapsules instrumentCapsules(const InstrumentInput& instrument) {
  InstrumentCapsules set;
  auto add = [&set](const Capsule& capsule) { set.capsules[set.count++] = capsule; };
  const Eigen::Isometry3d& pose = instrument.pose;
  const double r = instrument.radius;
  if (!instrument.jaws) {
    add({pose * Eigen::Vector3d(0.0, 0.0, -r), pose * Eigen::Vector3d(0.0, 0.0, -std::max(instrument.length, r)), r});
    return set;
  }
  const double hinge_z = -instrument.jaw_length;
  add({pose * Eigen::Vector3d(0.0, 0.0, hinge_z - r),
       pose * Eigen::Vector3d(0.0, 0.0, std::min(hinge_z - r, -std::max(instrument.length, r))), r});
  // Jaw blades from the hinge; the capsule's rounded end stops at the blade's tip.
  const double half_angle = 0.5 * std::clamp(instrument.jaw_angle, 0.0, kMaxJawOpening);
  const double reach = std::max(instrument.jaw_length - instrument.jaw_radius, 0.0);
  for (const double side : {1.0, -1.0}) {
    const Eigen::Vector3d direction(0.0, side * std::sin(half_angle), std::cos(half_angle));
    const Eigen::Vector3d hinge(0.0, 0.0, hinge_z);
    add({pose * hinge, pose * Eigen::Vector3d(hinge + reach * direction), instrument.jaw_radius});
  }
  return set;
}

Eigen::Isometry3d interpolatePose(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to, double alpha) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  const Eigen::Quaterniond q0(from.rotation());
  const Eigen::Quaterniond q1(to.rotation());
  pose.linear() = q0.slerp(alpha, q1).toRotationMatrix();
  pose.translation() = (1.0 - alpha) * from.translation() + alpha * to.translation();
  return pose;
}

struct TissueSimulator::GraphAdjacency {
  using NodeSprings = mge::NeighbourSlots<mge::Node, mge::Spring>;
  explicit GraphAdjacency(mge::Membrane& membrane)
      : node_springs(membrane.tissue(), mge::labels::kNodeList, {mge::referenceLabel(mge::labels::kSpringNodes)},
                     NodeSprings::Layout::kSlotOrder) {}
  NodeSprings node_springs;
};

TissueSimulator::TissueSimulator(mge::Membrane& membrane, const TissueConfig& config)
    : membrane_(&membrane), config_(config) {
  if (!(config_.dt > 0.0) || !std::isfinite(config_.dt)) {
    throw std::invalid_argument("tissue: dt must be positive, got " + std::to_string(config_.dt));
  }
  auto_integrator_ = config_.integrator == kAutoIntegrator;
  // "auto" starts with the explicit candidate its registry entry builds; onTopologyChanged() below decides.
  integrator_ = makeIntegrator(config_.integrator, config_.integrator_options);
  choice_.integrator = integrator_->name();
  choice_.reason = "configured";
  forces_.params = config_.forces;
  model_ = tissueModelRegistry().at(config_.model).make(membrane, config_);
  statistics_.strain_bound = model_->strainBound();
  graph_adjacency_ = std::make_unique<GraphAdjacency>(membrane);
  onTopologyChanged();
  if (config_.repair_massless_nodes) repairMasslessNodes();
  if (config_.refinement.levels > 0) {
    if (!model_->supportsRefinement() || config_.adhesion_stiffness > 0.0) {
      throw std::invalid_argument(std::string("tissue: refinement is not supported by the ") + model_->name() +
                                  " model" + (model_->supportsRefinement() ? " with adhesion" : ""));
    }
    refinement_ = std::make_unique<LocalRefinement>(membrane, config_.refinement);
  }
  checkNodes();
  if (config_.fluid_modulus > 0.0) {
    if (!(config_.fluid_wall_radius > 0.0) || !std::isfinite(config_.fluid_wall_radius)) {
      throw std::invalid_argument("tissue: fluid_modulus needs a positive fluid_wall_radius");
    }
    rest_enclosed_volume_ = enclosedVolume();
  }
}

void TissueSimulator::repairMasslessNodes() {
  // Degenerate input: a node only in zero-area triangles got no lumped mass; give it the mean node mass.
  double total = 0.0;
  for (std::size_t i = 0; i < membrane_->nodeCount(); ++i) total += membrane_->masses()[i];
  const double mean = membrane_->nodeCount() > 0 ? total / static_cast<double>(membrane_->nodeCount()) : 0.0;
  for (std::size_t i = 0; i < membrane_->nodeCount(); ++i) {
    if (!(membrane_->masses()[i] > 0.0)) membrane_->nodeAtSlot(i).mass() = mean;
  }
  rebuildConstraints();  // the free mass and the "auto" choice depend on the masses
}

void TissueSimulator::checkNodes() {
  const SystemView system = view();
  for (std::size_t i = 0; i < system.node_count; ++i) {
    if (!system.positions[i].allFinite()) {
      throw std::invalid_argument("tissue: node " + std::to_string(i) + " has a non-finite position");
    }
    if (system.isFree(i) && !(system.masses[i] > 0.0 && std::isfinite(system.masses[i]))) {
      throw std::invalid_argument("tissue: free node " + std::to_string(i) +
                                  " has no positive mass (a node only in zero-area triangles?)");
    }
  }
}

TissueSimulator::~TissueSimulator() = default;

void TissueSimulator::onTopologyChanged() {
  const std::size_t n = membrane_->nodeCount();
  over_tear_.assign(membrane_->springCount(), 0);  // spring slots are renumbered
  grasped_.assign(n, 0);
  for (Grasp& grasp : grasps_) grasp = Grasp{};
  grasped_nodes_.clear();
  anchored_.assign(n, 0);
  forces_.anchors.clear();
  const std::uint8_t* fixed = membrane_->fixedFlags();
  if (config_.adhesion_stiffness > 0.0) {
    for (std::size_t i = 0; i < n; ++i) {
      if (!fixed[i]) continue;
      anchored_[i] = 1;
      forces_.anchors.push_back({static_cast<std::uint32_t>(i), membrane_->positions()[i], config_.adhesion_stiffness});
    }
  }
  forces_.triangles = membrane_->triangleNodeSlots();
  forces_.triangle_count = membrane_->triangleCount();
  if (!forces_.external.empty()) forces_.external.resize(n, Eigen::Vector3d::Zero());
  if (config_.fluid_modulus > 0.0) {
    // Slots moved: the fluid is where no adhesion holds any more.
    wet_.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) wet_[i] = anchored_[i] ? 0 : 1;
    forces_.pressure_mask = nullptr;  // spreadFluid() rebuilds it before the next step
  }
  interaction_points_.clear();
  // Deformation vectors address node slots of the old topology.
  external_deformations_.clear();
  interaction_stamp_.assign(n, 0);
  if (!frame_pressed_.empty()) frame_pressed_.assign(n, 0);  // slots moved: the marks would name other nodes
  touched_.assign(n, 0);
  sorted_seeds_.clear();
  sorted_valid_ = false;
  rebuildConstraints();
  GraphAdjacency::NodeSprings& node_springs = graph_adjacency_->node_springs;
  node_springs.refresh(membrane_->graph(), membrane_->nodeArrays(), membrane_->springArrays());
  adjacency_.adopt(view(), node_springs.offsets(), node_springs.neighbourSlots());
  sorter_.rebuild(view(), adjacency_);
  model_->onTopologyChanged(*this);
}

void TissueSimulator::rebuildConstraints() {
  updateConstraintFlags();
  if (auto_integrator_) chooseIntegratorNow();
}

void TissueSimulator::updateConstraintFlags() {
  const std::size_t n = membrane_->nodeCount();
  constrained_.resize(n);
  const std::uint8_t* fixed = membrane_->fixedFlags();
  for (std::size_t i = 0; i < n; ++i) constrained_[i] = ((fixed[i] && !anchored_[i]) || grasped_[i]) ? 1 : 0;
  grasped_nodes_.clear();
  free_mass_ = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (grasped_[i]) grasped_nodes_.push_back(static_cast<std::uint32_t>(i));
    if (constrained_[i] == 0) free_mass_ += membrane_->masses()[i];
  }
}

void TissueSimulator::chooseIntegratorNow() {
  // What the steps so far did: deterministic counts, so a replay decides the same.
  const TissueWork& work = statistics_.work;
  ObservedWork observed;
  if (work.implicit_integrations > 0) {
    observed.cg_iterations = static_cast<double>(work.cg_iterations) / static_cast<double>(work.implicit_integrations);
  }
  if (work.integrations > 0) {
    observed.bound_sweeps = static_cast<double>(work.bound_sweeps) / static_cast<double>(work.integrations);
  }
  AutoIntegratorOptions options = config_.auto_integrator;
  // Substeps on trial need the watchdog to judge them.
  if (!config_.watchdog.enabled) options.trials = false;
  IntegratorChoice choice = chooseIntegrator(view(), forces_, config_.dt, options, &choice_scratch_, observed,
                                             config_.integrator_options.cg_max_iterations);
  const bool changed =
      choice.integrator != choice_.integrator || choice.substeps != choice_.substeps || choice_changes_ == 0;
  if (choice.integrator != integrator_->name()) {
    integrator_ = makeIntegrator(choice.integrator, config_.integrator_options);
  }
  choice_ = std::move(choice);
  if (changed) ++choice_changes_;
}

void TissueSimulator::rejectIntegratorProbe() {
  const int tried = choice_.substeps;
  choice_.probe = false;
  if (choice_.safe_substeps > 0) {
    choice_.substeps = choice_.safe_substeps;
  } else {
    choice_.integrator = "implicit_euler";
    choice_.substeps = 1;
    integrator_ = makeIntegrator(choice_.integrator, config_.integrator_options);
  }
  choice_.reason += "; the watchdog rejected " + std::to_string(tried) + " substeps: " + integratorLabel();
  ++choice_changes_;
}

std::string TissueSimulator::integratorLabel() const {
  return choice_.substeps > 1 ? choice_.integrator + " x" + std::to_string(choice_.substeps) : choice_.integrator;
}

void TissueSimulator::setInstruments(const std::vector<InstrumentInput>& instruments) {
  if (previous_instruments_.size() != instruments.size()) {
    // New instrument set: no motion to interpolate from.
    previous_instruments_ = instruments;
    current_instruments_ = instruments;
    step_start_poses_.assign(instruments.size(), Eigen::Isometry3d::Identity());
    for (std::size_t i = 0; i < instruments.size(); ++i) step_start_poses_[i] = instruments[i].pose;
    releaseAll();
    grasps_.assign(instruments.size(), Grasp{});
  }
  target_instruments_ = instruments;
}

void TissueSimulator::addDeformations(const std::vector<NodeDeformation>& deformations) {
  external_deformations_.insert(external_deformations_.end(), deformations.begin(), deformations.end());
}

void TissueSimulator::addInteractionPoint(std::uint32_t node) {
  if (node >= interaction_stamp_.size()) return;
  if (interaction_stamp_[node] == 0) interaction_points_.push_back(node);
  interaction_stamp_[node] = statistics_.steps + 1;
}

void TissueSimulator::releaseAll() {
  for (Grasp& grasp : grasps_) grasp = Grasp{};
  std::fill(grasped_.begin(), grasped_.end(), 0);
  rebuildConstraints();
}

void TissueSimulator::slipGraspedNode(std::uint32_t node) {
  if (node >= grasped_.size() || !grasped_[node]) return;
  grasped_[node] = 0;
  constrained_[node] = membrane_->fixedFlags()[node] && !anchored_[node] ? 1 : 0;
  for (Grasp& grasp : grasps_) {
    for (std::size_t k = 0; k < grasp.nodes.size(); ++k) {
      if (grasp.nodes[k] != node) continue;
      grasp.nodes.erase(grasp.nodes.begin() + static_cast<std::ptrdiff_t>(k));
      grasp.local.erase(grasp.local.begin() + static_cast<std::ptrdiff_t>(k));
      break;
    }
  }
  ++statistics_.slipped_nodes;
}

void TissueSimulator::updateInstruments(double alpha) {
  for (std::size_t i = 0; i < target_instruments_.size(); ++i) {
    step_start_poses_[i] = current_instruments_[i].pose;
    current_instruments_[i] = target_instruments_[i];
    current_instruments_[i].pose = interpolatePose(previous_instruments_[i].pose, target_instruments_[i].pose, alpha);
  }
  for (std::size_t i = 0; i < current_instruments_.size(); ++i) {
    updateGrasp(i, current_instruments_[i], current_instruments_[i].pose, step_start_poses_[i], config_.dt);
  }
}

void TissueSimulator::updateGrasp(std::size_t index, const InstrumentInput& instrument, const Eigen::Isometry3d& pose,
                                  const Eigen::Isometry3d& /*previous_pose*/, double dt) {
  Grasp& grasp = grasps_[index];
  const bool jaws_closed = instrument.can_grasp && instrument.jaw_angle < config_.grasp_jaw_angle;
  const bool closed = jaws_closed || instrument.holds;
  Eigen::Vector3d* x = membrane_->positions();
  Eigen::Vector3d* v = membrane_->velocities();
  if (!jaws_closed && instrument.holds && !grasp.active) {
    // A hold without jaws (suction) takes what is within reach of its point; finding nothing, it retries next step.
    const Eigen::Vector3d centre = pose * instrument.hold_point;
    const Eigen::Isometry3d inverse = pose.inverse();
    for (std::size_t i = 0; i < constrained_.size(); ++i) {
      if (constrained_[i] || (x[i] - centre).norm() > instrument.hold_radius) continue;
      grasp.nodes.push_back(static_cast<std::uint32_t>(i));
      grasp.local.push_back(inverse * x[i]);
      grasped_[i] = 1;
    }
    if (grasp.nodes.empty()) return;
    grasp.active = true;
    rebuildConstraints();
  } else if (closed && !grasp.active) {
    // Thesis §5.1: nodes between the closing jaws are grasped and from now on follow the instrument.
    const Eigen::Vector3d centre = pose * Eigen::Vector3d(0.0, 0.0, -0.5 * instrument.jaw_length);
    const double reach = std::max(config_.grasp_radius, 0.5 * instrument.jaw_length);
    const Eigen::Isometry3d inverse = pose.inverse();
    for (std::size_t i = 0; i < constrained_.size(); ++i) {
      if (constrained_[i] || (x[i] - centre).norm() > reach) continue;
      // Only what lies between the jaws (within the grasp radius of the jaw axis).
      const Eigen::Vector3d local = inverse * x[i];
      if (local.head<2>().norm() > config_.grasp_radius) continue;
      grasp.nodes.push_back(static_cast<std::uint32_t>(i));
      grasp.local.push_back(local);
      grasped_[i] = 1;
    }
    grasp.active = true;
    rebuildConstraints();
  } else if (!closed && grasp.active) {
    for (std::uint32_t node : grasp.nodes) grasped_[node] = 0;
    grasp = Grasp{};
    rebuildConstraints();
  }
  if (!grasp.active) return;
  const bool project = jaws_closed && instrument.jaw_angle < config_.projection_jaw_angle;
  for (std::size_t k = 0; k < grasp.nodes.size(); ++k) {
    if (project) grasp.local[k].y() = 0.0;  // onto the jaws' mid-plane
    const std::uint32_t node = grasp.nodes[k];
    const Eigen::Vector3d target = pose * grasp.local[k];
    v[node] = (target - x[node]) / dt;
    x[node] = target;
    addInteractionPoint(node);
  }
}

void TissueSimulator::sortSprings() {
  // Retire interaction points older than the lifetime (Alg. 5.2 time stamps).
  const std::uint64_t now = statistics_.steps + 1;
  const std::uint64_t lifetime = static_cast<std::uint64_t>(std::max(config_.interaction_lifetime_steps, 1));
  interaction_points_.erase(std::remove_if(interaction_points_.begin(), interaction_points_.end(),
                                           [&](std::uint32_t node) {
                                             if (interaction_stamp_[node] + lifetime >= now) return false;
                                             interaction_stamp_[node] = 0;
                                             return true;
                                           }),
                            interaction_points_.end());
  seeds_.assign(interaction_points_.begin(), interaction_points_.end());
  std::sort(seeds_.begin(), seeds_.end());
  if (seeds_.empty()) {
    sorted_valid_ = false;
    sorted_seeds_.clear();
    return;
  }
  if (!sorted_valid_ || seeds_ != sorted_seeds_) {
    ++statistics_.work.bfs_sorts;
    sorter_.sort(view(), seeds_);
    sorted_seeds_ = seeds_;
    sorted_valid_ = true;
  }
}

std::uint32_t TissueSimulator::markTouched(std::vector<std::uint32_t>& touched, std::uint32_t& epoch) const {
  // Springs at an instrument (contact or grasp) are stretched by the instrument, not by an instability.
  ++epoch;
  touched.resize(membrane_->nodeCount(), 0);
  for (const NodeDeformation& contact : contacts_) {
    if (contact.node < touched.size()) touched[contact.node] = epoch;
  }
  for (std::uint32_t node : grasped_nodes_) touched[node] = epoch;
  return epoch;
}

double TissueSimulator::enclosedVolume() const {
  // Per triangle: the sector of the wall sphere under it (solid angle Ω, Van Oosterom & Strackee 1983) minus the
  // tetrahedron (origin, a, b, c) — the fluid between the triangle and the wall. Triangles facing the origin have
  // a·(b×c) < 0, hence the sign; a triangle resting on the sphere encloses (almost) nothing.
  const double wall = config_.fluid_wall_radius;
  const Eigen::Vector3d* x = membrane_->positions();
  const auto* triangles = membrane_->triangleNodeSlots();
  double volume = 0.0;
  for (std::size_t t = 0; t < membrane_->triangleCount(); ++t) {
    const Eigen::Vector3d& a = x[triangles[t][0]];
    const Eigen::Vector3d& b = x[triangles[t][1]];
    const Eigen::Vector3d& c = x[triangles[t][2]];
    const double triple = a.dot(b.cross(c));
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double denominator = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    const double solid_angle = 2.0 * std::atan2(triple, denominator);
    volume -= wall * wall * wall / 3.0 * solid_angle - triple / 6.0;
  }
  return volume - rest_enclosed_volume_;
}

void TissueSimulator::setFluidSource(const std::optional<Eigen::Vector3d>& point, double radius) {
  if (!point || !point->allFinite()) return;
  const Eigen::Vector3d* x = membrane_->positions();
  wet_.resize(membrane_->nodeCount(), 0);
  for (std::size_t i = 0; i < wet_.size(); ++i) {
    if ((x[i] - *point).norm() <= radius) wet_[i] = 1;
  }
}

void TissueSimulator::spreadFluid() {
  const std::size_t n = membrane_->nodeCount();
  wet_.resize(n, 0);
  // One ring per step: the front moves 1 edge per ms, faster than the adhesions give way. Reached this step = 2, so
  // the ring does not run on within the pass (and nothing is allocated).
  const std::size_t springs = membrane_->springCount();
  const auto* ends = membrane_->springNodeSlots();
  for (std::size_t s = 0; s < springs; ++s) {
    const std::uint32_t a = ends[s][0], b = ends[s][1];
    if (wet_[a] == 1 && wet_[b] == 0 && !anchored_[b]) wet_[b] = 2;
    if (wet_[b] == 1 && wet_[a] == 0 && !anchored_[a]) wet_[a] = 2;
  }
  for (std::uint8_t& wet : wet_) wet = wet != 0 ? 1 : 0;
  const auto* triangles = membrane_->triangleNodeSlots();
  wet_triangles_.assign(membrane_->triangleCount(), 0);
  for (std::size_t t = 0; t < wet_triangles_.size(); ++t) {
    wet_triangles_[t] = wet_[triangles[t][0]] || wet_[triangles[t][1]] || wet_[triangles[t][2]];
  }
  forces_.pressure_mask = wet_triangles_.data();
}

bool TissueSimulator::step() {
  if (config_.fluid_modulus > 0.0) {
    spreadFluid();
    const double mismatch = fluid_volume_ - enclosedVolume();
    const double pressure = config_.fluid_modulus * mismatch / std::max(fluid_volume_, config_.fluid_volume_floor);
    fluid_pressure_ = std::isfinite(pressure) ? std::clamp(pressure, 0.0, config_.fluid_max_pressure) : 0.0;
    forces_.params.pressure = fluid_pressure_;
  }
  const bool ok = model_->step(*this);
  ++statistics_.steps;
  return ok;
}

FrameReport TissueSimulator::advance(double frame_time, const Clock& clock) {
  FrameReport report;
  const double start = clock();
  std::fill(frame_pressed_.begin(), frame_pressed_.end(), 0);
  const std::uint64_t fallbacks_before = statistics_.fallbacks;
  pending_time_ += std::max(frame_time, 0.0);
  report.requested_time = pending_time_;
  const double budget = config_.time_budget_ms * 1e-3;
  const int planned =
      std::min(config_.max_steps_per_frame, static_cast<int>(std::floor(pending_time_ / config_.dt + 1e-9)));
  // Only with resting instruments: a moving one must reach its end-of-frame pose.
  const bool early_stop = config_.early_stop_force > 0.0 && model_->supportsEarlyStop() && instrumentsAtRest();
  for (int s = 0; s < planned; ++s) {
    if (s > 0 && clock() - start >= budget) {
      report.budget_exhausted = true;
      break;
    }
    updateInstruments(static_cast<double>(s + 1) / planned);
    step();
    ++report.steps;
    report.simulated_time += config_.dt;
    if (early_stop && s + 1 < planned && maxFreeForce() < config_.early_stop_force) {
      report.early_stopped = true;
      break;
    }
  }
  if (planned > 0) {
    previous_instruments_ = current_instruments_;
    // Real time: time the budget did not cover is dropped, not owed to the next frame; so is the rest of a frame
    // at equilibrium.
    pending_time_ =
        report.budget_exhausted || report.early_stopped ? 0.0 : std::max(0.0, pending_time_ - report.simulated_time);
  }
  report.wall_time = clock() - start;
  report.fallbacks = static_cast<int>(statistics_.fallbacks - fallbacks_before);
  // The watchdog measured the state after the last step already.
  report.max_strain = maxStrain();
  statistics_.max_strain = std::max(statistics_.max_strain, report.max_strain);
  // Issue 40: what the model's bound projection and the watchdog let through (or a rolled-back step left).
  if (planned > 0 && !(report.max_strain <= statistics_.strain_bound * (1.0 + 1e-9))) ++statistics_.bound_violations;
  return report;
}

double TissueSimulator::maxFreeForce() {
  const SystemView system = view();
  if (early_stop_forces_.size() != system.node_count) {
    early_stop_forces_.resize(system.node_count);
    early_stop_zero_.assign(system.node_count, Eigen::Vector3d::Zero());
  }
  forces_.compute(system, system.positions, early_stop_zero_.data(), early_stop_forces_.data());
  // Nodes at an instrument are held by it: their spring forces stay unbalanced at equilibrium.
  const std::uint32_t epoch = markTouched(touched_, touched_epoch_);
  double max_force2 = 0.0;
  for (std::size_t i = 0; i < system.node_count; ++i) {
    if (system.isFree(i) && touched_[i] != epoch)
      max_force2 = std::max(max_force2, early_stop_forces_[i].squaredNorm());
  }
  return std::sqrt(max_force2);
}

bool TissueSimulator::instrumentsAtRest() const {
  for (std::size_t i = 0; i < target_instruments_.size() && i < previous_instruments_.size(); ++i) {
    const InstrumentInput& now = target_instruments_[i];
    const InstrumentInput& before = previous_instruments_[i];
    if (now.pose.matrix() != before.pose.matrix() || now.jaw_angle != before.jaw_angle) return false;
  }
  return true;
}

double TissueSimulator::maxStrain() { return tissue::maxStrain(view()); }
double TissueSimulator::kineticEnergy() { return tissue::kineticEnergy(view()); }
double TissueSimulator::totalEnergy() {
  const SystemView system = view();
  return tissue::kineticEnergy(system) + forces_.potentialEnergy(system, system.positions);
}

void TissueSimulator::restoreDerived(StateArchive& archive) {
  const std::size_t n = membrane_->nodeCount();
  const std::size_t springs = membrane_->springCount();
  auto per_node = [&](const auto& column, const char* what, bool may_be_empty) {
    if (column.size() != n && !(may_be_empty && column.empty())) {
      archive.fail(std::string(what) + " has " + std::to_string(column.size()) + " entries for " + std::to_string(n) +
                   " nodes");
    }
  };
  per_node(interaction_stamp_, "interaction_stamp", false);
  per_node(wet_, "wet", true);
  per_node(pressed_, "pressed", true);
  per_node(frame_pressed_, "frame_pressed", true);
  if (over_tear_.size() != springs) archive.fail("over_tear does not have one entry per spring");
  for (std::uint32_t node : interaction_points_) {
    if (node >= n) archive.fail("an interaction point beyond the nodes");
  }
  for (const NodeDeformation& deformation : external_deformations_) {
    if (deformation.node >= n) archive.fail("a deformation of a node beyond the nodes");
  }
  grasped_.assign(n, 0);
  for (const Grasp& grasp : grasps_) {
    if (grasp.local.size() != grasp.nodes.size()) archive.fail("a grasp with offsets for other nodes");
    for (std::uint32_t node : grasp.nodes) {
      if (node >= n) archive.fail("a grasped node beyond the nodes");
      grasped_[node] = 1;
    }
  }
  anchored_.assign(n, 0);
  for (const Anchor& anchor : forces_.anchors) {
    if (anchor.node >= n) archive.fail("an adhesion anchor beyond the nodes");
    anchored_[anchor.node] = 1;
  }
  updateConstraintFlags();
  forces_.triangles = membrane_->triangleNodeSlots();
  forces_.triangle_count = membrane_->triangleCount();
  if (!forces_.external.empty()) forces_.external.assign(n, Eigen::Vector3d::Zero());
  forces_.pressure_mask = nullptr;  // spreadFluid() rebuilds it from wet_ before the next step
  touched_.assign(n, 0);
  touched_epoch_ = 0;
  // The membrane's restore made a new tissue element (same id): the view bound to the old one is made anew.
  graph_adjacency_ = std::make_unique<GraphAdjacency>(*membrane_);
  GraphAdjacency::NodeSprings& node_springs = graph_adjacency_->node_springs;
  node_springs.refresh(membrane_->graph(), membrane_->nodeArrays(), membrane_->springArrays());
  adjacency_.adopt(view(), node_springs.offsets(), node_springs.neighbourSlots());
  sorter_.rebuild(view(), adjacency_);
  // A BFS order is a function of its seeds: sorted again from the saved key, so the next step reuses it as the
  // original did (and counts no sort the original did not).
  if (sorted_valid_) {
    for (std::uint32_t node : sorted_seeds_) {
      if (node >= n) archive.fail("a BFS seed beyond the nodes");
    }
    sorter_.sort(view(), sorted_seeds_);
  }
  model_->onTopologyChanged(*this);
}

}  // namespace tissue
}  // namespace vrm_sim
