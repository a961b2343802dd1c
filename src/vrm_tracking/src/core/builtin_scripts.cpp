// Procedural scripts, so the simulator graph runs (and its tests pass) without any file on disk. They are generated
// as ordinary keyframes and go through the same validation and sampling as a parsed file.

#include <cmath>
#include <functional>
#include <map>

#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// Point on the eye sphere at polar angle `polar` from the anterior axis (+z) and azimuth `azimuth` about it. Pars
// plana trocars sit roughly 45° from the optical axis; the demo uses the same "left"/"right" trocars as vrm_sim's
// default scene (45°, azimuth 150°/30°), so the scene's trocar frames and the scripted shafts agree.
Eigen::Vector3d spherePoint(double radius, double polar, double azimuth) {
  return radius *
         Eigen::Vector3d(std::sin(polar) * std::cos(azimuth), std::sin(polar) * std::sin(azimuth), std::cos(polar));
}

// "demo" (40 s loop): eye gently rotating ±5°; left light pipe circling above the posterior pole; right forceps
// approaching a point 0.5 mm above the retina at 0.5 mm/s, closing its jaws, pulling back and releasing; pedal
// travel, the cutter switch, zoom/focus buttons and the microscope knobs change along the way. Every track ends
// where it starts so the loop is seamless.
ScriptDefinition makeDemo() {
  ScriptDefinition d;
  d.name = "demo";
  d.source = "<builtin:demo>";
  d.playback = Playback::kLoop;
  const double period = 40.0;
  const double r = d.eye.radius;

  // Eye: ±5° about x and y at incommensurate-looking but loop-periodic frequencies, sampled every 0.5 s (slerp
  // between samples stays within a few µrad of the sinusoid at this rate).
  for (double t = 0.0; t <= period + 1e-9; t += 0.5) {
    const double roll = 5.0 * kDeg * std::sin(2.0 * kPi * t / period);
    const double pitch = 5.0 * kDeg * std::sin(2.0 * 2.0 * kPi * t / period);
    EyeKeyframe key;
    key.t = t;
    key.rotation =
        Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
    d.eye_track.push_back(key);
  }

  InstrumentTrack left;
  left.slot = "left";
  left.trocar = spherePoint(r, 45.0 * kDeg, 150.0 * kDeg);
  // Light pipe: 3 mm circle 4 mm below the centre, one turn per 10 s, 10° per keyframe.
  for (int i = 0; i <= 4 * 36; ++i) {
    InstrumentKeyframe key;
    key.t = period * i / (4.0 * 36.0);
    key.type = InstrumentType::kLightPipe;
    const double angle = 2.0 * kPi * i / 36.0;
    key.tip = Eigen::Vector3d(0.003 * std::cos(angle), 0.003 * std::sin(angle), -0.004);
    left.keyframes.push_back(key);
  }
  d.instruments.push_back(left);

  InstrumentTrack right;
  right.slot = "right";
  right.trocar = spherePoint(r, 45.0 * kDeg, 30.0 * kDeg);
  const Eigen::Vector3d start(0.001, 0.0, -0.006);
  const double above_retina = 0.0005;
  const Eigen::Vector3d target(0.001, 0.0, -std::sqrt(std::pow(r - above_retina, 2) - 0.001 * 0.001));
  const double travel_time = (target - start).norm() / 0.0005;  // 0.5 mm/s
  auto forceps = [&](double t, const Eigen::Vector3d& tip, double jaw, double roll) {
    InstrumentKeyframe key;
    key.t = t;
    key.type = InstrumentType::kForceps;
    key.tip = tip;
    key.jaw_angle = jaw;
    key.roll = roll;
    right.keyframes.push_back(key);
  };
  const double open = 0.35;  // rad
  double t = 2.0;
  forceps(0.0, start, open, 0.0);
  forceps(t, start, open, 0.0);
  forceps(t += travel_time, target, open, 0.0);
  forceps(t += 1.5, target, 0.0, 0.0);         // grasp
  forceps(t += travel_time, start, 0.0, 0.4);  // peel back, rolling the wrist a little
  forceps(t += 2.0, start, open, 0.0);         // release
  forceps(period, start, open, 0.0);
  d.instruments.push_back(right);

  auto pedal = [&](double time, double travel, bool cutter, bool zoom_in, bool zoom_out, bool near, bool far) {
    PedalKeyframe key;
    key.t = time;
    key.value.travel = travel;
    key.value.instrument_switch = cutter;
    key.value.zoom_in = zoom_in;
    key.value.zoom_out = zoom_out;
    key.value.focus_near = near;
    key.value.focus_far = far;
    d.pedal_track.push_back(key);
  };
  // The zoom/focus buttons are pressed for equal times in both directions, so the knob twin returns each loop.
  pedal(0.0, 0.0, false, false, false, false, false);
  pedal(4.0, 0.0, false, true, false, false, false);
  pedal(5.0, 0.0, false, false, false, false, false);
  pedal(8.0, 0.6, false, false, false, false, false);
  pedal(14.0, 0.6, true, false, false, true, false);
  pedal(15.0, 0.6, false, false, false, false, false);
  pedal(20.0, 0.6, false, false, false, false, false);
  pedal(22.0, 0.0, false, false, false, false, false);
  pedal(30.0, 0.0, false, false, true, false, true);
  pedal(31.0, 0.0, false, false, false, false, false);
  pedal(period, 0.0, false, false, false, false, false);

  auto microscope = [&](double time, double focus, double zoom, double light) {
    MicroscopeKeyframe key;
    key.t = time;
    key.value.focus_distance = focus;
    key.value.zoom = zoom;
    key.value.ambient_light = light;
    key.value.disparity_scale = 1.0;
    d.microscope_track.push_back(key);
  };
  microscope(0.0, 0.200, 1.0, 0.3);
  microscope(10.0, 0.195, 1.5, 0.3);
  microscope(30.0, 0.195, 1.5, 0.2);
  microscope(35.0, 0.200, 1.0, 0.3);
  microscope(period, 0.200, 1.0, 0.3);
  return d;
}

const std::map<std::string, std::function<ScriptDefinition()>>& registry() {
  static const std::map<std::string, std::function<ScriptDefinition()>> scripts = {{"demo", makeDemo}};
  return scripts;
}

}  // namespace

SurgeonScript SurgeonScript::builtin(const std::string& name) {
  const auto it = registry().find(name);
  if (it == registry().end()) throw std::invalid_argument("no built-in surgeon script named '" + name + "'");
  return SurgeonScript(it->second());
}

SurgeonScript SurgeonScript::load(const std::string& spec) {
  static const std::string kPrefix = "builtin:";
  if (spec.empty()) return builtin("demo");
  if (spec.compare(0, kPrefix.size(), kPrefix) == 0) return builtin(spec.substr(kPrefix.size()));
  return fromFile(spec);
}

std::vector<std::string> SurgeonScript::builtinNames() {
  std::vector<std::string> names;
  for (const auto& entry : registry()) names.push_back(entry.first);
  return names;
}

}  // namespace vrm_tracking
