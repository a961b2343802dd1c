#pragma once
// The device twins' tracks for a scene's scripted session (issue 33, part 4). With script:=scenario:NAME the pedal and
// knob twins used to play the built-in demo's zoom/focus sweeps and buttons, so a saved frame was often out of focus
// and zoomed at random. Here they play tracks derived from the same scripted session the scripted surgeon plays: the
// microscope keeps the working plane in focus at a fixed zoom, the pedal follows the working instrument's suction and
// presses no buttons. ROS-free; every track is a pure function of the script time, so a session stays deterministic
// from its input stamps whatever the twins' tick phases.

#include <string>

#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

struct ScenarioFocusOptions {
  // World z of the microscope objective, looking down -z: vrm_render's MicroscopeRig (0.188 m puts the default
  // 0.2 m focus on the posterior pole of a 12 mm eye centred at the origin).
  double objective_z = 0.188;
  // The focal plane is the fundus under the working tip, raised with the tip by at most plane_height: what the
  // surgeon must see sharp there is the fundus and the tissue on it (an ILM ~0.05 mm, a membrane ~0.3 mm above it;
  // a vitreous sheet 1 mm above it is translucent). Following the tip itself put the fundus 0.7-1 mm out of focus
  // while the tip hovered or came down (run.sh's frame at 2.5 s: Laplacian variance 0.34x that without depth of
  // field); at zoom 1.5 the renderer blurs ~2 px per mm of defocus (vrm_render MicroscopeRig), 0.4 px at 0.2 mm.
  double plane_height = 0.2e-3;
  double window = 0.5;     // s: the target is averaged over the last `window` of script time (a focus motor's lag)
  double step = 0.01;      // s: grid the average samples the script on
  double key_step = 0.05;  // s between the keyframes of the tracks
  // The focus holds until the smoothed working plane has moved more than this from it, then refocuses there, as a
  // surgeon refocuses when the picture softens (at zoom 1.5, 0.1 mm of defocus blurs ~0.2 px). A focus that crept
  // with every tick changed the microscope's cameras every frame, so the renderer's static retina layer (issue 30)
  // was never reused: run.sh's session fell from 36 to 25 fps (issue 33's first latency run).
  double refocus_tolerance = 0.1e-3;
  double zoom = 1.5;  // fixed: the demo's working magnification (20 mm field at the focal plane)
  double ambient_light = 0.3;  // unless the scene's session has a microscope track (e.g. no light pipe: turned up)
};

// The focus distance (objective to focal plane, m) that puts the plane the working instrument `tool_slot` works in
// in focus at this snapshot (unsmoothed): its tip's world z clamped into [retina, retina + plane_height] on the
// vertical through the tip (the eye sphere of `eye_radius` about the snapshot's rotation centre; the eye frame's
// origin is that centre). No such instrument in the snapshot, or a tip outside the sphere's footprint: the posterior
// pole.
double scenarioFocusDistance(const SurgeonSnapshot& snapshot, const std::string& tool_slot, double eye_radius,
                             const ScenarioFocusOptions& options = {});

// A scripted session (playInScene(), scene_trocars.h) with its microscope and pedal tracks replaced: a keyframe
// every options.key_step s from 0 to the session's end; focus = scenarioFocusDistance() averaged over the last
// options.window s of script time (sampled every options.step s; from 0 at the start), held until that moves more
// than options.refocus_tolerance from it (then refocused onto it at the next keyframe), zoom and ambient light fixed;
// pedal travel = the working instrument's suction (a vitrectomy pedal's; 0 for a forceps), no buttons — unless the
// session has a pedal track of its own (issue 37: the laser fires on the pedal), which it keeps. The result plays
// once, like the session. Throws std::invalid_argument for non-positive steps, a negative window, plane_height or
// refocus_tolerance.
SurgeonScript withScenarioDeviceTracks(const SurgeonScript& session, const std::string& tool_slot,
                                       const ScenarioFocusOptions& options = {});

}  // namespace vrm_tracking
