#include "vrm_sim/tissue/tissue_simulator.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "spring_kernels.h"
#include "vrm_sim/mge/membrane.h"

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
  const double half_angle = 0.5 * std::clamp(instrument.jaw_angle, 0.0, 1.5);
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

TissueSimulator::TissueSimulator(mge::Membrane& membrane, const TissueConfig& config)
    : membrane_(&membrane), config_(config) {
  if (!(config_.dt > 0.0) || !std::isfinite(config_.dt)) {
    throw std::invalid_argument("tissue: dt must be positive, got " + std::to_string(config_.dt));
  }
  auto_integrator_ = config_.integrator == kAutoIntegrator;
  // "auto" starts with the explicit candidate; onTopologyChanged() below decides.
  integrator_ = makeIntegrator(auto_integrator_ ? "symplectic_euler" : config_.integrator, config_.integrator_options);
  choice_.integrator = integrator_->name();
  choice_.reason = "configured";
  IntegratorOptions fallback_options = config_.integrator_options;
  fallback_options.cg_max_iterations = std::max(fallback_options.cg_max_iterations, 50);
  implicit_fallback_ = makeIntegrator("implicit_euler", fallback_options);
  forces_.params = config_.forces;
  if (config_.model == "chainmail") {
    chainmail_ = std::make_unique<ChainMail>(membrane, config_.chainmail);
  } else if (config_.model != "mass_spring") {
    throw std::invalid_argument("tissue: unknown model '" + config_.model + "' (mass_spring | chainmail)");
  }
  onTopologyChanged();
  if (config_.repair_massless_nodes) {
    // Degenerate input: a node only in zero-area triangles got no lumped mass; give it the mean node mass.
    double total = 0.0;
    for (std::size_t i = 0; i < membrane_->nodeCount(); ++i) total += membrane_->masses()[i];
    const double mean = membrane_->nodeCount() > 0 ? total / static_cast<double>(membrane_->nodeCount()) : 0.0;
    for (std::size_t i = 0; i < membrane_->nodeCount(); ++i) {
      if (!(membrane_->masses()[i] > 0.0)) membrane_->nodeAtSlot(i).mass() = mean;
    }
    rebuildConstraints();  // the free mass and the "auto" choice depend on the masses
  }
  if (config_.refinement.levels > 0) {
    if (chainmail_ || config_.adhesion_stiffness > 0.0) {
      throw std::invalid_argument("tissue: refinement needs the mass_spring model without adhesion");
    }
    refinement_ = std::make_unique<LocalRefinement>(membrane, config_.refinement);
  }
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
  interaction_points_.clear();
  // Deformation vectors address node slots of the old topology.
  external_deformations_.clear();
  interaction_stamp_.assign(n, 0);
  if (!frame_pressed_.empty()) frame_pressed_.assign(n, 0);  // slots moved: the marks would name other nodes
  touched_.assign(n, 0);
  sorted_seeds_.clear();
  sorted_valid_ = false;
  rebuildConstraints();
  sorter_.rebuild(view());
  if (chainmail_) {
    chainmail_->rebuild();
    chainmail_committed_.assign(membrane_->positions(), membrane_->positions() + n);
  }
}

void TissueSimulator::rebuildConstraints() {
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
  if (auto_integrator_) chooseIntegratorNow();
}

void TissueSimulator::chooseIntegratorNow() {
  IntegratorChoice choice = chooseIntegrator(view(), forces_, config_.dt, config_.auto_integrator, &choice_scratch_);
  const bool changed =
      choice.integrator != choice_.integrator || choice.substeps != choice_.substeps || choice_changes_ == 0;
  if (choice.integrator != integrator_->name()) {
    integrator_ = makeIntegrator(choice.integrator, config_.integrator_options);
  }
  choice_ = std::move(choice);
  if (changed) ++choice_changes_;
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
  const bool closed = instrument.can_grasp && instrument.jaw_angle < config_.grasp_jaw_angle;
  Eigen::Vector3d* x = membrane_->positions();
  Eigen::Vector3d* v = membrane_->velocities();
  if (closed && !grasp.active) {
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
  const bool project = instrument.jaw_angle < config_.projection_jaw_angle;
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
    sorter_.sort(view(), seeds_);
    sorted_seeds_ = seeds_;
    sorted_valid_ = true;
  }
}

void TissueSimulator::rawStep(Integrator& integrator, double dt) {
  const SystemView system = view();
  if (measure_energy_) {
    // The balance covers the integration only: the strain limit and the contact response that follow are
    // projections (kinematic constraints, the instrument), whose work is given, not created by the integrator.
    // The start energy's spring part comes from the integrator's first force evaluation (at the start state), at
    // almost no cost; XPBD evaluates no spring forces, so it gets a sweep.
    const bool sweep = std::strcmp(integrator.name(), "xpbd") == 0;
    double start_springs = 0.0;
    Energy before = energy(sweep ? nullptr : &start_springs);
    if (!sweep) forces_.captureSpringEnergy(&start_springs);
    integrator.step(system, forces_, dt);
    forces_.captureSpringEnergy(nullptr);
    before.elastic += sweep ? 0.0 : start_springs;
    // Every integration is balanced exactly (a sweep over the springs). Skipping that sweep while the kinetic energy
    // grows slowly was tried: it let explicit Euler's slow growth at the halved steps through
    // (TissueWatchdog.UnstableStepIsCaughtWithinThreeSteps).
    const Energy after = energy();
    const double excess = after.total() - before.total() - externalWork(dt) - energyAllowance(before);
    energy_excess_ = std::max(energy_excess_, excess);
  } else {
    integrator.step(system, forces_, dt);
  }

  // Strain limit first, then collision response: the instrument has the last word, so no node is left inside it
  // (the few springs at the contact may then exceed τ_c slightly until the next step).
  if (config_.strain_limit > 0.0) {
    sortSprings();
    for (int pass = 0; pass < config_.strain_limit_passes; ++pass) {
      if (provotPass(system, config_.strain_limit, sorted_valid_ ? &sorter_ : nullptr, config_.strain_limit_outer_only)
              .corrected == 0) {
        break;
      }
    }
  }
  // Collision response (thesis §5.1): exact capsule test until the collision library's deformation vectors arrive.
  contacts_.clear();
  for (std::size_t i = 0; i < current_instruments_.size(); ++i) {
    const InstrumentInput& instrument = current_instruments_[i];
    if (!instrument.collides || isGrasping(i)) continue;
    const Eigen::Vector3d velocity = (instrument.pose.translation() - step_start_poses_[i].translation()) / config_.dt;
    for (const Capsule& capsule : instrumentCapsules(instrument)) {
      detectCapsuleContacts(system, capsule, velocity, config_.shell_scale, contacts_);
    }
  }
  if (config_.tear_strain > 0.0 && !external_deformations_.empty()) {
    // The detector's vectors land in the frame's first step only; the nodes they moved stay "pressed" for the whole
    // frame, so the dent they make relaxes instead of tearing in the next substep.
    frame_pressed_.resize(membrane_->nodeCount(), 0);
    for (const NodeDeformation& d : external_deformations_) {
      if (d.node < frame_pressed_.size()) frame_pressed_[d.node] = 1;
    }
  }
  contacts_.insert(contacts_.end(), external_deformations_.begin(), external_deformations_.end());
  external_deformations_.clear();
  applyDeformations(system, contacts_, config_.friction);
  for (const NodeDeformation& contact : contacts_) addInteractionPoint(contact.node);

  if (config_.plastic) {
    for (std::size_t s = 0; s < system.spring_count; ++s) {
      const auto& ends = system.springs[s];
      const double length = (system.positions[ends[1]] - system.positions[ends[0]]).norm();
      membrane_->restLengths()[s] = std::max(membrane_->restLengths()[s], length);
    }
  }
}

void TissueSimulator::saveState() {
  // Plain copies into buffers sized once per topology: the rollback costs two memcpy per step.
  const std::size_t n = membrane_->nodeCount();
  if (saved_positions_.size() != n) {
    saved_positions_.resize(n);
    saved_velocities_.resize(n);
  }
  std::memcpy(static_cast<void*>(saved_positions_.data()), membrane_->positions(), n * sizeof(Eigen::Vector3d));
  std::memcpy(static_cast<void*>(saved_velocities_.data()), membrane_->velocities(), n * sizeof(Eigen::Vector3d));
  if (config_.plastic) {
    saved_rest_lengths_.assign(membrane_->restLengths(), membrane_->restLengths() + membrane_->springCount());
  }
}

void TissueSimulator::restoreState() {
  const std::size_t n = saved_positions_.size();
  std::memcpy(static_cast<void*>(membrane_->positions()), saved_positions_.data(), n * sizeof(Eigen::Vector3d));
  std::memcpy(static_cast<void*>(membrane_->velocities()), saved_velocities_.data(), n * sizeof(Eigen::Vector3d));
  if (config_.plastic) std::copy(saved_rest_lengths_.begin(), saved_rest_lengths_.end(), membrane_->restLengths());
  frame_strain_ = -1.0;
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

TissueSimulator::Energy TissueSimulator::energy(const double* spring_energy) {
  const SystemView system = view();
  Energy e;
  const Eigen::Vector3d& g = config_.forces.gravity;
  const bool gravity = g.squaredNorm() > 0.0;
  for (std::size_t i = 0; i < system.node_count; ++i) {
    if (!system.isFree(i)) continue;
    e.kinetic += 0.5 * system.masses[i] * system.velocities[i].squaredNorm();
    if (gravity) e.gravity -= system.masses[i] * g.dot(system.positions[i]);
  }
  if (spring_energy != nullptr) {
    e.elastic = *spring_energy;
  } else {
    const std::size_t m = system.spring_count;
    if (energy_scratch_.size() < 3 * m) energy_scratch_.resize(3 * m);
    double* d = energy_scratch_.data();
    e.elastic = kernels::springEnergy(m, system.springs, system.positions, system.stiffnesses, system.rest_lengths, d,
                                      d + m, d + 2 * m);
  }
  for (const Anchor& anchor : forces_.anchors) {
    e.elastic += 0.5 * anchor.stiffness * (system.positions[anchor.node] - anchor.point).squaredNorm();
  }
  return e;
}

double TissueSimulator::energyAllowance(const Energy& before) const {
  const double floor_speed = config_.watchdog.energy_floor_speed;
  return config_.watchdog.energy_tolerance * (before.kinetic + before.elastic) +
         0.5 * free_mass_ * floor_speed * floor_speed;
}

double TissueSimulator::externalWork(double dt) const {
  // F·Δx with Δx ≈ h·v after the step (exact for symplectic Euler), F at the end positions: an estimate, enough to
  // keep pressure and external loads from counting as created energy.
  if (forces_.external.empty() && (forces_.params.pressure == 0.0 || forces_.triangles == nullptr)) return 0.0;
  const Eigen::Vector3d* x = membrane_->positions();
  const Eigen::Vector3d* v = membrane_->velocities();
  const std::size_t n = membrane_->nodeCount();
  double work = 0.0;
  for (std::size_t i = 0; i < n && i < forces_.external.size(); ++i) {
    if (constrained_[i] == 0) work += dt * forces_.external[i].dot(v[i]);
  }
  if (forces_.params.pressure != 0.0 && forces_.triangles != nullptr) {
    for (std::size_t t = 0; t < forces_.triangle_count; ++t) {
      const auto& c = forces_.triangles[t];
      const Eigen::Vector3d f = (forces_.params.pressure / 6.0) * (x[c[1]] - x[c[0]]).cross(x[c[2]] - x[c[0]]);
      for (std::uint32_t corner : c) {
        if (constrained_[corner] == 0) work += dt * f.dot(v[corner]);
      }
    }
  }
  return std::abs(work);
}

bool TissueSimulator::unstable() {
  frame_strain_ = -1.0;
  const SystemView system = view();
  const double max_speed2 = config_.watchdog.max_speed * config_.watchdog.max_speed;
  for (std::size_t i = 0; i < system.node_count; ++i) {
    if (!system.isFree(i)) continue;
    if (!system.positions[i].allFinite() || !system.velocities[i].allFinite()) {
      ++statistics_.non_finite;
      return true;
    }
    if (system.velocities[i].squaredNorm() > max_speed2) {
      ++statistics_.too_fast;
      return true;
    }
  }
  if (!(energy_excess_ <= 0.0)) {
    ++statistics_.energy_growth;
    return true;
  }
  return false;
}

bool TissueSimulator::step() {
  frame_strain_ = -1.0;
  if (chainmail_) {
    chainmailStep();  // cuts and tears at its end
    ++statistics_.steps;
    return true;
  }
  topologyBeforeStep();
  if (!config_.watchdog.enabled) {
    for (int k = 0; k < choice_.substeps; ++k) rawStep(*integrator_, config_.dt / choice_.substeps);
    topologyAfterStep();
    ++statistics_.steps;
    return true;
  }
  if (fallback_level_ > 0 && --hold_remaining_ <= 0) {
    --fallback_level_;
    hold_remaining_ = config_.watchdog.hold_steps;
  }
  saveState();
  pending_deformations_.assign(external_deformations_.begin(), external_deformations_.end());
  bool ok = false;
  for (int level = fallback_level_; level <= config_.watchdog.max_halvings + 1 && !ok; ++level) {
    energy_excess_ = -std::numeric_limits<double>::infinity();
    // Implicit Euler is stable at any dt: its residual energy error (truncated CG) is no instability to roll back.
    measure_energy_ = level <= config_.watchdog.max_halvings && std::strcmp(integrator_->name(), "implicit_euler") != 0;
    if (level > fallback_level_) {
      restoreState();
      external_deformations_.assign(pending_deformations_.begin(), pending_deformations_.end());
      ++statistics_.fallbacks;
    }
    if (level <= config_.watchdog.max_halvings) {
      const int substeps = choice_.substeps << level;
      for (int k = 0; k < substeps; ++k) rawStep(*integrator_, config_.dt / substeps);
    } else {
      ++statistics_.implicit_fallbacks;
      rawStep(*implicit_fallback_, config_.dt);
    }
    ok = !unstable();
    measure_energy_ = false;
    if (ok && energy_excess_ > -std::numeric_limits<double>::infinity()) {
      statistics_.max_energy_excess = std::max(statistics_.max_energy_excess, energy_excess_);
    }
    if (level > fallback_level_ && ok) {
      fallback_level_ = std::min(level, config_.watchdog.max_halvings);
      hold_remaining_ = config_.watchdog.hold_steps;
    }
  }
  if (!ok) {
    // Nothing worked: keep the last good state (frozen) rather than letting an explosion reach the renderer.
    restoreState();
    for (std::size_t i = 0; i < membrane_->nodeCount(); ++i) membrane_->velocities()[i].setZero();
    ++statistics_.unrecovered;
  }
  if (ok) topologyAfterStep();
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
  const bool early_stop = config_.early_stop_force > 0.0 && !chainmail_ && instrumentsAtRest();
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
  report.max_strain = report.steps > 0 && frame_strain_ >= 0.0 ? frame_strain_ : maxStrain();
  statistics_.max_strain = std::max(statistics_.max_strain, report.max_strain);
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

}  // namespace tissue
}  // namespace vrm_sim
