#pragma once
// The scenario types, one class per file named after its type (navigation.cpp, ..., posterior_hyaloid.cpp; helpers
// shared by a family in common.h, rigid_object_params.h, peel.h and retina_sheet.h); makeScenario() (registry.cpp)
// picks one by the scene's scenario.type.

#include <memory>

#include "vrm_sim/scenario/scenario.h"

namespace vrm_sim {
namespace scenario {

// The abstract scenarios of thesis §7.4.1: skills without anatomy (navigation, trajectory following, pick and place,
// steady hold). Geometry in the eye frame; the retina is the eye sphere unless the core simulates it.
std::unique_ptr<Scenario> makeNavigation(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeTrajectory(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makePickAndPlace(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeSteadyHold(const scene::SceneDescription& scene);
// The surgical scenarios (thesis §7): membrane peeling, ILM peeling and a vitrectomy step, scored from what the
// simulation core reports about the tissue (adhesion points, tearing, cutting) and the retina (contacts, bleeding).
std::unique_ptr<Scenario> makeMembranePeeling(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeIlmPeeling(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeVitrectomy(const scene::SceneDescription& scene);
// The object manipulation modules of thesis §7.4.1 beyond the sphere (boxes, rings, key-and-lock) and EyeSi's bimanual
// hand-over (issue 36). Rigid objects only (no tissue simulation): the bodies are rigid_body.h's, their placements go
// to the World (collision) and the renderer (SimulationState.objects). Geometry in the eye frame.
std::unique_ptr<Scenario> makeObjectManipulation(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeBimanual(const scene::SceneDescription& scene);
// laser_coagulation (issue 37): a barrier laser around a retinal break.
std::unique_ptr<Scenario> makeLaserCoagulation(const scene::SceneDescription& scene);
// The retina's own layers (issue 38). retina_relocation (thesis §7): the needle pierces the retina and injects fluid
// under it, which detaches it into a bleb; moving the needle while it is inside tears the retina. posterior_hyaloid
// (EyeSi's vitreoretinal programme): the vitrector's suction engages the posterior hyaloid, stained so it can be seen,
// and lifting it detaches it from the retina; pulled too hard where it adheres, it tears the retina beneath.
std::unique_ptr<Scenario> makeRetinaRelocation(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makePosteriorHyaloid(const scene::SceneDescription& scene);

}  // namespace scenario
}  // namespace vrm_sim
