#pragma once
// The scenario types (one class each, in abstract_scenarios.cpp, manipulation_scenarios.cpp,
// surgical_scenarios.cpp, laser_coagulation.cpp and retina_scenarios.cpp); makeScenario() picks one
// by the scene's scenario.type.

#include <memory>

#include "vrm_sim/scenario/scenario.h"

namespace vrm_sim {
namespace scenario {

std::unique_ptr<Scenario> makeNavigation(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeTrajectory(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makePickAndPlace(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeSteadyHold(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeMembranePeeling(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeIlmPeeling(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeVitrectomy(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeObjectManipulation(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeBimanual(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeLaserCoagulation(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makeRetinaRelocation(const scene::SceneDescription& scene);
std::unique_ptr<Scenario> makePosteriorHyaloid(const scene::SceneDescription& scene);

}  // namespace scenario
}  // namespace vrm_sim
