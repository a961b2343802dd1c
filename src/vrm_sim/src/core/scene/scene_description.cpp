#include "vrm_sim/scene/scene_description.h"

#include <algorithm>
#include <cmath>

#include "vrm_sim/scene/mesh_utils.h"

namespace vrm_sim {
namespace scene {
namespace {
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
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

const char* toString(TissueModel model) {
  switch (model) {
    case TissueModel::kNone:
      return "none";
    case TissueModel::kMassSpring:
      return "mass_spring";
    case TissueModel::kChainmail:
      return "chainmail";
  }
  return "?";
}

const char* toString(InstrumentType type) {
  switch (type) {
    case InstrumentType::kLightPipe:
      return "light_pipe";
    case InstrumentType::kForceps:
      return "forceps";
    case InstrumentType::kVitrector:
      return "vitrector";
    case InstrumentType::kNeedle:
      return "needle";
    case InstrumentType::kHook:
      return "hook";
  }
  return "?";
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

const std::vector<std::string>& knownIntegrators() {
  static const std::vector<std::string> names = {"explicit_euler", "quasi_static_euler", "rk2",
                                                 "implicit_euler", "symplectic_euler",   "xpbd"};
  return names;
}

const std::vector<std::string>& knownCollisionDetectors() {
  // zcoll / zcoll_f name the thesis' algorithms and use the fastest backend here (CPU); the rest pick a backend.
  static const std::vector<std::string> names = {"zcoll",      "zcoll_f",        "zcoll_cpu", "zcoll_f_cpu", "zcoll_gl",
                                                 "zcoll_f_gl", "myszkowski_cpu", "geometric", "fcl",         "fcl_aabb",
                                                 "fcl_obbrss", "fcl_kios",       "none"};
  return names;
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
