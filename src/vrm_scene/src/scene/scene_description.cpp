#include "vrm_scene/scene_description.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/surface_target.h"

namespace vrm_sim {
namespace scene {
namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;
}  // namespace

const char* toString(SceneKind kind) { return kind == SceneKind::kAbstract ? "abstract" : "surgical"; }

const char* toString(ObjectRole role) {
  switch (role) {
    case ObjectRole::kRetina:
      return "retina";
    case ObjectRole::kMembrane:
      return "membrane";
    case ObjectRole::kIlm:
      return "ilm";
    case ObjectRole::kRigid:
      return "rigid";
    case ObjectRole::kAbstractTarget:
      return "abstract_target";
    case ObjectRole::kDecoration:
      return "decoration";
  }
  return "?";
}

const char* toString(ObjectFrame frame) { return frame == ObjectFrame::kWorld ? "world" : "eye"; }

const Registry<InstrumentType>& instrumentTypeRegistry() {
  // Order = the InstrumentTypes.msg constants (vrm_sim/conversions.h maps them); each name is also the name of
  // the type's mesh generator (scene/instrument_meshes.h).
  static const Registry<InstrumentType> registry(
      "instrument type",
      {{"light_pipe", InstrumentType::kLightPipe, "endoilluminator: the spotlight, no shadow"},
       {"forceps", InstrumentType::kForceps, "grasps with its jaws (membrane peeling)"},
       {"vitrector", InstrumentType::kVitrector, "aspirates and cuts at its port"},
       {"needle", InstrumentType::kNeedle, "a straight pointer (abstract scenarios)"},
       {"hook", InstrumentType::kHook, "a bent tip (abstract scenarios)"},
       {"laser_probe", InstrumentType::kLaserProbe, "endolaser: aiming beam, shots on the pedal (laser coagulation)"}});
  return registry;
}

const char* toString(InstrumentType type) {
  for (const auto& entry : instrumentTypeRegistry().entries()) {
    if (entry.make == type) return entry.name.c_str();
  }
  return "?";
}

std::optional<InstrumentType> instrumentTypeNamed(const std::string& name) {
  const auto* entry = instrumentTypeRegistry().find(name);
  return entry != nullptr ? std::optional<InstrumentType>(entry->make) : std::nullopt;
}

const char* toString(InstrumentSlot slot) { return slot == InstrumentSlot::kLeft ? "left" : "right"; }

const char* toString(Simulation simulation) {
  switch (simulation) {
    case Simulation::kTissue:
      return "tissue";
    case Simulation::kCollision:
      return "collision";
    case Simulation::kGrasping:
      return "grasping";
    case Simulation::kCutting:
      return "cutting";
    case Simulation::kBleeding:
      return "bleeding";
  }
  return "?";
}

Eigen::Vector3d PathTremor::offset(double t) const {
  if (!(amplitude > 0.0)) return Eigen::Vector3d::Zero();
  const double phase = 2.0 * kPi * frequency_hz * t;
  return amplitude *
         Eigen::Vector3d(std::sin(phase), std::sin(phase + 2.0 * kPi / 3.0), std::sin(phase + 4.0 * kPi / 3.0));
}

PedalWaypoint samplePedals(const std::vector<PedalWaypoint>& pedals, double t) {
  PedalWaypoint sample;
  if (!pedals.empty()) {
    const auto next = std::upper_bound(pedals.begin(), pedals.end(), t,
                                       [](double time, const PedalWaypoint& w) { return time < w.t; });
    if (next == pedals.begin()) {
      sample = pedals.front();
    } else {
      sample = *(next - 1);
      if (next != pedals.end()) {
        const double alpha = (t - sample.t) / (next->t - sample.t);
        sample.travel = (1.0 - alpha) * sample.travel + alpha * next->travel;
      }
    }
  }
  sample.t = t;
  return sample;
}

InstrumentWaypoint samplePath(const std::vector<InstrumentWaypoint>& path, double t) {
  InstrumentWaypoint sample = t <= path.front().t ? path.front() : path.back();
  if (t > path.front().t && t < path.back().t) {
    const auto next = std::upper_bound(path.begin(), path.end(), t,
                                       [](double time, const InstrumentWaypoint& w) { return time < w.t; });
    const InstrumentWaypoint& b = *next;
    const InstrumentWaypoint& a = *(next - 1);
    const double alpha = (t - a.t) / (b.t - a.t);
    sample = a;
    sample.tip_in_eye = (1.0 - alpha) * a.tip_in_eye + alpha * b.tip_in_eye;
    sample.jaw_angle_deg = (1.0 - alpha) * a.jaw_angle_deg + alpha * b.jaw_angle_deg;
    sample.suction = (1.0 - alpha) * a.suction + alpha * b.suction;
    sample.cut_rate_hz = (1.0 - alpha) * a.cut_rate_hz + alpha * b.cut_rate_hz;
    sample.roll_deg = (1.0 - alpha) * a.roll_deg + alpha * b.roll_deg;
    sample.injection_flow = (1.0 - alpha) * a.injection_flow + alpha * b.injection_flow;
  }
  // The instrument in hand: the last exchange at or before t (the first waypoint's before the path).
  sample.type.reset();
  for (std::size_t i = 0; i < path.size() && (i == 0 || path[i].t <= t); ++i) {
    if (path[i].type) sample.type = path[i].type;
  }
  sample.t = t;
  return sample;
}

const ScenarioParam* ScenarioDescription::param(const std::string& name) const {
  const auto found = params.find(name);
  return found == params.end() ? nullptr : &found->second;
}

const char* toString(Playback playback) { return playback == Playback::kLoop ? "loop" : "once"; }

Eigen::Quaterniond EyeWaypoint::rotation() const { return Eigen::Quaterniond(rotationFromRpy(rpy_deg * kDegToRad)); }

double ScriptedSession::duration() const {
  double end = 0.0;
  for (const ScriptedInstrument& instrument : instruments) {
    if (!instrument.path.empty()) end = std::max(end, instrument.path.back().t);
  }
  if (!eye.empty()) end = std::max(end, eye.back().t);
  if (!pedals.empty()) end = std::max(end, pedals.back().t);
  if (!microscope.empty()) end = std::max(end, microscope.back().t);
  return end;
}

const ScriptedInstrument* ScriptedSession::findInstrument(InstrumentSlot slot) const {
  for (const ScriptedInstrument& instrument : instruments) {
    if (instrument.slot == slot) return &instrument;
  }
  return nullptr;
}

const ScriptedSession& findScript(const SceneDescription& scene, const std::string& name) {
  std::string known;
  if (scene.scenario) {
    for (const auto& [script_name, session] : scene.scenario->scripts)
      known += (known.empty() ? "" : ", ") + script_name;
  }
  if (!scene.scenario || scene.scenario->scripts.count(name) == 0) {
    throw std::invalid_argument("scene '" + scene.name + "' has no scripted session '" + name + "'" +
                                (known.empty() ? std::string(" (it has none)") : " (it has: " + known + ")"));
  }
  return scene.scenario->scripts.at(name);
}

SceneDescription withScript(const SceneDescription& scene, const std::string& script) {
  return withScript(scene, resolveSurfaceTargets(scene, findScript(scene, script)));
}

SceneDescription withScript(const SceneDescription& scene, const ScriptedSession& script) {
  SceneDescription scripted = scene;
  for (auto& instrument : scripted.instruments) {
    instrument.path.clear();
    instrument.tremor = PathTremor{};
    const ScriptedInstrument* part = script.findInstrument(instrument.slot);
    if (part == nullptr) continue;
    instrument.path = part->path;
    instrument.tremor = part->tremor;
    if (part->type && *part->type != instrument.type) {
      instrument.type = *part->type;
      instrument.params = defaultInstrumentParams(instrument.type);
    }
  }
  return scripted;
}

Eigen::Isometry3d Pose::toIsometry() const {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.linear() = rotationFromRpy(rpy_deg * kDegToRad);
  transform.translation() = xyz;
  return transform;
}

bool SceneDescription::hasDeformableObjects() const {
  return std::any_of(objects.begin(), objects.end(),
                     [](const ObjectDescription& object) { return object.isDeformable(); });
}

double SceneDescription::scriptedDuration() const {
  double end = 0.0;
  for (const auto& instrument : instruments) {
    if (!instrument.path.empty()) end = std::max(end, instrument.path.back().t);
  }
  return end;
}

const ObjectDescription* SceneDescription::findObject(const std::string& object_name) const {
  for (const auto& object : objects) {
    if (object.name == object_name) return &object;
  }
  return nullptr;
}

const Trocar* SceneDescription::findTrocar(const std::string& trocar_name) const {
  for (const auto& trocar : eye.trocars) {
    if (trocar.name == trocar_name) return &trocar;
  }
  return nullptr;
}

const InstrumentDescription* SceneDescription::findInstrument(InstrumentSlot slot) const {
  for (const auto& instrument : instruments) {
    if (instrument.slot == slot) return &instrument;
  }
  return nullptr;
}

GeneratorParams defaultInstrumentParams(InstrumentType type) {
  return *defaultGeneratorParams(toString(type));  // instrument type names are generator names
}

std::vector<Trocar> defaultTrocars(double eye_radius) {
  const auto on_sphere = [eye_radius](double angle_from_axis_deg, double azimuth_deg) {
    const double polar = angle_from_axis_deg * kDegToRad, azimuth = azimuth_deg * kDegToRad;
    return Eigen::Vector3d(eye_radius * std::sin(polar) * std::cos(azimuth),
                           eye_radius * std::sin(polar) * std::sin(azimuth), eye_radius * std::cos(polar));
  };
  return {{"left", on_sphere(45.0, 150.0)}, {"right", on_sphere(45.0, 30.0)}};
}

}  // namespace scene
}  // namespace vrm_sim
