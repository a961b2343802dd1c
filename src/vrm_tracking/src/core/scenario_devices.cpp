#include "vrm_tracking/scenario_devices.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace vrm_tracking {

double scenarioFocusDistance(const SurgeonSnapshot& snapshot, const std::string& tool_slot, double eye_radius,
                             const ScenarioFocusOptions& options) {
  const Eigen::Vector3d& centre = snapshot.rotation_center;
  const double pole_z = centre.z() - eye_radius;
  const auto tool = std::find_if(snapshot.instruments.begin(), snapshot.instruments.end(),
                                 [&](const InstrumentSample& sample) { return sample.slot == tool_slot; });
  if (tool == snapshot.instruments.end() || !tool->tip.allFinite()) return options.objective_z - pole_z;
  const Eigen::Vector3d tip = centre + snapshot.eye_rotation * tool->tip;
  const double lateral_sq = (tip.head<2>() - centre.head<2>()).squaredNorm();
  if (!(lateral_sq < eye_radius * eye_radius)) return options.objective_z - pole_z;
  const double retina_z = centre.z() - std::sqrt(eye_radius * eye_radius - lateral_sq);
  return options.objective_z - std::clamp(tip.z(), retina_z, retina_z + options.plane_height);
}

SurgeonScript withScenarioDeviceTracks(const SurgeonScript& session, const std::string& tool_slot,
                                       const ScenarioFocusOptions& options) {
  if (!(options.step > 0.0) || !(options.key_step > 0.0) || !(options.window >= 0.0) ||
      !(options.plane_height >= 0.0) || !(options.refocus_tolerance >= 0.0))
    throw std::invalid_argument(
        "scenario device tracks: need step, key_step > 0 and window, plane_height, refocus_tolerance >= 0");
  const double eye_radius = session.eye().radius;
  const double duration = session.duration();
  // The target on a grid of options.step from 0, then its running mean over the window (a pure function of the grid).
  const int samples = static_cast<int>(std::ceil(duration / options.step)) + 1;
  std::vector<double> target(samples), prefix(samples + 1, 0.0);
  for (int i = 0; i < samples; ++i) {
    target[i] = scenarioFocusDistance(session.sample(i * options.step), tool_slot, eye_radius, options);
    prefix[i + 1] = prefix[i] + target[i];
  }
  const int window = static_cast<int>(std::lround(options.window / options.step));
  const auto smoothed = [&](double t) {
    const int last = std::clamp(static_cast<int>(std::floor(t / options.step + 1e-9)), 0, samples - 1);
    const int first = std::max(0, last - window);
    return (prefix[last + 1] - prefix[first]) / (last + 1 - first);
  };

  vrm_sim::scene::ScriptedSession devices = session.session();
  // The scene's own microscope track (a session that sets the light, e.g. bimanual without a light pipe) keeps its
  // ambient light; focus and zoom stay the twin's.
  const bool scripted_light = !devices.microscope.empty();
  // Likewise its own pedal track (issue 37: the laser session fires on the pedal); without one the pedal follows the
  // tool's scripted suction.
  const bool scripted_pedals = !devices.pedals.empty();
  devices.name += " (scenario devices)";
  devices.playback = Playback::kOnce;
  devices.microscope.clear();
  if (!scripted_pedals) devices.pedals.clear();
  const int keys = static_cast<int>(std::ceil(duration / options.key_step)) + 1;
  double focus = smoothed(0.0);
  for (int k = 0; k < keys; ++k) {
    const double t = k * options.key_step;
    const double plane = smoothed(t);
    if (std::abs(plane - focus) > options.refocus_tolerance) focus = plane;
    vrm_sim::scene::MicroscopeWaypoint microscope;
    microscope.t = t;
    microscope.focus_distance = focus;
    microscope.zoom = options.zoom;
    microscope.ambient_light = scripted_light ? session.sample(t).microscope.ambient_light : options.ambient_light;
    devices.microscope.push_back(microscope);

    if (scripted_pedals) continue;
    vrm_sim::scene::PedalWaypoint pedal;
    pedal.t = t;
    for (const InstrumentSample& sample : session.sample(t).instruments) {
      if (sample.slot == tool_slot) pedal.travel = std::clamp(sample.suction, 0.0, 1.0);
    }
    devices.pedals.push_back(pedal);
  }
  return SurgeonScript(std::move(devices), session.eye(), session.tracks(), session.source());
}

}  // namespace vrm_tracking
