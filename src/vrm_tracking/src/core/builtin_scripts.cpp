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

// Where the demo expects the membrane: a copy of the membrane of vrm_sim's default scene (membrane_peeling: 0.3 mm
// above the retina, centred 8° from the posterior pole at azimuth 0). It only makes the written tips plausible;
// the keyframes are written `on: membrane`, so applyScene() puts them on the scene's membrane, wherever it is.
constexpr double kNominalMembraneHeight = 0.0003;        // m above the retina
constexpr double kNominalMembraneCentreOffsetDeg = 8.0;  // from the posterior pole, towards azimuth 0

// Point `height` above (towards the eye centre; negative: below) the nominal membrane, `arc` metres along the
// membrane from its centre towards azimuth `azimuth` (about the optical axis, 0 = +x).
Eigen::Vector3d nominalMembranePoint(double eye_radius, double arc, double azimuth, double height) {
  const double membrane_radius = eye_radius - kNominalMembraneHeight;
  const double offset = kNominalMembraneCentreOffsetDeg * kDeg;
  const Eigen::Vector3d centre_direction(std::sin(offset), 0.0, -std::cos(offset));
  Eigen::Vector3d towards(std::cos(azimuth), std::sin(azimuth), 0.0);
  towards = (towards - towards.dot(centre_direction) * centre_direction).normalized();  // tangent at the centre
  const double angle = arc / membrane_radius;
  const Eigen::Vector3d direction = std::cos(angle) * centre_direction + std::sin(angle) * towards;
  return (membrane_radius - height) * direction;
}

// "demo" (40 s loop): eye gently rotating ±5°; left light pipe circling above the posterior pole; right forceps
// peeling the membrane within the first 14 s (so a short session shows it): it grasps the membrane between its
// adhesion ring and its edge on the side facing the right trocar, lifts it 1.2 mm while pulling it 1 mm towards the
// membrane centre, releases it and withdraws. Pedal travel, the cutter switch, zoom/focus buttons and the
// microscope knobs change along the way. Every track ends where it starts so the loop is seamless.
ScriptDefinition makeDemo() {
  ScriptDefinition d;
  d.name = "demo";
  d.source = "<builtin:demo>";
  d.playback = Playback::kLoop;
  // The demo runs with every scene; where one has no membrane, the grasp keyframes keep their written tips.
  d.targets_optional = true;
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
    key.type = vrm_sim::scene::InstrumentType::kLightPipe;
    const double angle = 2.0 * kPi * i / 36.0;
    key.tip = Eigen::Vector3d(0.003 * std::cos(angle), 0.003 * std::sin(angle), -0.004);
    left.keyframes.push_back(key);
  }
  d.instruments.push_back(left);

  InstrumentTrack right;
  right.slot = "right";
  const double right_azimuth = 30.0 * kDeg;
  right.trocar = spherePoint(r, 45.0 * kDeg, right_azimuth);
  const Eigen::Vector3d start(0.001, 0.0, -0.006);
  // Grasp 2 mm from the membrane centre towards the right trocar: outside the adhesion ring (0.6 x the 2.5 mm patch
  // radius = 1.5 mm), inside the edge, and on the side the shaft comes from, so the jaws reach it.
  const double grasp_arc = 0.002;
  const double peel_arc = grasp_arc - 0.001;  // peel 1 mm towards the centre, against the adhesion points
  // vrm_sim grasps the nodes between the tip and 1.5 mm behind it along the shaft (TissueSimulator::updateGrasp), so
  // the tip goes just below the membrane before the jaws close; the open jaws push only what lies under the blades.
  const double grasp_height = -0.00006;
  const double approach_height = 0.0004;
  const double peel_height = 0.0012;
  const double open = 0.35;  // rad
  auto forceps = [&](double t, const Eigen::Vector3d& tip, double jaw) {
    InstrumentKeyframe key;
    key.t = t;
    key.type = vrm_sim::scene::InstrumentType::kForceps;
    key.tip = tip;
    key.jaw_angle = jaw;
    right.keyframes.push_back(key);
  };
  auto forcepsOnMembrane = [&](double t, double arc, double height, double jaw) {
    forceps(t, nominalMembranePoint(r, arc, right_azimuth, height), jaw);
    SurfaceTarget& target = right.keyframes.back().target;
    target.object = "membrane";
    target.height = height;
    target.written_tip = right.keyframes.back().tip;
  };
  forceps(0.0, start, open);
  forceps(1.0, start, open);                                 // rest
  forcepsOnMembrane(4.2, grasp_arc, approach_height, open);  // above the grasp point
  forcepsOnMembrane(5.2, grasp_arc, grasp_height, open);     // descend, slowly, jaws open
  forcepsOnMembrane(5.5, grasp_arc, grasp_height, open);     // settle
  forcepsOnMembrane(5.8, grasp_arc, grasp_height, 0.0);      // close: grasp
  forcepsOnMembrane(9.8, peel_arc, peel_height, 0.0);        // peel: lift and pull towards the centre
  forcepsOnMembrane(10.3, peel_arc, peel_height, 0.0);       // hold
  forcepsOnMembrane(10.6, peel_arc, peel_height, open);      // release
  forceps(14.0, start, open);                                // withdraw
  forceps(period, start, open);
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

SurgeonScript SurgeonScript::load(const std::string& spec) { return SurgeonScript(loadDefinition(spec)); }

ScriptDefinition SurgeonScript::loadDefinition(const std::string& spec) {
  static const std::string kPrefix = "builtin:";
  if (spec.empty() || spec.compare(0, kPrefix.size(), kPrefix) == 0) {
    const std::string name = spec.empty() ? "demo" : spec.substr(kPrefix.size());
    const auto it = registry().find(name);
    if (it == registry().end()) throw std::invalid_argument("no built-in surgeon script named '" + name + "'");
    return it->second();
  }
  return definitionFromFile(spec);
}

std::vector<std::string> SurgeonScript::builtinNames() {
  std::vector<std::string> names;
  for (const auto& entry : registry()) names.push_back(entry.first);
  return names;
}

}  // namespace vrm_tracking
