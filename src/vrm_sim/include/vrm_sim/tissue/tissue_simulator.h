#pragma once
// One deformable membrane's simulation (thesis §5): forces, a named integrator, fixed-Δt substepping inside a
// per-frame time budget, Provot strain limiting in BFS order from the interaction points, collision response from
// deformation vectors (ε-shell, eq. 5.12), grasping with the forceps, plasticity and a stability watchdog. It works
// in place on the MGE membrane's contiguous arrays, so the renderer and collision see the result without copies.
//
// Time and clocks are inputs: advance() is told how much simulated time the frame covers and gets the clock it
// measures its budget with, so tests with a fake clock are deterministic.

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vrm_scene/instrument_limits.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/chainmail.h"
#include "vrm_sim/tissue/contact.h"
#include "vrm_sim/tissue/integrator.h"
#include "vrm_sim/tissue/integrator_choice.h"
#include "vrm_sim/tissue/refinement.h"
#include "vrm_sim/tissue/strain_limit.h"
#include "vrm_sim/tissue/system.h"
#include "vrm_sim/tissue/tissue_model.h"

namespace vrm_sim {
namespace mge {
class Membrane;
}

namespace tissue {

// The watchdog tells an instability from a kinematic shock by an energy balance (issue 15 §2): a step is rejected
// only when an integration creates energy (kinetic + springs + anchors + gravity after it exceed the energy before
// it plus the work of pressure and external forces and the allowance below). The energy the instruments put in — a
// grasp moving its nodes, a yank, the contact response — and the strain limit's projection act between
// integrations, so they are given, never counted as created. Also rejected: a non-finite state or a node faster
// than max_speed. Implicit Euler (nominal or the last fallback) is checked for these two only.
struct WatchdogConfig {
  bool enabled = true;
  double max_speed = 20.0;  // m/s; no node of intra-ocular tissue moves this fast (instruments: ≤ 0.1 m/s, a yank 0.6)
  // Energy the integrator may create in one step beyond the balance, relative to the kinetic + elastic energy at the
  // start (stable explicit steps stay far below; an instability multiplies the energy of its mode every step) ...
  double energy_tolerance = 1.0;
  // ... plus the kinetic energy of the free nodes at this speed [m/s] (a floor, so a membrane at rest is not judged
  // by rounding).
  double energy_floor_speed = 0.005;
  int max_halvings = 4;  // Δt/2, Δt/4, ... before falling back to implicit Euler
  int hold_steps = 20;   // steps a fallback stays in force before the nominal Δt is tried again
};

struct TissueConfig {
  // A name of tissueModelRegistry() (tissue_model.h): "mass_spring" (integrated with `integrator`) or "chainmail"
  // (Gibson 1997, inelastic: instruments move nodes, links drag neighbours within the `chainmail` limits; no
  // integration).
  std::string model = "mass_spring";
  ChainMailConfig chainmail;
  // A name of integratorRegistry(): an integrator, or "auto" (integrator_choice.h): chosen per membrane from its
  // stiffness, masses, damping and dt, and chosen again when a grasp or a topology change alters them.
  std::string integrator = "quasi_static_euler";
  IntegratorOptions integrator_options;
  AutoIntegratorOptions auto_integrator;
  double dt = 1e-3;             // s per step (fixed)
  double time_budget_ms = 2.0;  // wall time per frame
  int max_steps_per_frame = 1000;
  ForceParameters forces;
  // τ_c of Alg. 5.1; <= 0 disables. Stable means bounded (issue 40): the mass-spring model ends every accepted step
  // with no spring stretched beyond strainBound(τ) (strain_limit.h; 1.15 for τ_c = 1.1), τ = tear_strain where the
  // membrane tears, else τ_c (no bound with neither). The passes below stay Alg. 5.1 at τ_c as before; after the
  // contact response a bound projection acts only on springs beyond the bound (MassSpringModel::enforceBound).
  double strain_limit = 1.1;
  int strain_limit_passes = 1;
  bool strain_limit_outer_only = false;  // see provotPass()
  bool plastic = false;                  // rest length follows the maximum length reached (thesis §5.1)
  // > 0: the membrane's fixed nodes are held by zero-length springs of this stiffness instead of being pinned.
  double adhesion_stiffness = 0.0;
  // > 0 [N]: an adhesion spring pulled with more than this lets go of its node for good (the membrane peels off the
  // retina there); 0: adhesion never lets go.
  double adhesion_break_force = 0.0;
  // Adhesion that gives way over time (the posterior hyaloid's): 0 = an overloaded adhesion spring lets go at once;
  // > 0 [s]: it lets go once it carried more than adhesion_break_force this long (peeling runs at a finite speed).
  // adhesion_tear_force > 0 [N]: a spring loaded past it first tears the tissue it is fixed to (counted in
  // adhesion_tears, its point in adhesionTearPoints()) and lets go — what a yank does where a slow pull peels.
  double adhesion_release_time = 0.0;
  double adhesion_tear_force = 0.0;
  // Fluid under the sheet (a subretinal injection), fluid_modulus > 0 [Pa]: every step the triangles carry the
  // pressure p = fluid_modulus · (V_fluid − V_enclosed) / max(V_fluid, fluid_volume_floor), clamped to
  // [0, fluid_max_pressure], where V_fluid is setFluidVolume()'s and V_enclosed the volume between the sheet and the
  // sphere of fluid_wall_radius about the frame's origin (enclosedVolume(), less its value at rest). The sheet's
  // triangles face the origin, so the pressure lifts it off that sphere. The fluid spreads from where it enters
  // (setFluidSource): it wets the nodes there, and from a wet node every neighbour that no adhesion holds; the pressure
  // acts on the triangles with a wet corner, so the adhesions at the front are the ones it loads and the bleb grows
  // from the injection outwards. Replaces forces.pressure.
  double fluid_modulus = 0.0;
  double fluid_wall_radius = 0.0;     // m
  double fluid_volume_floor = 1e-11;  // m^3: so the first drop does not meet an infinitely stiff fluid
  double fluid_max_pressure = 2e4;    // Pa
  // Degenerate input: give free nodes without mass (only in zero-area triangles) the mean node mass instead of
  // rejecting the membrane.
  bool repair_massless_nodes = false;
  int interaction_lifetime_steps = 50;  // interaction points are retired after this many steps (Alg. 5.2)
  // Optional early stop (thesis §5.1, Alg. 5.2: "stop when forces fall below a bound"), 0 = off. > 0 [N]: advance()
  // ends a frame early once the largest static force (springs, anchors, gravity, pressure; no damping) on a free
  // node not held by an instrument is below this while the instruments rest: further steps would not move it.
  double early_stop_force = 0.0;
  double shell_scale = 1.05;           // ε-shell (Fig. 5.1)
  double friction = 0.3;               // f_R of eq. 5.12
  double grasp_radius = 3e-4;          // m around the jaw centre
  double grasp_jaw_angle = 0.15;       // rad: a forceps closing below this grasps, opening above releases
  double projection_jaw_angle = 0.05;  // rad: below this the grasped nodes are pressed onto the jaw mid-plane
  WatchdogConfig watchdog;
  // After every accepted step, stretch springs longer than tear_strain · rest length break (see topology.h);
  // <= 0 disables tearing.
  double tear_strain = 0.0;
  // Local refinement at the instruments (thesis §5.2.4, refinement.h); levels 0 = off. mass_spring without
  // adhesion only (virtual nodes use the fixed flag).
  RefinementConfig refinement;
};

// One instrument as the tissue sees it, in the membrane's frame. Instrument frame: origin at the tip, +z from the
// handle to the tip; the collision shape is a capsule of `radius` from the tip back along −z over `length` (a
// sphere if length <= radius). Forceps (`jaws`): the shaft capsule ends at the hinge, jaw_length behind the tip, and
// each jaw is a capsule of `jaw_radius` from the hinge towards its tip, opened by ±jaw_angle/2 towards ±y — so the
// open jaws push tissue only under the blades, and tissue between them can be grasped. Their mid-plane is the
// instrument's xz plane. An instrument that holds a grasp pushes nothing (its grasped nodes follow it instead).
// The forceps open no further than this (rad, full opening): the jaw capsules here and the instrument model's meshes
// stop at the same angle, the scene floor's (vrm_scene/instrument_limits.h).
using scene::kMaxJawOpening;

struct InstrumentInput {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  double radius = 3e-4;
  double length = 0.0;
  bool collides = true;
  bool can_grasp = false;
  double jaw_angle = 1.0;  // rad (forceps opening)
  double jaw_length = 1.5e-3;
  bool jaws = false;
  double jaw_radius = 1e-4;
  // Vitrector: while `cuts`, every step removes the tissue inside the cutting volume, a capsule of `cut_radius` from
  // cut_offset to cut_offset + cut_length behind the tip along −z (instrument frame; cut_length 0 = a sphere).
  bool cuts = false;
  double cut_radius = 0.0;
  double cut_offset = 0.0;
  double cut_length = 0.0;
  // Holding without jaws — the vitrector's suction at its port (the World sets it): while `holds` the
  // instrument takes the nodes within hold_radius of hold_point (instrument frame) that are not held yet, and they
  // follow it until `holds` ends. A hold that found nothing tries again next step.
  bool holds = false;
  Eigen::Vector3d hold_point = Eigen::Vector3d::Zero();
  double hold_radius = 0.0;
  void transferState(StateArchive& archive) {
    archive(pose)(radius)(length)(collides)(can_grasp)(jaw_angle)(jaw_length)(jaws)(jaw_radius)(cuts)(cut_radius);
    archive(cut_offset)(cut_length)(holds)(hold_point)(hold_radius);
  }
};

struct FrameReport {
  int steps = 0;
  double simulated_time = 0.0;  // s actually covered (< the request when the budget ran out)
  double requested_time = 0.0;
  double wall_time = 0.0;  // s by the given clock
  bool budget_exhausted = false;
  int fallbacks = 0;           // rolled-back steps in this frame
  double max_strain = 0.0;     // after the frame
  bool early_stopped = false;  // the forces fell below early_stop_force: the rest of the frame was skipped
};

// Work the steps did, in counts (issue 40 §2: what `auto`'s cost model reads; unlike time it replays bit for bit):
// integrations (every substep and every rolled-back attempt), the CG iterations of the implicit ones, Provot passes,
// the bound check's squared-length scans over all springs, the bound projection's BFS sweeps over all springs, the
// springs its region solver visited and the BFS orderings (Alg. 5.2's from the interaction points, the projection's
// from the drivers or the pinned nodes) computed anew.
struct TissueWork {
  std::uint64_t integrations = 0, implicit_integrations = 0, cg_iterations = 0;
  std::uint64_t provot_passes = 0, bound_scans = 0, bound_sweeps = 0, region_springs = 0, bfs_sorts = 0;
  void transferState(StateArchive& archive) {
    archive(integrations)(implicit_integrations)(cg_iterations)(provot_passes)(bound_scans)(bound_sweeps);
    archive(region_springs)(bfs_sorts);
  }
};

struct SimulatorStatistics {
  std::uint64_t steps = 0;
  std::uint64_t fallbacks = 0;           // rolled-back steps, all kinds
  std::uint64_t implicit_fallbacks = 0;  // steps redone with implicit Euler after all halvings failed
  std::uint64_t unrecovered = 0;         // steps that failed even the implicit fallback (state rolled back)
  double max_strain = 0.0;               // largest strain seen at the end of any frame
  // Issue 40: the bound every accepted step keeps (TissueModel::strainBound(), +inf: none), the frames that ended
  // beyond it anyway (0 = bounded; with the watchdog on a step beyond it is rejected, so this counts what the watchdog
  // could not catch), the bound projections that ran (a step had a spring beyond the bound) and the grasped nodes
  // that slipped out of the jaws because the membrane could not follow them within the bound (tearing off).
  double strain_bound = std::numeric_limits<double>::infinity();
  std::uint64_t bound_violations = 0;
  std::uint64_t bound_projections = 0;
  std::uint64_t slipped_nodes = 0;
  // Why steps were rejected (over_bound: a spring beyond the bound the projection could not bring back).
  std::uint64_t non_finite = 0, too_fast = 0, energy_growth = 0, over_bound = 0;
  // J: of accepted explicit steps, the most an integration created beyond its allowance (negative: all stayed below;
  // how close stable steps come).
  double max_energy_excess = -std::numeric_limits<double>::infinity();
  // Topology changes (cut, tear, refinement / coarsening): each one that changed the triangles counts once; a
  // TissueMesh producer sets topology_version from it.
  std::uint64_t topology_changes = 0;
  std::uint64_t cut_nodes = 0, removed_nodes = 0, torn_springs = 0;
  std::uint64_t released_adhesions = 0;  // adhesion springs that let go (adhesion_break_force)
  std::uint64_t adhesion_tears = 0;      // of those, the ones that tore the tissue beneath (adhesion_tear_force)
  double max_adhesion_force = 0.0;       // N: the largest pull on an adhesion spring after any step
  TissueWork work;
  void transferState(StateArchive& archive) {
    archive(steps)(fallbacks)(implicit_fallbacks)(unrecovered)(max_strain)(strain_bound)(bound_violations);
    archive(bound_projections)(slipped_nodes)(non_finite)(too_fast)(energy_growth)(over_bound)(max_energy_excess);
    archive(topology_changes)(cut_nodes)(removed_nodes)(torn_springs)(released_adhesions)(adhesion_tears);
    archive(max_adhesion_force)(work);
  }
};

using Clock = std::function<double()>;  // seconds, monotonic

class TissueSimulator {
 public:
  // Throws std::invalid_argument for an unknown integrator or model, settings the model rejects, a non-positive dt, a
  // free node without positive mass (unless config.repair_massless_nodes) or non-finite positions.
  TissueSimulator(mge::Membrane& membrane, const TissueConfig& config);
  ~TissueSimulator();

  // The instruments' poses at the end of the next frame; advance() interpolates from the previous ones.
  void setInstruments(const std::vector<InstrumentInput>& instruments);
  // Deformation vectors from the collision library, applied in the next step (and then dropped).
  void addDeformations(const std::vector<NodeDeformation>& deformations);

  // Integrates fixed steps until `frame_time` is covered or the budget (by `clock`) is spent; at least one step
  // runs when frame_time >= dt.
  FrameReport advance(double frame_time, const Clock& clock);
  // One fixed step of the tissue model with the current instrument poses; false if it could not be recovered
  // (mass_spring: the watchdog rolled it back).
  bool step();

  // Must be called after a topology change of the membrane (cut, tear, refinement); releases all grasps.
  void onTopologyChanged();
  // Checkpoints (issue 39 §1): saves or loads the membrane (every slot and id, MembraneSnapshot) and everything the
  // simulator, its model and its integrator carry from one frame into the next, at a frame boundary. Loading into a
  // simulator built from the same scene makes the following frames equal the original's bit for bit; what is derived
  // (constraint flags, adjacency, BFS orders) is rebuilt without the side effects of onTopologyChanged(). Throws
  // StateError for local refinement (not restorable yet) and for bytes that do not fit this membrane.
  void transferState(StateArchive& archive);
  void addInteractionPoint(std::uint32_t node);
  void releaseAll();
  // Stable = finite and bounded (issue 40): no step the watchdog could not recover (the state was rolled back) and no
  // frame that ended with a spring beyond statistics().strain_bound.
  bool stable() const { return statistics_.unrecovered == 0 && statistics_.bound_violations == 0; }

  const std::vector<std::uint32_t>& graspedNodes() const { return grasped_nodes_; }
  // Where adhesions tore the tissue beneath (adhesion_tear_force), in the membrane's frame, oldest first.
  const std::vector<Eigen::Vector3d>& adhesionTearPoints() const { return adhesion_tear_points_; }
  // The fluid under the sheet (TissueConfig::fluid_modulus): its volume [m^3], the volume the sheet encloses now
  // and the pressure of the last step.
  void setFluidVolume(double volume) { fluid_volume_ = std::isfinite(volume) ? std::max(volume, 0.0) : 0.0; }
  // Where the fluid enters (the needle's tip, membrane frame): the nodes within `radius` of it are wet. nullopt: none
  // enters now (the wet region stays).
  void setFluidSource(const std::optional<Eigen::Vector3d>& point, double radius);
  double fluidVolume() const { return fluid_volume_; }
  double enclosedVolume() const;
  double fluidPressure() const { return fluid_pressure_; }
  // Adhesion springs that still hold (thesis §7: the points where a membrane adheres to the retina).
  std::size_t adhesionPoints() const;
  // Whether instrument `index` (setInstruments order) holds tissue (jaws that closed on nothing hold nothing).
  bool isGrasping(std::size_t index) const {
    return index < grasps_.size() && grasps_[index].active && !grasps_[index].nodes.empty();
  }
  const SimulatorStatistics& statistics() const { return statistics_; }
  const TissueConfig& config() const { return config_; }
  const Integrator& integrator() const { return *integrator_; }
  // The integrator in use and why (for "auto" the latest choice; otherwise the configured one, 1 substep).
  const IntegratorChoice& integratorChoice() const { return choice_; }
  // Increases whenever "auto" changed its choice (integrator or substeps), so a caller can log each change once.
  std::uint64_t integratorChoiceChanges() const { return choice_changes_; }
  // "symplectic_euler", "symplectic_euler x2", "implicit_euler" — the integrator and its substeps per dt.
  std::string integratorLabel() const;
  ForceModel& forceModel() { return forces_; }
  SystemView view() { return viewOf(*membrane_, constrained_.data()); }
  double maxStrain();
  double kineticEnergy();
  double totalEnergy();
  const std::vector<NodeDeformation>& lastContacts() const { return contacts_; }
  int fallbackLevel() const { return model_->fallbackLevel(); }
  std::uint64_t topologyChanges() const { return statistics_.topology_changes; }
  const TissueModel& model() const { return *model_; }
  // The ChainMail of the chainmail model, nullptr for another model.
  ChainMail* chainmail();
  LocalRefinement* refinement() { return refinement_.get(); }

 private:
  // The models are this simulator's step (tissue_model.h): they work on its state.
  friend class MassSpringModel;
  friend class ChainMailModel;

  void repairMasslessNodes();  // TissueConfig::repair_massless_nodes
  // Throws std::invalid_argument for a non-finite position or a free node without positive mass.
  void checkNodes();
  void rebuildConstraints();
  // "auto": chooses the integrator for the current masses, springs, anchors and free nodes.
  void chooseIntegratorNow();
  // "auto": the substeps on trial (IntegratorChoice::probe) did not hold: implicit Euler until the next choice.
  void rejectIntegratorProbe();
  void updateInstruments(double alpha);
  void updateGrasp(std::size_t index, const InstrumentInput& instrument, const Eigen::Isometry3d& pose,
                   const Eigen::Isometry3d& previous_pose, double dt);
  // Marks the nodes at an instrument (contacts, grasps) with a new epoch, returned.
  std::uint32_t markTouched(std::vector<std::uint32_t>& touched, std::uint32_t& epoch) const;
  void sortSprings();
  // Largest static force on a free node (TissueConfig::early_stop_force) and whether the instruments rest.
  double maxFreeForce();
  bool instrumentsAtRest() const;
  // topology.cpp: the vitrector's cut and the local refinement at the instruments before a step; virtual nodes and
  // tearing after an accepted one. Grasps survive topology changes (remapped by node identity).
  void topologyBeforeStep();
  void topologyAfterStep();
  void releaseOverloadedAdhesions();
  // pressed_ = the nodes an instrument presses or holds in this step (contacts, the frame's deformation vectors,
  // grasped nodes): tearing spares their springs up to the bound.
  void markPressed();
  // A grasped node the membrane cannot follow within the bound lets go of the jaws (issue 40); the constraint flags
  // change at once, rebuildConstraints() follows after the step.
  void slipGraspedNode(std::uint32_t node);
  void finishRemoval(const std::vector<std::uint64_t>& grasped_ids);
  // The constraint flags, the grasped-node list and the free mass from fixed, anchored_ and grasped_.
  void updateConstraintFlags();
  // After a checkpoint was loaded: everything derived from the loaded state, nothing else.
  void restoreDerived(StateArchive& archive);
  std::vector<std::uint64_t> graspedNodeIds() const;

  mge::Membrane* membrane_;
  TissueConfig config_;
  std::unique_ptr<TissueModel> model_;
  // The integrator the mass-spring model steps with (chosen here for every model: "auto" is reported per tissue).
  std::unique_ptr<Integrator> integrator_;
  bool auto_integrator_ = false;
  IntegratorChoice choice_;
  std::uint64_t choice_changes_ = 0;
  std::vector<double> choice_scratch_;
  ForceModel forces_;
  std::vector<std::uint8_t> constrained_;
  std::vector<std::uint8_t> grasped_;
  std::vector<std::uint8_t> anchored_;
  std::vector<std::uint8_t> pressed_;        // nodes with a contact in the current step (tearing spares them)
  std::vector<std::uint8_t> frame_pressed_;  // nodes the detector's vectors moved in the current frame
  std::vector<std::uint8_t> over_tear_;      // springs past the tear strain after the last step (tearOverstretched())

  std::vector<InstrumentInput> previous_instruments_, target_instruments_, current_instruments_;
  std::vector<Eigen::Isometry3d> step_start_poses_;
  struct Grasp {
    std::vector<std::uint32_t> nodes;
    std::vector<Eigen::Vector3d> local;  // in the instrument frame at grasp time
    bool active = false;
    void transferState(StateArchive& archive) { archive(nodes)(local)(active); }
  };
  std::vector<Grasp> grasps_;
  std::vector<Eigen::Vector3d> adhesion_tear_points_;
  double fluid_volume_ = 0.0, fluid_pressure_ = 0.0;
  double rest_enclosed_volume_ = 0.0;  // enclosedVolume() of the rest state (the flat triangles' slivers)
  std::vector<std::uint8_t> wet_;      // per node: the fluid reached it
  std::vector<std::uint8_t> wet_triangles_;
  void spreadFluid();
  std::vector<std::uint32_t> grasped_nodes_;

  std::vector<NodeDeformation> contacts_, external_deformations_;
  std::vector<std::uint32_t> interaction_points_;
  std::vector<std::uint64_t> interaction_stamp_;  // per node: step of the last interaction + 1, 0 = none
  std::vector<std::uint32_t> seeds_, sorted_seeds_;
  // The node → spring adjacency of the membrane, from the MGE (a NeighbourSlots view of Γ(node, −kSpringNodes) in
  // slot order, rebuilt only when the graph's edges or the slots changed); shared by every spring sorter and the bound
  // solver of the model (issue 40).
  struct GraphAdjacency;
  std::unique_ptr<GraphAdjacency> graph_adjacency_;
  NodeSpringAdjacency adjacency_;
  SpringSorter sorter_;
  bool sorted_valid_ = false;

  std::vector<std::uint32_t> touched_;  // per node: epoch of the last early-stop check that saw it at an instrument
  std::uint32_t touched_epoch_ = 0;
  double free_mass_ = 0.0;  // kg: of the integrated nodes (rebuildConstraints), for the watchdog's floor
  std::vector<Eigen::Vector3d> early_stop_forces_, early_stop_zero_;  // buffers of maxFreeForce()
  double pending_time_ = 0.0;
  SimulatorStatistics statistics_;
  std::unique_ptr<LocalRefinement> refinement_;
  mge::MembraneSnapshot snapshot_;  // transferState's, kept: a periodic checkpoint reuses its memory
};

// The capsules an instrument pushes tissue with, in the membrane's frame (see InstrumentInput); a fixed-size set, so
// a step allocates nothing.
struct InstrumentCapsules {
  std::array<Capsule, 3> capsules;
  std::size_t count = 0;
  const Capsule* begin() const { return capsules.data(); }
  const Capsule* end() const { return capsules.data() + count; }
};
InstrumentCapsules instrumentCapsules(const InstrumentInput& instrument);

// Exact step of the instrument poses between frames (linear in translation, slerp in rotation).
Eigen::Isometry3d interpolatePose(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to, double alpha);

}  // namespace tissue
}  // namespace vrm_sim
