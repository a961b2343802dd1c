#pragma once
// Scripted surgeon: the ground truth of the simulated EyeSi hardware (thesis §2.4.1, mediators; §7 hardware).
//
// It plays a scripted session in the one scripted-motion format, the scene's (vrm_sim::scene::ScriptedSession: a
// scene's scenario.scripts or a script file, scene_description.h): eye rotation, one path per instrument slot, pedal
// and microscope tracks, each instrument's tremor. sample(t) turns it into a plain snapshot that the device twins
// publish and the synthetic tracking cameras render, so everything here is a pure function of (script, t) — no clock,
// no ROS. playInScene() (scene_trocars.h) builds one for a scene: waypoints on scene objects resolved, trocars and eye
// from the scene.
//
// Frames and conventions (shared with the optical tracking pipeline):
//   * eye frame: origin at the eye's rotation centre (= sphere centre), +z anterior (pupil, towards the
//     microscope), the posterior pole of the retina at (0, 0, -radius).
//   * eye rotation: world -> eye (pose of the eye in world) about the fixed rotation centre given in world.
//   * instruments: the tip is scripted in the eye frame; the shaft always passes through the slot's trocar
//     (the fixed insertion hole of the mechanical eye), so shaft_axis = normalize(tip - trocar) and
//     insertion_depth = |tip - trocar|.

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "vrm_scene/instrument_model.h"
#include "vrm_scene/scene_description.h"

namespace vrm_tracking {

// Instrument types are vrm_sim's (scene::InstrumentType, names by scene::toString); vrm_sim::toMsgType /
// instrumentTypeFromMsg (vrm_sim/conversions.h) are the one bridge to the InstrumentState constants.

using Playback = vrm_sim::scene::Playback;

// A script that cannot be played: the strict reader's error, at the waypoint ("<file>:<line>:<column>: <field>:
// <problem>"), for malformed files (loadScript) and for sessions that do not fit the eye they play in.
using ScriptError = vrm_sim::YamlError;

struct EyeGeometry {
  double radius = 0.012;                                      // m, sphere of the mechanical eye
  double margin = 0.001;                                      // m, tips may be this far outside the sphere
  Eigen::Vector3d rotation_center = Eigen::Vector3d::Zero();  // m, in world
};

struct PedalSample {
  double travel = 0.0;  // 0..1
  bool reflux = false;
  bool instrument_switch = false;
  bool zoom_in = false;
  bool zoom_out = false;
  bool focus_near = false;
  bool focus_far = false;
};

struct MicroscopeSample {
  double focus_distance = 0.2;   // m, objective to focal plane
  double zoom = 1.0;             // magnification (1 = widest field)
  double ambient_light = 0.5;    // 0..1
  double disparity_scale = 1.0;  // 0..1
};

struct InstrumentSample {
  std::string slot;  // "left" / "right": the trocar it goes through
  vrm_sim::scene::InstrumentType type = vrm_sim::scene::InstrumentType::kLightPipe;
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();          // eye frame, m (tremor included)
  Eigen::Vector3d trocar = Eigen::Vector3d::Zero();       // eye frame, m
  Eigen::Vector3d shaft_axis = Eigen::Vector3d::UnitZ();  // unit, handle -> tip
  double insertion_depth = 0.0;                           // m, |tip - trocar|
  double roll = 0.0;                                      // rad about the shaft
  double jaw_angle = 0.0;                                 // rad
  double suction = 0.0;                                   // 0..1
  double cut_rate = 0.0;                                  // Hz
  double injection_flow = 0.0;                            // m^3/s
  // Tip orientation in the eye frame: +z along shaft_axis, rotated by roll (see shaftOrientation()).
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

struct SurgeonSnapshot {
  double script_time = 0.0;                                          // s, after loop wrap / end clamp
  bool finished = false;                                             // playback once and t beyond the last waypoint
  Eigen::Quaterniond eye_rotation = Eigen::Quaterniond::Identity();  // world -> eye
  Eigen::Vector3d rotation_center = Eigen::Vector3d::Zero();         // world, m
  std::vector<InstrumentSample> instruments;                         // in the session's instrument order
  PedalSample pedals;
  MicroscopeSample microscope;
};

// Orientation of an instrument whose shaft runs through `trocar` along `shaft_axis` (roll 0: x along the eye's
// circumferential tangent at the trocar): the simulation's own, so a scripted roll means the same offline and here.
using vrm_sim::scene::shaftOrientation;

// What the scene decides for one scripted instrument (in the session's instrument order).
struct ScriptTrack {
  Eigen::Vector3d trocar = Eigen::Vector3d::Zero();  // eye frame, m
  // The instrument in hand until a waypoint names another: the session's `type`, else the scene's in the slot.
  vrm_sim::scene::InstrumentType type = vrm_sim::scene::InstrumentType::kLightPipe;
};

class SurgeonScript {
 public:
  // Validates the session against the eye (tips inside the sphere + margin, trocars on it, finite values in range,
  // waypoint times increasing; a session built in code is checked like a file) and takes one ScriptTrack per
  // scripted instrument; throws ScriptError at the offending waypoint. Waypoints `on` scene objects must have been
  // resolved (playInScene does it). `source` names the script in logs.
  SurgeonScript(vrm_sim::scene::ScriptedSession session, const EyeGeometry& eye, std::vector<ScriptTrack> tracks,
                std::string source);

  // t: seconds since the start of playback. Loop wraps at duration(); once holds the last waypoint afterwards.
  SurgeonSnapshot sample(double t) const;

  void setPlayback(Playback playback) { session_.playback = playback; }
  // Every instrument's tremor amplitude, m (0 = off; the frequency stays the script's): a hand other than the
  // script's (the nodelets' ~tremor_um, tracking_eval --tremor-um). std::invalid_argument unless finite and >= 0.
  void setTremorAmplitude(double amplitude);

  const vrm_sim::scene::ScriptedSession& session() const { return session_; }
  const EyeGeometry& eye() const { return eye_; }
  const std::vector<ScriptTrack>& tracks() const { return tracks_; }
  const std::string& source() const { return source_; }
  Playback playback() const { return session_.playback; }
  const std::string& name() const { return session_.name; }
  // Time of the last waypoint over all tracks (0 for a static script).
  double duration() const { return duration_; }

 private:
  void validate() const;

  vrm_sim::scene::ScriptedSession session_;
  EyeGeometry eye_;
  std::vector<ScriptTrack> tracks_;
  std::string source_;
  double duration_ = 0.0;
};

}  // namespace vrm_tracking
