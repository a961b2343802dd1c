#pragma once
// The tissue model of a TissueSimulator (`tissue.model` in the scene YAML): what one fixed step does to the membrane.
// A small interface with one implementation per file, chosen by name from tissueModelRegistry():
//   mass_spring (mass_spring_model.cpp): the integrator-driven path of thesis §5.1 — integrate (a named integrator,
//     integrator.h), Provot strain limit, collision response, plasticity, under the stability watchdog;
//   chainmail (chainmail_model.cpp): Gibson's ChainMail (1997, thesis §5.1, §5.3, chainmail.h) — inelastic, the
//     instruments move nodes and links drag their neighbours; no integration.
// The simulator keeps what every model shares: the instruments and their grasps, interaction points, topology
// changes (cut, tear, refinement, adhesion release), the frame loop and the statistics. A model steps with that
// state (it is the simulator's step, so TissueSimulator grants the implementations access) and keeps its own.

#include <memory>
#include <string>

#include "vrm_scene/registry.h"
#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace mge {
class Membrane;
}

namespace tissue {

class TissueSimulator;
struct TissueConfig;

class TissueModel {
 public:
  virtual ~TissueModel() = default;
  virtual const char* name() const = 0;

  // Capabilities the simulator checks.
  // Local refinement at the instruments (TissueConfig::refinement; virtual nodes are integrated).
  virtual bool supportsRefinement() const { return false; }
  // advance() may end a frame early once the static forces fall below TissueConfig::early_stop_force.
  virtual bool supportsEarlyStop() const { return false; }
  // The largest stretch L/l an accepted step may leave (issue 40, strainBound()); +inf: the model keeps none.
  virtual double strainBound() const;

  // After the simulator rebuilt its constraints for the membrane's current topology (once at construction, then
  // after every cut, tear or refinement).
  virtual void onTopologyChanged(TissueSimulator& /*simulator*/) {}
  // One fixed step at the current instrument poses, including the topology changes before and after it
  // (TissueSimulator::topologyBeforeStep / topologyAfterStep); false if the step could not be recovered (the state
  // is then the last good one). The simulator counts the step.
  virtual bool step(TissueSimulator& simulator) = 0;
  // Watchdog: how many times the step is currently halved (0 for a model without a watchdog).
  virtual int fallbackLevel() const { return 0; }
  // Checkpoints (issue 39 §1): the model's state between steps, after the simulator's own (the membrane and the
  // adjacency are restored). A model that cannot be restored exactly refuses (StateArchive::fail), so its sessions
  // restore from their journal instead.
  virtual void transferState(StateArchive& archive, TissueSimulator& simulator);
};

// Builds a model for `membrane` (taken as its rest state where the model has one). Throws std::invalid_argument for
// settings the model rejects.
using TissueModelFactory = std::unique_ptr<TissueModel> (*)(mge::Membrane& membrane, const TissueConfig& config);

// "mass_spring" (the default) first, then "chainmail".
const Registry<TissueModelFactory>& tissueModelRegistry();

}  // namespace tissue
}  // namespace vrm_sim
