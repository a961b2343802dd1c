// TissueSimulator::transferState (issue 39 §1): a tissue's part of a checkpoint. What is saved and why is listed in
// doc/checkpoint_state_inventory.md §2.13-2.18; in short: the membrane (MembraneSnapshot), the grasps with their
// offsets, the adhesion anchors as they are now (not as a topology change would rebuild them), the instruments'
// interpolation state, the fluid front, the interaction points with their stamps, the simulated time carried into the
// next frame, the statistics (auto's cost model reads the work counts), auto's choice, and the model's and the
// integrator's own state. Derived data is rebuilt by restoreDerived(), never by onTopologyChanged(), which would
// release the grasps and move the anchors.

#include <string>

#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {

void TissueSimulator::transferState(StateArchive& archive) {
  archive.section("tissue");
  archive.expect(config_.model, "the tissue model").expect(config_.integrator, "the configured integrator");
  // Local refinement keeps id-keyed regions and lattices whose restore is not built yet: refused, so such a session
  // restores from its journal.
  if (refinement_) archive.fail("local refinement cannot be checkpointed yet");
  mge::MembraneSnapshot& snapshot = snapshot_;
  if (archive.saving()) membrane_->takeSnapshot(snapshot);
  archive(snapshot);
  if (archive.loading()) {
    try {
      membrane_->restore(snapshot);
    } catch (const std::invalid_argument& error) {
      archive.fail(error.what());
    }
  }
  archive.section("tissue_simulator");
  archive(choice_)(choice_changes_)(forces_.anchors)(over_tear_)(previous_instruments_)(target_instruments_);
  archive(current_instruments_)(step_start_poses_)(grasps_)(adhesion_tear_points_)(fluid_volume_)(fluid_pressure_);
  archive(wet_)(pressed_)(frame_pressed_)(external_deformations_)(interaction_points_)(interaction_stamp_);
  archive(sorted_seeds_)(sorted_valid_)(pending_time_)(statistics_);
  if (archive.loading()) {
    // The integrator auto had chosen (or the configured one) before its state is loaded into it.
    if (choice_.integrator != integrator_->name()) {
      try {
        integrator_ = makeIntegrator(choice_.integrator, config_.integrator_options);
      } catch (const std::invalid_argument& error) {
        archive.fail(error.what());
      }
    }
    restoreDerived(archive);
  }
  archive.section("integrator");
  integrator_->transferState(archive, view());
  archive.section("tissue_model");
  model_->transferState(archive, *this);
}

}  // namespace tissue
}  // namespace vrm_sim
