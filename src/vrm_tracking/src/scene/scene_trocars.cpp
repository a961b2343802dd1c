#include "vrm_tracking/scene_trocars.h"

#include <algorithm>
#include <map>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "vrm_scene/scene_loader.h"

namespace vrm_tracking {

namespace scene = vrm_sim::scene;

namespace {

std::string describeScene(const scene::SceneDescription& scene) {
  return "scene '" + scene.name + "' (" + (scene.source_file.empty() ? std::string("<memory>") : scene.source_file) +
         ")";
}

}  // namespace

std::string sceneOrDefault(const std::string& spec) { return spec.empty() ? vrm_sim::scene::kDefaultSceneName : spec; }

Eigen::Vector3d sceneTrocarForSlot(const scene::SceneDescription& scene, const std::string& slot) {
  std::string trocar_name = slot;
  for (const scene::InstrumentDescription& instrument : scene.instruments) {
    if (slot == scene::toString(instrument.slot)) trocar_name = instrument.trocar;
  }
  if (const scene::Trocar* trocar = scene.findTrocar(trocar_name)) return trocar->position_in_eye;
  std::string available;
  for (const scene::Trocar& trocar : scene.eye.trocars) available += (available.empty() ? "" : ", ") + trocar.name;
  throw std::runtime_error(describeScene(scene) + " has no trocar for instrument slot '" + slot +
                           "' (looked for trocar '" + trocar_name +
                           "'; the scene's trocars: " + (available.empty() ? "none" : available) + ")");
}

const char* const kDefaultScriptName = "demo";

bool isScenarioSpec(const std::string& spec) { return spec.rfind("scenario:", 0) == 0; }

scene::ScriptedSession loadSession(const std::string& spec, const scene::SceneDescription& scene) {
  if (isScenarioSpec(spec)) return scene::findScript(scene, spec.substr(9));
  return scene::loadScript(spec.empty() ? kDefaultScriptName : spec);
}

SurgeonScript playInScene(const scene::SceneDescription& scene, const scene::ScriptedSession& session,
                          scene::SurfaceTargetReport* report) {
  scene::ScriptedSession resolved = scene::resolveSurfaceTargets(scene, session, report);
  std::vector<ScriptTrack> tracks;
  for (const scene::ScriptedInstrument& instrument : resolved.instruments) {
    ScriptTrack track;
    const std::string slot = scene::toString(instrument.slot);
    track.trocar = sceneTrocarForSlot(scene, slot);
    const scene::InstrumentDescription* in_scene = scene.findInstrument(instrument.slot);
    if (instrument.type) {
      track.type = *instrument.type;
    } else if (in_scene != nullptr) {
      track.type = in_scene->type;
    } else {
      throw std::runtime_error(describeScene(scene) + " has no instrument in slot '" + slot + "' and script '" +
                               session.name + "' names no `type` for it");
    }
    tracks.push_back(track);
  }
  EyeGeometry eye;
  eye.radius = scene.eye.radius;
  eye.rotation_center = scene.eye.centre_in_world;
  const std::string source =
      session.location.file.empty() ? describeScene(scene) + " script '" + session.name + "'" : session.location.file;
  return SurgeonScript(std::move(resolved), eye, std::move(tracks), source);
}

void applySceneTrocars(const scene::SceneDescription& scene, MarkerLayout* layout) {
  std::vector<Eigen::Vector3d> trocars;
  for (const InstrumentMarker& marker : layout->instruments) trocars.push_back(sceneTrocarForSlot(scene, marker.slot));
  for (std::size_t i = 0; i < trocars.size(); ++i) {
    layout->instruments[i].trocar = trocars[i];
    layout->instruments[i].trocar_from_scene = false;
  }
}

Eigen::Vector3d applyScene(const scene::SceneDescription& scene, MarkerLayout* layout) {
  const Eigen::Vector3d layout_centre = layout->rotation_center;
  applySceneTrocars(scene, layout);  // throws before anything changed
  layout->rotation_center = scene.eye.centre_in_world;
  return layout_centre;
}

SceneIdentity sceneIdentity(const scene::SceneDescription& scene) {
  SceneIdentity identity;
  identity.name = scene.name;
  identity.file = scene.source_file;
  identity.difficulty = scene.scenario ? scene.scenario->difficulty : "";
  identity.content_hash = identity.file.empty() ? 0 : scene::sceneContentHash(identity.file, identity.difficulty);
  return identity;
}

bool sameScene(const SceneIdentity& a, const SceneIdentity& b) {
  return a.file == b.file && a.difficulty == b.difficulty && a.content_hash == b.content_hash;
}

}  // namespace vrm_tracking
