#pragma once
// Scripted surgeon: the ground truth of the simulated EyeSi hardware (thesis §2.4.1, mediators; §7 hardware).
//
// A script is a set of keyframe tracks (eye rotation, one track per instrument slot, pedals, microscope knobs).
// sample(t) turns it into a plain snapshot that the device twins publish, and that later synthetic tracking
// cameras will render, so everything here is a pure function of (script, t, tremor seed) — no clock, no ROS.
//
// Frames and conventions (shared with the optical tracking pipeline):
//   * eye frame: origin at the eye's rotation centre (= sphere centre), +z anterior (pupil, towards the
//     microscope), the posterior pole of the retina at (0, 0, -radius).
//   * eye rotation: world -> eye (pose of the eye in world) about the fixed rotation centre given in world.
//   * instruments: the tip is scripted in the eye frame; the shaft always passes through the slot's trocar
//     (the fixed insertion hole of the mechanical eye), so shaft_axis = normalize(tip - trocar) and
//     insertion_depth = |tip - trocar|.

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "vrm_sim/scene/scene_description.h"

namespace vrm_tracking {

// Instrument types are vrm_sim's (scene::InstrumentType, names by scene::toString); vrm_sim::toMsgType /
// instrumentTypeFromMsg (vrm_sim/conversions.h) are the one bridge to the InstrumentState constants.

enum class Playback { kOnce, kLoop };

// A malformed or inconsistent script. what() reads "<source>:<line>: <field>: <message>" so an author can jump to
// the place; line is 1-based, 0 when unknown (programmatic scripts, unreadable files).
class ScriptError : public std::runtime_error {
 public:
  ScriptError(const std::string& source, int line, const std::string& field, const std::string& message);

  const std::string& source() const { return source_; }
  int line() const { return line_; }
  const std::string& field() const { return field_; }

 private:
  std::string source_;
  int line_;
  std::string field_;
};

struct EyeGeometry {
  double radius = 0.012;                                      // m, sphere of the mechanical eye
  double margin = 0.001;                                      // m, tips may be this far outside the sphere
  Eigen::Vector3d rotation_center = Eigen::Vector3d::Zero();  // m, in world
  int line = 0;
  // The file has no `eye:` block (the shipped ones don't): applySceneTrocars takes radius and rotation centre from
  // the scene (until then the defaults above, which are the shipped scenes' values).
  bool from_scene = false;
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
  bool finished = false;                                             // playback once and t beyond the last keyframe
  Eigen::Quaterniond eye_rotation = Eigen::Quaterniond::Identity();  // world -> eye
  Eigen::Vector3d rotation_center = Eigen::Vector3d::Zero();         // world, m
  std::vector<InstrumentSample> instruments;                         // in slot order of the script
  PedalSample pedals;
  MicroscopeSample microscope;
};

// Orientation of an instrument whose shaft runs through `trocar` along `shaft_axis`. Roll 0 puts the tip frame's
// x axis as close as possible to the circumferential tangent of the eye sphere at the trocar: a shaft through a
// point on the sphere with its tip inside can never be tangent, so this reference never degenerates (a world or
// eye axis would, e.g. for a shaft pointing straight down to the posterior pole).
Eigen::Quaterniond shaftOrientation(const Eigen::Vector3d& trocar, const Eigen::Vector3d& shaft_axis, double roll);

// ---- Script definition: the keyframes, as parsed or generated. Unspecified keyframe fields were carried over
// from the previous keyframe of the same track by the parser. `line` (1-based, 0 = unknown) feeds ScriptError.

struct EyeKeyframe {
  double t = 0.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  int line = 0;
};

// A keyframe tip written against a scene object (YAML `on:` / `height:`), so that scripts that touch tissue follow
// the scene file instead of a copy of its geometry. applyScene() (scene_trocars.h) resolves it: the closest point of
// the object's surface to `written_tip`, moved `height` along the surface normal that points into the eye (towards
// the eye centre). Until then, and where no scene is given, the keyframe plays `written_tip`.
struct SurfaceTarget {
  std::string object;   // scene object name; empty: the keyframe's tip is a plain eye-frame position
  double height = 0.0;  // m above the surface (towards the eye centre); negative: below it
  Eigen::Vector3d written_tip = Eigen::Vector3d::Zero();  // eye frame, m: the author's point near the object
  bool resolved = false;  // the keyframe's tip is the scene-resolved point (set by applyScene)

  bool active() const { return !object.empty(); }
};

struct InstrumentKeyframe {
  double t = 0.0;
  vrm_sim::scene::InstrumentType type = vrm_sim::scene::InstrumentType::kLightPipe;
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();  // what is played (the resolved point for a resolved target)
  SurfaceTarget target;
  double roll = 0.0;
  double jaw_angle = 0.0;
  double suction = 0.0;
  double cut_rate = 0.0;
  double injection_flow = 0.0;
  int line = 0;
};

struct InstrumentTrack {
  std::string slot;
  Eigen::Vector3d trocar = Eigen::Vector3d::Zero();
  // The script names no trocar for this slot (the shipped files don't: the scene is the one source of the trocars):
  // applySceneTrocars / applyScene (scene_trocars.h) must fill it in before the script is played (validated).
  bool trocar_from_scene = false;
  int line = 0;
  std::vector<InstrumentKeyframe> keyframes;
};

struct PedalKeyframe {
  double t = 0.0;
  PedalSample value;
  int line = 0;
};

struct MicroscopeKeyframe {
  double t = 0.0;
  MicroscopeSample value;
  int line = 0;
};

struct ScriptDefinition {
  std::string name;
  std::string source = "<memory>";  // file path or "<builtin:NAME>", used in error messages
  Playback playback = Playback::kLoop;
  EyeGeometry eye;
  std::vector<EyeKeyframe> eye_track;  // empty: identity
  std::vector<InstrumentTrack> instruments;
  std::vector<PedalKeyframe> pedal_track;            // empty: defaults
  std::vector<MicroscopeKeyframe> microscope_track;  // empty: defaults
  // Built-in scripts are meant for every scene: there a keyframe `on` an object the scene lacks keeps its written
  // tip. A file is written for a scene, so there a missing object is an error (see applyScene).
  bool targets_optional = false;
};

// Names of the scene objects the script's keyframes are written on (SurfaceTarget), unique, in order of first use.
std::vector<std::string> surfaceTargetObjects(const ScriptDefinition& definition);

// Physiological tremor (thesis §1.3: 8–10 Hz). A sum of sinusoids with frequencies, phases and weights drawn once
// from std::mt19937(seed), so the offset is a pure function of (seed, slot, t): the same recording replays
// identically whatever rate it is sampled at (§2.4.2, record the oracle's seed, not its answers).
class Tremor {
 public:
  // amplitude: m, bound of the offset per axis; 0 disables. num_slots: instrument count (each gets its own
  // independent draws, in slot order).
  Tremor(double amplitude, std::uint32_t seed, std::size_t num_slots);

  Eigen::Vector3d offset(std::size_t slot, double t) const;
  double amplitude() const { return amplitude_; }

 private:
  struct Component {
    double frequency;  // Hz
    double phase;      // rad
    double weight;     // weights of one axis sum to 1, so |offset| <= amplitude per axis
  };
  static constexpr int kComponentsPerAxis = 3;
  double amplitude_;
  std::vector<Component> components_;  // [slot][axis][component], flattened
};

class SurgeonScript {
 public:
  // Validates the definition (keyframe times >= 0 and strictly increasing, finite values, tips inside the eye
  // sphere + margin, trocars usable, unique slots); throws ScriptError.
  explicit SurgeonScript(ScriptDefinition definition);

  // Throws ScriptError naming the file, the 1-based line and the field path.
  static SurgeonScript fromFile(const std::string& path);
  static SurgeonScript fromYamlString(const std::string& text, const std::string& source = "<string>");
  // Procedural scripts so the simulator runs without a file; names: builtinNames(). Throws std::invalid_argument.
  static SurgeonScript builtin(const std::string& name);
  static std::vector<std::string> builtinNames();
  // What the nodelets' `script` parameter means: "" -> builtin("demo"), "builtin:NAME" -> builtin(NAME),
  // anything else -> fromFile(spec).
  static SurgeonScript load(const std::string& spec);
  // The same, not validated yet, for a caller that applies a scene first (a file may leave the trocars to the
  // scene). Throws ScriptError for a malformed file, std::invalid_argument for an unknown built-in.
  static ScriptDefinition loadDefinition(const std::string& spec);
  static ScriptDefinition definitionFromFile(const std::string& path);

  // t: seconds since the start of playback. Loop wraps at duration(); once holds the last keyframe afterwards.
  SurgeonSnapshot sample(double t) const;

  void setPlayback(Playback playback) { definition_.playback = playback; }
  // amplitude in m (0 = off); see Tremor.
  void setTremor(double amplitude, std::uint32_t seed);

  const ScriptDefinition& definition() const { return definition_; }
  Playback playback() const { return definition_.playback; }
  const std::string& name() const { return definition_.name; }
  // Time of the last keyframe over all tracks (0 for a static script).
  double duration() const { return duration_; }

 private:
  void validate() const;

  ScriptDefinition definition_;
  double duration_ = 0.0;
  std::shared_ptr<const Tremor> tremor_;
};

}  // namespace vrm_tracking
