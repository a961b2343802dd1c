#include <functional>
#include <map>

#include "scenarios.h"
#include "vrm_sim/scene/scene_loader.h"

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

void hashBytes(std::uint64_t& state, const void* data, std::size_t size) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    state ^= bytes[i];
    state *= 0x100000001b3ull;
  }
}

std::unique_ptr<Scenario> makeScenario(const scene::SceneDescription& scene) {
  using Factory = std::function<std::unique_ptr<Scenario>(const scene::SceneDescription&)>;
  // Explicit, not self-registering: a static library drops object files nothing references.
  static const std::map<std::string, Factory> factories = {{"navigation", makeNavigation},
                                                           {"trajectory", makeTrajectory},
                                                           {"pick_and_place", makePickAndPlace},
                                                           {"steady_hold", makeSteadyHold},
                                                           {"membrane_peeling", makeMembranePeeling},
                                                           {"ilm_peeling", makeIlmPeeling},
                                                           {"vitrectomy", makeVitrectomy}};
  if (!scene.scenario) {
    scene::SourceLocation where;
    where.file = scene.source_file;
    throw scene::SceneError(where, "the scene has no scenario section");
  }
  const auto factory = factories.find(scene.scenario->type);
  if (factory == factories.end()) {
    throw scene::SceneError(scene.scenario->location, "unknown scenario type '" + scene.scenario->type + "'");
  }
  return factory->second(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
