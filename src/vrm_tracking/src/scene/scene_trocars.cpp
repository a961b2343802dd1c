#include "vrm_tracking/scene_trocars.h"

#include <fstream>
#include <stdexcept>
#include <vector>

#include "vrm_sim/scene/scene_loader.h"

namespace vrm_tracking {

namespace scene = vrm_sim::scene;

scene::SceneDescription loadSceneSpec(const std::string& spec) {
  return scene::loadScene(std::ifstream(spec).good() ? spec : scene::shippedScenePath(spec));
}

Eigen::Vector3d sceneTrocarForSlot(const scene::SceneDescription& scene, const std::string& slot) {
  std::string trocar_name = slot;
  for (const scene::InstrumentDescription& instrument : scene.instruments) {
    if (slot == scene::toString(instrument.slot)) trocar_name = instrument.trocar;
  }
  if (const scene::Trocar* trocar = scene.findTrocar(trocar_name)) return trocar->position_in_eye;
  std::string available;
  for (const scene::Trocar& trocar : scene.eye.trocars) available += (available.empty() ? "" : ", ") + trocar.name;
  throw std::runtime_error("scene '" + scene.name + "' (" +
                           (scene.source_file.empty() ? std::string("<memory>") : scene.source_file) +
                           ") has no trocar for instrument slot '" + slot + "' (looked for trocar '" + trocar_name +
                           "'; the scene's trocars: " + (available.empty() ? "none" : available) + ")");
}

void applySceneTrocars(const scene::SceneDescription& scene, ScriptDefinition* script) {
  std::vector<Eigen::Vector3d> trocars;
  for (const InstrumentTrack& track : script->instruments) trocars.push_back(sceneTrocarForSlot(scene, track.slot));
  for (std::size_t i = 0; i < trocars.size(); ++i) script->instruments[i].trocar = trocars[i];
}

void applySceneTrocars(const scene::SceneDescription& scene, MarkerLayout* layout) {
  std::vector<Eigen::Vector3d> trocars;
  for (const InstrumentMarker& marker : layout->instruments) trocars.push_back(sceneTrocarForSlot(scene, marker.slot));
  for (std::size_t i = 0; i < trocars.size(); ++i) layout->instruments[i].trocar = trocars[i];
}

SurgeonScript applySceneTrocars(const scene::SceneDescription& scene, const SurgeonScript& script) {
  ScriptDefinition definition = script.definition();
  applySceneTrocars(scene, &definition);
  return SurgeonScript(std::move(definition));
}

}  // namespace vrm_tracking
