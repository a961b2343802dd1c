
#include "scenarios.h"
#include "vrm_scene/scene_loader.h"

namespace vrm_sim {
namespace scenario {

const InstrumentView* FrameView::instrument(const std::string& slot) const {
  for (const InstrumentView& view : instruments) {
    if (view.slot == slot) return &view;
  }
  return nullptr;
}

const TissueView* FrameView::tissue(const std::string& object) const {
  for (const TissueView& view : tissues) {
    if (view.object == object) return &view;
  }
  return nullptr;
}

const Registry<ScenarioFactory>& scenarioRegistry() {
  static const Registry<ScenarioFactory> registry(
      "scenario type", {{"navigation", makeNavigation, "touch the targets in order (thesis §2.3.2, abstract)"},
                        {"trajectory", makeTrajectory, "follow a path with the tip"},
                        {"pick_and_place", makePickAndPlace, "carry objects to their targets with the forceps"},
                        {"steady_hold", makeSteadyHold, "hold the tip still at a target"},
                        {"object_manipulation", makeObjectManipulation,
                         "place a box turned like its pad, thread a ring over a post, insert a key into a lock"},
                        {"bimanual", makeBimanual, "hand a cube from one forceps to the other"},
                        {"membrane_peeling", makeMembranePeeling, "grasp and peel an epiretinal membrane"},
                        {"ilm_peeling", makeIlmPeeling, "peel the inner limiting membrane"},
                        {"vitrectomy", makeVitrectomy, "remove the vitreous with the vitrector"},
                        {"laser_coagulation", makeLaserCoagulation,
                         "surround a retinal break with a row of laser burns (endolaser on the pedal)"},
                        {"retina_relocation", makeRetinaRelocation,
                         "inject fluid under the retina with the needle: a bleb of the target size, no tear"},
                        {"posterior_hyaloid", makePosteriorHyaloid,
                         "engage the posterior hyaloid with the vitrector's suction and lift it off the retina"}});
  return registry;
}

std::unique_ptr<Scenario> makeScenario(const scene::SceneDescription& scene) {
  if (!scene.scenario) {
    scene::SourceLocation where;
    where.file = scene.source_file;
    throw scene::SceneError(where, "the scene has no scenario section");
  }
  const auto* entry = scenarioRegistry().find(scene.scenario->type);
  if (entry == nullptr) {
    throw scene::SceneError(scene.scenario->type_location, scenarioRegistry().unknownMessage(scene.scenario->type));
  }
  return entry->make(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
