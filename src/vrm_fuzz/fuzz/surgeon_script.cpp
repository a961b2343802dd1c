// Scripted sessions (the one scripted-motion format, vrm_sim loadScriptFromString) played by vrm_tracking's
// SurgeonScript as the device twins do: a script the reader accepts is placed in a scene (playInScene), then sampled
// with tremor at the start, inside and past its end.
#include "vrm_tracking/surgeon_script.h"

#include "fuzz_target.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/scene_trocars.h"

VRM_FUZZ_TARGET(surgeon_script) {
  using namespace vrm_tracking;
  namespace scene = vrm_sim::scene;
  static const scene::SceneDescription fuzz_scene = [] {
    scene::SceneDescription made;
    made.name = "fuzz";
    made.eye.trocars = scene::defaultTrocars(made.eye.radius);
    scene::InstrumentDescription light;
    light.slot = scene::InstrumentSlot::kLeft;
    light.type = scene::InstrumentType::kLightPipe;
    light.trocar = "left";
    scene::InstrumentDescription forceps = light;
    forceps.slot = scene::InstrumentSlot::kRight;
    forceps.type = scene::InstrumentType::kForceps;
    forceps.trocar = "right";
    made.instruments = {light, forceps};
    return made;
  }();
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    SurgeonScript script = playInScene(fuzz_scene, scene::loadScriptFromString(text, "fuzzed.yaml"));
    const double duration = script.duration();
    script.setTremorAmplitude(1e-5);
    for (double t : {0.0, 0.5 * duration, duration, duration + 1.0, -1.0, 1e9}) script.sample(t);
    script.setPlayback(Playback::kOnce);
    script.sample(2.0 * duration + 0.1);
  } catch (const ScriptError&) {
    // the reader's or the player's error at a waypoint
  } catch (const std::runtime_error&) {
    // a slot the fuzz scene has no trocar for
  }
  return 0;
}
