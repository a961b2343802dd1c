// The mass-spring model (thesis §5.1): the integrator-driven step of TissueSimulator — integrate with the simulator's
// integrator, Provot strain limit (Alg. 5.1), collision response (eq. 5.12), the bound projection (issue 40),
// plasticity — under the stability watchdog (WatchdogConfig: halved steps, then implicit Euler, rolled back on
// failure).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "spring_kernels.h"
#include "tissue_models_impl.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {

class MassSpringModel : public TissueModel {
 public:
  explicit MassSpringModel(const TissueConfig& config) {
    IntegratorOptions fallback_options = config.integrator_options;
    fallback_options.cg_max_iterations = std::max(fallback_options.cg_max_iterations, 50);
    implicit_fallback_ = makeIntegrator("implicit_euler", fallback_options);
    const double tau = config.tear_strain > 0.0 ? config.tear_strain : config.strain_limit;
    bound_ = tissue::strainBound(tau);
    bound_target_ = strainBoundTarget(tau);
  }
  const char* name() const override { return "mass_spring"; }
  bool supportsRefinement() const override { return true; }
  bool supportsEarlyStop() const override { return true; }
  double strainBound() const override { return bound_; }
  void onTopologyChanged(TissueSimulator& simulator) override;
  bool step(TissueSimulator& simulator) override;
  int fallbackLevel() const override { return fallback_level_; }
  void transferState(StateArchive& archive, TissueSimulator& simulator) override;

 private:
  struct Energy {
    double kinetic = 0.0, elastic = 0.0, gravity = 0.0;  // J; elastic = springs + anchors
    double total() const { return kinetic + elastic + gravity; }
  };
  // The step at watchdog level `level` (0: nominal substeps, each level halves them, beyond max_halvings: implicit
  // Euler); restores the saved state first when retrying. True if the result is stable.
  bool attempt(TissueSimulator& simulator, int level);
  // Integrate + limit + respond (+ yield), no watchdog.
  void rawStep(TissueSimulator& simulator, Integrator& integrator, double dt);
  // One integration; balances its energy when measure_energy_.
  void integrate(TissueSimulator& simulator, const SystemView& system, Integrator& integrator, double dt);
  // Counts an integration and, for an implicit one (after it ran), its CG iterations in work_.
  void countIntegration(const Integrator& integrator);
  // Provot's strain limit (Alg. 5.1) in BFS order from the interaction points.
  void limitStrain(TissueSimulator& simulator, const SystemView& system);
  // Stable means bounded (issue 40), after the contact response: springs beyond bound_ shortened towards bound_target_
  // (boundPass()): outwards from this step's drivers, then Gauss-Seidel on the violation's region to convergence with
  // the instruments holding; where that is infeasible (a grasp pulled farther than the pinned membrane can follow, a
  // dent deeper than it can follow) the tissue wins — only the pinned nodes hold, grasped nodes it moves slip out of
  // the jaws, contacts are passed through. With tearing the instruments always hold and what the dynamics stretched
  // past the tear strain is left to tear (topologyAfterStep()). Sets bound_exceeded_ if a spring that cannot tear stays
  // beyond the bound (the watchdog then rejects the step).
  void enforceBound(TissueSimulator& simulator, const SystemView& system);
  // Up to `sweeps` boundPass() sweeps, until one corrects nothing; the statistics of the last.
  // (Without a sorter the sweeps alternate their direction.) `stop_when_stalled`: also stop once a sweep corrects no
  // fewer springs than the one before.
  BoundPassStatistics sweepBound(const SystemView& system, BoundPassOptions options, int sweeps,
                                 bool stop_when_stalled = false);
  // Up to `sweeps` sweeps of active_ (seeded), alternating directions; true once a sweep corrects nothing (every
  // spring within the bound but those left to tear).
  bool solveActive(const SystemView& system, const BoundPassOptions& options, int sweeps);
  // tearable_: the springs this step's dynamics stretched past the tear strain (see BoundPassOptions::tearable).
  void markTearable(const SystemView& system, const std::uint8_t* pressed, double tear_strain);
  // The grasped nodes the tissue-wins phase moved slip out of the jaws.
  void slipMovedGrasps(TissueSimulator& simulator);
  // Tearing: a bending spring (which never tears) beyond the bound.
  bool untearableBeyond(const SystemView& system) const;
  // Collision response (eq. 5.12): the instruments' capsules and the collision library's deformation vectors.
  void respondToContacts(TissueSimulator& simulator, const SystemView& system);
  // Plasticity (TissueConfig::plastic): rest lengths follow the longest length reached.
  void yield(TissueSimulator& simulator, const SystemView& system);
  // The energy of the current state: a sweep over the nodes and one over the springs, or, given spring_energy, that
  // value for the springs' part instead of the second sweep.
  Energy energy(TissueSimulator& simulator, const double* spring_energy = nullptr);
  // What an integration step may create beyond the balance (WatchdogConfig::energy_tolerance and the floor).
  double energyAllowance(const TissueSimulator& simulator, const Energy& before) const;
  // Work of pressure and external forces during an integration step of dt just done (estimate, see below).
  double externalWork(const TissueSimulator& simulator, double dt) const;
  // This attempt's integration created energy: unstable() rejects it.
  bool doomed() const { return measure_energy_ && energy_excess_ > 0.0; }
  // Non-finite, too fast, or an integration step that created energy (energy_excess_ > 0).
  bool unstable(TissueSimulator& simulator);
  void saveState(TissueSimulator& simulator);
  void restoreState(TissueSimulator& simulator);

  TissueWork* work_ = nullptr;                     // the simulator's statistics_.work, during step()
  std::unique_ptr<Integrator> implicit_fallback_;  // the watchdog's last resort, stable at any dt
  std::vector<Eigen::Vector3d> saved_positions_, saved_velocities_;
  std::vector<double> saved_rest_lengths_;
  std::vector<double> energy_scratch_;  // 3 per spring: the energy sweep's gathered spring vectors
  bool measure_energy_ = false;         // rawStep() balances each integration (watchdog on, explicit attempt)
  double energy_excess_ = 0.0;          // J: the most an integration of this step created beyond the allowance
  std::vector<NodeDeformation> pending_deformations_;  // external deformations, replayed after a rollback
  int fallback_level_ = 0;
  int hold_remaining_ = 0;

  // The bound projection (enforceBound()): strainBound() and strainBoundTarget() of the tear strain (tearing) or of
  // τ_c; its per-spring bending and tearable flags (tearing), pinned, held and moved nodes, the BFS from the pinned
  // nodes and the region solver.
  double bound_ = 0.0, bound_target_ = 0.0;
  bool bound_exceeded_ = false;  // this attempt left a spring beyond the bound (see enforceBound())
  bool slipped_ = false;         // grasped nodes slipped in this step: the constraints are rebuilt after it
  std::vector<std::uint8_t> bending_, pinned_, moved_, holding_, tearable_;
  std::vector<std::uint32_t> pinned_seeds_, pinned_sorted_seeds_;
  SpringSorter pinned_sorter_;
  bool pinned_sorted_ = false;
  // BFS from the kinematic drivers of this step (grasped nodes, contacts): unlike Alg. 5.2's interaction points it
  // holds no node an instrument touched in earlier steps.
  std::vector<std::uint32_t> driver_seeds_, driver_sorted_seeds_;
  SpringSorter driver_sorter_;
  bool driver_sorted_ = false;
  // Sweeps per projection at most. Outwards: a pull through a membrane that can follow it converges in two or three
  // (the second settles nodes with two parents, the last proves it); the tissue-wins phases run only when a kinematic
  // driver asks more than the membrane can give.
  static constexpr int kOutwardSweeps = 6;
  static constexpr int kInwardSweeps = 4;
  // ActiveBoundSolver sweeps: with the instruments holding, then with the tissue winning (over-relaxed: a grasp pulled
  // back across the membrane is a long-range correction, which plain Gauss-Seidel propagates slowly).
  static constexpr int kHoldingSweeps = 32;
  static constexpr int kTissueWinsSweeps = 128;
  static constexpr double kRelaxation = 1.5;
  ActiveBoundSolver active_;
};

std::unique_ptr<TissueModel> makeMassSpringModel(mge::Membrane& /*membrane*/, const TissueConfig& config) {
  return std::make_unique<MassSpringModel>(config);
}

// The watchdog's level and hold, the BFS orders' keys (sorted again: a sort is a function of its seeds, so the next
// step reuses the order as the original did) and the fallback integrator's warm start.
void MassSpringModel::transferState(StateArchive& archive, TissueSimulator& s) {
  archive(fallback_level_)(hold_remaining_)(pinned_sorted_seeds_)(pinned_sorted_)(driver_sorted_seeds_)(driver_sorted_);
  if (archive.loading()) {
    const SystemView system = s.view();
    for (const auto* seeds : {&pinned_sorted_seeds_, &driver_sorted_seeds_}) {
      for (std::uint32_t node : *seeds) {
        if (node >= system.node_count) archive.fail("a bound projection seed beyond the nodes");
      }
    }
    if (!std::isfinite(bound_)) {
      pinned_sorted_ = driver_sorted_ = false;
    } else {
      if (pinned_sorted_) pinned_sorter_.sort(system, pinned_sorted_seeds_);
      if (driver_sorted_) driver_sorter_.sort(system, driver_sorted_seeds_);
    }
  }
  archive.section("implicit_fallback");
  implicit_fallback_->transferState(archive, s.view());
}

void MassSpringModel::onTopologyChanged(TissueSimulator& s) {
  if (!std::isfinite(bound_)) return;
  const SystemView system = s.view();
  driver_sorter_.rebuild(system, s.adjacency_);
  driver_sorted_ = false;
  pinned_sorter_.rebuild(system, s.adjacency_);
  pinned_sorted_ = false;
  pinned_seeds_.reserve(system.node_count);
  pinned_sorted_seeds_.reserve(system.node_count);
  active_.reset(system.spring_count, s.adjacency_);
  driver_seeds_.reserve(system.node_count);
  driver_sorted_seeds_.reserve(system.node_count);
  // Sized once per topology: a projection allocates nothing.
  pinned_.assign(system.node_count, 0);
  moved_.assign(system.node_count, 0);
  holding_.assign(system.node_count, 0);
  tearable_.assign(system.spring_count, 0);
  bending_.assign(system.spring_count, 0);
  if (s.config_.tear_strain > 0.0) {
    for (std::size_t k = 0; k < system.spring_count; ++k) bending_[k] = s.membrane_->springAtSlot(k).bending() ? 1 : 0;
  }
}

bool MassSpringModel::step(TissueSimulator& simulator) {
  TissueSimulator& s = simulator;
  const TissueConfig& config = s.config_;
  work_ = &s.statistics_.work;
  s.topologyBeforeStep();
  if (!config.watchdog.enabled) {
    for (int k = 0; k < s.choice_.substeps; ++k) rawStep(s, *s.integrator_, config.dt / s.choice_.substeps);
    if (slipped_) {
      slipped_ = false;
      s.rebuildConstraints();
    }
    s.topologyAfterStep();
    return true;
  }
  if (fallback_level_ > 0 && --hold_remaining_ <= 0) {
    --fallback_level_;
    hold_remaining_ = config.watchdog.hold_steps;
  }
  saveState(s);
  pending_deformations_.assign(s.external_deformations_.begin(), s.external_deformations_.end());
  bool ok = false;
  for (int level = fallback_level_; level <= config.watchdog.max_halvings + 1 && !ok; ++level) {
    ok = attempt(s, level);
    if (!ok && level == fallback_level_ && s.choice_.probe) {
      // `auto`'s substeps on trial did not hold: implicit Euler from here, this step redone at the same level.
      s.rejectIntegratorProbe();
      restoreState(s);
      s.external_deformations_.assign(pending_deformations_.begin(), pending_deformations_.end());
      ++s.statistics_.fallbacks;
      ok = attempt(s, level);
    }
  }
  if (!ok) {
    // Nothing worked: keep the last good state (frozen) rather than letting an explosion reach the renderer.
    restoreState(s);
    for (std::size_t i = 0; i < s.membrane_->nodeCount(); ++i) s.membrane_->velocities()[i].setZero();
    ++s.statistics_.unrecovered;
  }
  if (slipped_) {
    slipped_ = false;
    s.rebuildConstraints();
  }
  if (ok) s.topologyAfterStep();
  return ok;
}

bool MassSpringModel::attempt(TissueSimulator& s, int level) {
  const TissueConfig& config = s.config_;
  energy_excess_ = -std::numeric_limits<double>::infinity();
  bound_exceeded_ = false;
  // Implicit Euler is stable at any dt: its residual energy error (truncated CG) is no instability to roll back.
  measure_energy_ = level <= config.watchdog.max_halvings && std::strcmp(s.integrator_->name(), "implicit_euler") != 0;
  if (level > fallback_level_) {
    restoreState(s);
    s.external_deformations_.assign(pending_deformations_.begin(), pending_deformations_.end());
    ++s.statistics_.fallbacks;
  }
  if (level <= config.watchdog.max_halvings) {
    const int substeps = s.choice_.substeps << level;
    for (int k = 0; k < substeps && !doomed(); ++k) rawStep(s, *s.integrator_, config.dt / substeps);
  } else {
    ++s.statistics_.implicit_fallbacks;
    rawStep(s, *implicit_fallback_, config.dt);
  }
  const bool ok = !unstable(s);
  measure_energy_ = false;
  if (ok && energy_excess_ > -std::numeric_limits<double>::infinity()) {
    s.statistics_.max_energy_excess = std::max(s.statistics_.max_energy_excess, energy_excess_);
  }
  if (level > fallback_level_ && ok) {
    fallback_level_ = std::min(level, config.watchdog.max_halvings);
    hold_remaining_ = config.watchdog.hold_steps;
  }
  return ok;
}

void MassSpringModel::rawStep(TissueSimulator& s, Integrator& integrator, double dt) {
  const SystemView system = s.view();
  integrate(s, system, integrator, dt);
  // An attempt whose integration created energy is rejected (unstable()) and rolled back whatever follows: its
  // projections would be spent on an exploded state (hard_mass_ratio_1e5: ~100x the cost of the step).
  if (doomed()) return;
  // Strain limit first, then collision response: the instrument has the last word, so no node is left inside it
  // (the few springs at the contact may then exceed τ_c slightly until the next step).
  if (s.config_.strain_limit > 0.0) limitStrain(s, system);
  respondToContacts(s, system);
  if (std::isfinite(bound_)) enforceBound(s, system);
  if (s.config_.plastic) yield(s, system);
}

void MassSpringModel::integrate(TissueSimulator& s, const SystemView& system, Integrator& integrator, double dt) {
  if (measure_energy_) {
    // The balance covers the integration only: the strain limit and the contact response that follow are
    // projections (kinematic constraints, the instrument), whose work is given, not created by the integrator.
    // The start energy's spring part comes from the integrator's first force evaluation (at the start state), at
    // almost no cost; XPBD evaluates no spring forces, so it gets a sweep.
    const bool sweep = std::strcmp(integrator.name(), "xpbd") == 0;
    double start_springs = 0.0;
    Energy before = energy(s, sweep ? nullptr : &start_springs);
    if (!sweep) s.forces_.captureSpringEnergy(&start_springs);
    integrator.step(system, s.forces_, dt);
    s.forces_.captureSpringEnergy(nullptr);
    before.elastic += sweep ? 0.0 : start_springs;
    // Every integration is balanced exactly (a sweep over the springs). Skipping that sweep while the kinetic energy
    // grows slowly was tried: it let explicit Euler's slow growth at the halved steps through
    // (TissueWatchdog.UnstableStepIsCaughtWithinThreeSteps).
    const Energy after = energy(s);
    const double excess = after.total() - before.total() - externalWork(s, dt) - energyAllowance(s, before);
    energy_excess_ = std::max(energy_excess_, excess);
  } else {
    integrator.step(system, s.forces_, dt);
  }
  countIntegration(integrator);
}

void MassSpringModel::countIntegration(const Integrator& integrator) {
  if (work_ == nullptr) return;
  ++work_->integrations;
  // The watchdog's own implicit Euler (a larger iteration budget) is not what `auto` would run.
  if (std::strcmp(integrator.name(), "implicit_euler") == 0 && &integrator != implicit_fallback_.get()) {
    ++work_->implicit_integrations;
    work_->cg_iterations += static_cast<std::uint64_t>(std::max(integrator.lastIterations(), 0));
  }
}

void MassSpringModel::limitStrain(TissueSimulator& s, const SystemView& system) {
  const TissueConfig& config = s.config_;
  s.sortSprings();
  for (int pass = 0; pass < config.strain_limit_passes; ++pass) {
    // Provot's velocity adjustment (the moved nodes stop against their correction) for integrators that carry their
    // velocities into the next step; quasi-static Euler starts every step from rest.
    if (work_ != nullptr) ++work_->provot_passes;
    if (provotPass(system, config.strain_limit, s.sorted_valid_ ? &s.sorter_ : nullptr, config.strain_limit_outer_only,
                   s.integrator_->startsFromRest() ? nullptr : system.velocities)
            .corrected == 0) {
      break;
    }
  }
}

BoundPassStatistics MassSpringModel::sweepBound(const SystemView& system, BoundPassOptions options, int sweeps,
                                                bool stop_when_stalled) {
  BoundPassStatistics stats;
  std::size_t previous = 0;
  for (int k = 0; k < sweeps; ++k) {
    options.reverse = (k % 2) == 1;
    if (work_ != nullptr) ++work_->bound_sweeps;
    stats = boundPass(system, options);
    if (stats.corrected == 0) break;
    // A sweep that corrects as many as the one before makes no headway (a driver asks more than the membrane can
    // give: the same springs are pulled back and forth); the next phase decides.
    if (stop_when_stalled && k > 0 && stats.corrected >= previous) break;
    previous = stats.corrected;
  }
  return stats;
}

bool MassSpringModel::untearableBeyond(const SystemView& system) const {
  const double bound2 = bound_ * bound_;
  for (std::size_t k = 0; k < system.spring_count && k < bending_.size(); ++k) {
    if (!bending_[k] || !(system.rest_lengths[k] >= kMinSpringLength)) continue;
    const auto& ends = system.springs[k];
    const double rest = system.rest_lengths[k];
    if (!((system.positions[ends[1]] - system.positions[ends[0]]).squaredNorm() <= bound2 * rest * rest)) return true;
  }
  return false;
}

void MassSpringModel::enforceBound(TissueSimulator& s, const SystemView& system) {
  // The common case costs one sweep of squared lengths: nothing beyond the bound, nothing to do (seed() is that sweep).
  if (work_ != nullptr) ++work_->bound_scans;
  if (!active_.seed(system, bound_)) return;
  ++s.statistics_.bound_projections;
  const bool tearing = s.config_.tear_strain > 0.0;
  BoundPassOptions options;
  options.bound = bound_;
  options.target = bound_target_;
  options.velocities = system.velocities;
  if (tearing) {
    // The springs that may be left to tear: stretched past the tear strain by this step's dynamics (integration,
    // Alg. 5.1, contact response), no end pressed by an instrument, not a bending spring. A spring the projection's
    // own moves stretch beyond the bound is corrected like any other (a pinch of the closing jaws tears nothing).
    s.markPressed();
    options.tear_strain = s.config_.tear_strain;
    markTearable(system, s.pressed_.data(), s.config_.tear_strain);
    options.tearable = tearable_.data();
  }
  // The kinematic drivers of this step: the grasped nodes and the contacts (where the contact response put them).
  driver_seeds_.assign(s.grasped_nodes_.begin(), s.grasped_nodes_.end());
  for (const NodeDeformation& contact : s.contacts_) {
    if (contact.node < system.node_count) driver_seeds_.push_back(contact.node);
  }
  std::sort(driver_seeds_.begin(), driver_seeds_.end());
  driver_seeds_.erase(std::unique(driver_seeds_.begin(), driver_seeds_.end()), driver_seeds_.end());
  if (!driver_seeds_.empty()) {
    // Outwards from the drivers in BFS order (Alg. 5.2), only the outer end of a spring moved: a pull or a push
    // propagates through a membrane that can follow it in one sweep (ChainMail-like).
    if (!driver_sorted_ || driver_seeds_ != driver_sorted_seeds_) {
      if (work_ != nullptr) ++work_->bfs_sorts;
      driver_sorter_.sort(system, driver_seeds_);
      driver_sorted_seeds_ = driver_seeds_;
      driver_sorted_ = true;
    }
    options.sorter = &driver_sorter_;
    // (A push alone: the first sweep does the propagation, the rest is left to the convergent solve below.)
    const int outward = s.grasped_nodes_.empty() ? 1 : kOutwardSweeps;
    const BoundPassStatistics stats = sweepBound(system, options, outward, /*stop_when_stalled=*/!tearing);
    if (stats.corrected == 0 && stats.skipped_fixed == 0) return;
    options.sorter = nullptr;
    // Then Gauss-Seidel to convergence on the violation's region, the instruments holding: grasped nodes (constrained)
    // and contacts fixed.
    if (work_ != nullptr) ++work_->bound_scans;
    if (!active_.seed(system, bound_)) return;
    holding_.assign(system.node_count, 0);
    for (std::size_t i = 0; i < system.node_count; ++i) holding_[i] = system.isFree(i) ? 0 : 1;
    for (const NodeDeformation& contact : s.contacts_) {
      if (contact.node < system.node_count) holding_[contact.node] = 1;
    }
    options.fixed = holding_.data();
    const bool held = solveActive(system, options, kHoldingSweeps);
    options.fixed = nullptr;
    if (held) return;
  }
  if (tearing) {
    // The instruments hold: a stretch spring still beyond the bound tears after the step (tearOverstretched()).
    if (untearableBeyond(system)) bound_exceeded_ = true;
    return;
  }
  // The tissue wins: only the pinned nodes hold. Gauss-Seidel on the violation's region to convergence; grasped nodes
  // it moves slip out of the jaws (a grasp pulled farther than the pinned membrane can follow), contacts it moves are
  // pulled into the instrument (a dent deeper than the tissue can follow is passed through, not stretched around).
  const std::size_t n = system.node_count;
  pinned_.assign(n, 0);
  pinned_seeds_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    if (system.isFree(i) || s.grasped_[i]) continue;
    pinned_[i] = 1;
    pinned_seeds_.push_back(static_cast<std::uint32_t>(i));
  }
  moved_.assign(n, 0);
  options.fixed = pinned_.data();
  options.moved = moved_.data();
  if (!pinned_seeds_.empty() && !s.grasped_nodes_.empty()) {
    // Inwards from the pinned nodes in BFS order first: a grasp pulled beyond reach comes back to where the membrane
    // can hold it in about one sweep, where Gauss-Seidel needs many. (A dent needs no such long-range correction.)
    if (!pinned_sorted_ || pinned_seeds_ != pinned_sorted_seeds_) {
      if (work_ != nullptr) ++work_->bfs_sorts;
      pinned_sorter_.sort(system, pinned_seeds_);
      pinned_sorted_seeds_ = pinned_seeds_;
      pinned_sorted_ = true;
    }
    options.sorter = &pinned_sorter_;
    sweepBound(system, options, kInwardSweeps, /*stop_when_stalled=*/true);
    options.sorter = nullptr;
    if (work_ != nullptr) ++work_->bound_scans;
    if (!active_.seed(system, bound_)) {
      slipMovedGrasps(s);
      return;
    }
  }
  options.relaxation = kRelaxation;
  const bool converged = solveActive(system, options, kTissueWinsSweeps);
  slipMovedGrasps(s);
  if (!converged) bound_exceeded_ = true;
}

void MassSpringModel::slipMovedGrasps(TissueSimulator& s) {
  for (const std::uint32_t node : s.grasped_nodes_) {
    if (!moved_[node] || !s.grasped_[node]) continue;
    s.slipGraspedNode(node);
    slipped_ = true;
  }
}

void MassSpringModel::markTearable(const SystemView& system, const std::uint8_t* pressed, double tear_strain) {
  tearable_.assign(system.spring_count, 0);
  const double tear2 = tear_strain * tear_strain;
  for (std::size_t k = 0; k < system.spring_count; ++k) {
    const auto& ends = system.springs[k];
    if ((k < bending_.size() && bending_[k]) || pressed[ends[0]] || pressed[ends[1]]) continue;
    const double rest = system.rest_lengths[k];
    const double length2 = (system.positions[ends[1]] - system.positions[ends[0]]).squaredNorm();
    tearable_[k] = length2 > tear2 * rest * rest ? 1 : 0;
  }
}

bool MassSpringModel::solveActive(const SystemView& system, const BoundPassOptions& options, int sweeps) {
  for (int k = 0; k < sweeps; ++k) {
    if (work_ != nullptr) work_->region_springs += active_.activeSprings();
    const BoundPassStatistics stats = active_.sweep(system, options, (k % 2) == 1);
    // A spring beyond the bound between two fixed nodes stays so whatever the sweeps do.
    if (stats.skipped_fixed > 0) return false;
    if (stats.corrected == 0) return true;
  }
  return false;
}

void MassSpringModel::respondToContacts(TissueSimulator& s, const SystemView& system) {
  const TissueConfig& config = s.config_;
  // Collision response (thesis §5.1): exact capsule test until the collision library's deformation vectors arrive.
  s.contacts_.clear();
  for (std::size_t i = 0; i < s.current_instruments_.size(); ++i) {
    const InstrumentInput& instrument = s.current_instruments_[i];
    if (!instrument.collides || s.isGrasping(i)) continue;
    const Eigen::Vector3d velocity = (instrument.pose.translation() - s.step_start_poses_[i].translation()) / config.dt;
    for (const Capsule& capsule : instrumentCapsules(instrument)) {
      detectCapsuleContacts(system, capsule, velocity, config.shell_scale, s.contacts_);
    }
  }
  if (config.tear_strain > 0.0 && !s.external_deformations_.empty()) {
    // The detector's vectors land in the frame's first step only; the nodes they moved stay "pressed" for the whole
    // frame, so the dent they make relaxes instead of tearing in the next substep.
    s.frame_pressed_.resize(s.membrane_->nodeCount(), 0);
    for (const NodeDeformation& d : s.external_deformations_) {
      if (d.node < s.frame_pressed_.size()) s.frame_pressed_[d.node] = 1;
    }
  }
  s.contacts_.insert(s.contacts_.end(), s.external_deformations_.begin(), s.external_deformations_.end());
  s.external_deformations_.clear();
  applyDeformations(system, s.contacts_, config.friction);
  for (const NodeDeformation& contact : s.contacts_) s.addInteractionPoint(contact.node);
}

void MassSpringModel::yield(TissueSimulator& s, const SystemView& system) {
  for (std::size_t k = 0; k < system.spring_count; ++k) {
    const auto& ends = system.springs[k];
    const double length = (system.positions[ends[1]] - system.positions[ends[0]]).norm();
    s.membrane_->restLengths()[k] = std::max(s.membrane_->restLengths()[k], length);
  }
}

void MassSpringModel::saveState(TissueSimulator& s) {
  // Plain copies into buffers sized once per topology: the rollback costs two memcpy per step.
  mge::Membrane& membrane = *s.membrane_;
  const std::size_t n = membrane.nodeCount();
  if (saved_positions_.size() != n) {
    saved_positions_.resize(n);
    saved_velocities_.resize(n);
  }
  std::memcpy(static_cast<void*>(saved_positions_.data()), membrane.positions(), n * sizeof(Eigen::Vector3d));
  std::memcpy(static_cast<void*>(saved_velocities_.data()), membrane.velocities(), n * sizeof(Eigen::Vector3d));
  if (s.config_.plastic) {
    saved_rest_lengths_.assign(membrane.restLengths(), membrane.restLengths() + membrane.springCount());
  }
}

void MassSpringModel::restoreState(TissueSimulator& s) {
  mge::Membrane& membrane = *s.membrane_;
  const std::size_t n = saved_positions_.size();
  std::memcpy(static_cast<void*>(membrane.positions()), saved_positions_.data(), n * sizeof(Eigen::Vector3d));
  std::memcpy(static_cast<void*>(membrane.velocities()), saved_velocities_.data(), n * sizeof(Eigen::Vector3d));
  if (s.config_.plastic) std::copy(saved_rest_lengths_.begin(), saved_rest_lengths_.end(), membrane.restLengths());
}

MassSpringModel::Energy MassSpringModel::energy(TissueSimulator& s, const double* spring_energy) {
  const SystemView system = s.view();
  Energy e;
  const Eigen::Vector3d& g = s.config_.forces.gravity;
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
  for (const Anchor& anchor : s.forces_.anchors) {
    e.elastic += 0.5 * anchor.stiffness * (system.positions[anchor.node] - anchor.point).squaredNorm();
  }
  return e;
}

double MassSpringModel::energyAllowance(const TissueSimulator& s, const Energy& before) const {
  const double floor_speed = s.config_.watchdog.energy_floor_speed;
  return s.config_.watchdog.energy_tolerance * (before.kinetic + before.elastic) +
         0.5 * s.free_mass_ * floor_speed * floor_speed;
}

double MassSpringModel::externalWork(const TissueSimulator& s, double dt) const {
  // F·Δx with Δx ≈ h·v after the step (exact for symplectic Euler), F at the end positions: an estimate, enough to
  // keep pressure and external loads from counting as created energy.
  const ForceModel& forces = s.forces_;
  if (forces.external.empty() && (forces.params.pressure == 0.0 || forces.triangles == nullptr)) return 0.0;
  const Eigen::Vector3d* x = s.membrane_->positions();
  const Eigen::Vector3d* v = s.membrane_->velocities();
  const std::size_t n = s.membrane_->nodeCount();
  double work = 0.0;
  for (std::size_t i = 0; i < n && i < forces.external.size(); ++i) {
    if (s.constrained_[i] == 0) work += dt * forces.external[i].dot(v[i]);
  }
  if (forces.params.pressure != 0.0 && forces.triangles != nullptr) {
    for (std::size_t t = 0; t < forces.triangle_count; ++t) {
      if (forces.pressure_mask != nullptr && forces.pressure_mask[t] == 0) continue;
      const auto& c = forces.triangles[t];
      const Eigen::Vector3d f = (forces.params.pressure / 6.0) * (x[c[1]] - x[c[0]]).cross(x[c[2]] - x[c[0]]);
      for (std::uint32_t corner : c) {
        if (s.constrained_[corner] == 0) work += dt * f.dot(v[corner]);
      }
    }
  }
  return std::abs(work);
}

bool MassSpringModel::unstable(TissueSimulator& s) {
  const SystemView system = s.view();
  const double max_speed2 = s.config_.watchdog.max_speed * s.config_.watchdog.max_speed;
  for (std::size_t i = 0; i < system.node_count; ++i) {
    if (!system.isFree(i)) continue;
    if (!system.positions[i].allFinite() || !system.velocities[i].allFinite()) {
      ++s.statistics_.non_finite;
      return true;
    }
    if (system.velocities[i].squaredNorm() > max_speed2) {
      ++s.statistics_.too_fast;
      return true;
    }
  }
  if (!(energy_excess_ <= 0.0)) {
    ++s.statistics_.energy_growth;
    return true;
  }
  // Stable means bounded (issue 40): a spring the projection could not bring back within the bound is an instability
  // to roll back and retry at smaller steps.
  if (bound_exceeded_) {
    ++s.statistics_.over_bound;
    return true;
  }
  return false;
}

}  // namespace tissue
}  // namespace vrm_sim
