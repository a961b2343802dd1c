// Surgeon scripts (vrm_tracking surgeon_script.h): a script the parser accepts is played (sample()) as the device
// twins do, with tremor, at the start, inside and past its end.
#include "vrm_tracking/surgeon_script.h"

#include "fuzz_target.h"

VRM_FUZZ_TARGET(surgeon_script) {
  using namespace vrm_tracking;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    SurgeonScript script = SurgeonScript::fromYamlString(text, "fuzzed.yaml");
    const double duration = script.duration();
    script.setTremor(1e-5, 7);
    for (double t : {0.0, 0.5 * duration, duration, duration + 1.0, -1.0, 1e9}) script.sample(t);
    script.setPlayback(Playback::kOnce);
    script.sample(2.0 * duration + 0.1);
  } catch (const ScriptError&) {
  }
  return 0;
}
