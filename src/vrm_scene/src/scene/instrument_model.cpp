#include "vrm_scene/instrument_model.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <variant>

#include "vrm_scene/scene_loader.h"

namespace vrm_sim {
namespace scene {

namespace {
constexpr double kRadToDeg = 180.0 / M_PI;
constexpr double kDegToRad = M_PI / 180.0;  // not 1 / kRadToDeg: the scripted jaw angles keep their bit patterns
}  // namespace

InstrumentDescription instrumentOfType(const InstrumentDescription& configured, InstrumentType type) {
  InstrumentDescription instrument = configured;
  if (type != configured.type) {
    instrument.type = type;
    instrument.params = defaultInstrumentParams(type);
  }
  return instrument;
}

bool allowsType(const InstrumentDescription& configured, InstrumentType type) {
  return type == configured.type || std::find(configured.alternatives.begin(), configured.alternatives.end(), type) !=
                                        configured.alternatives.end();
}

InstrumentType typeAfterRequest(const InstrumentDescription& configured, InstrumentType current,
                                std::optional<InstrumentType> requested) {
  return requested && allowsType(configured, *requested) ? *requested : current;
}

int jawStepDeg(InstrumentType type, double jaw_angle_rad) {
  if (type != InstrumentType::kForceps || !std::isfinite(jaw_angle_rad)) return 0;
  return static_cast<int>(std::lround(std::clamp(jaw_angle_rad, 0.0, kMaxJawOpening) * kRadToDeg));
}

std::string applyInstrumentSettings(InstrumentDescription& instrument, const std::string& settings) {
  auto* laser = std::get_if<LaserProbeParams>(&instrument.params);
  if (laser == nullptr) return std::string("a ") + toString(instrument.type) + " has no settings";
  struct Range {
    const char* key;
    double LaserProbeParams::*field;
    double minimum, maximum;
    bool zero_allowed;
  };
  // The ranges of the scene file (scene_loader.cpp: readParams for LaserProbeParams).
  static constexpr Range kRanges[] = {{"power_mw", &LaserProbeParams::power_mw, 0.0, 3000.0, false},
                                      {"duration_ms", &LaserProbeParams::duration_ms, 0.0, 5000.0, false},
                                      {"interval_ms", &LaserProbeParams::interval_ms, 0.0, 5000.0, true}};
  LaserProbeParams changed = *laser;
  std::size_t begin = 0;
  while (begin <= settings.size()) {
    const std::size_t end = std::min(settings.find(',', begin), settings.size());
    const std::string entry = settings.substr(begin, end - begin);
    const std::size_t equals = entry.find('=');
    const std::string key = entry.substr(0, equals);
    const Range* range = nullptr;
    for (const Range& candidate : kRanges) {
      if (key == candidate.key) range = &candidate;
    }
    if (equals == std::string::npos || range == nullptr) {
      return "'" + entry + "': expected power_mw=, duration_ms= or interval_ms= with a number";
    }
    const std::string text = entry.substr(equals + 1);
    char* parsed_end = nullptr;
    const double value = std::strtod(text.c_str(), &parsed_end);
    const bool in_range = std::isfinite(value) && value <= range->maximum &&
                          (value > range->minimum || (range->zero_allowed && value == range->minimum));
    if (text.empty() || parsed_end != text.c_str() + text.size() || !in_range) {
      return "'" + entry + "': " + key + " must be a number in " + (range->zero_allowed ? "[" : "(") +
             std::to_string(static_cast<int>(range->minimum)) + ", " +
             std::to_string(static_cast<int>(range->maximum)) + "]";
    }
    changed.*(range->field) = value;
    begin = end + 1;
  }
  *laser = changed;
  return "";
}

TriangleMesh instrumentMesh(const InstrumentDescription& instrument, int jaw_deg) {
  InstrumentDescription at_opening = instrument;
  if (auto* forceps = std::get_if<ForcepsParams>(&at_opening.params)) forceps->jaw_angle_deg = jaw_deg;
  return buildInstrumentMesh(at_opening);
}

Eigen::Quaterniond shaftOrientation(const Eigen::Vector3d& trocar, const Eigen::Vector3d& shaft_axis, double roll) {
  const Eigen::Vector3d z = shaft_axis.normalized();
  const Eigen::Vector3d normal = trocar.normalized();
  Eigen::Vector3d tangent = Eigen::Vector3d::UnitZ().cross(normal);
  // A trocar on the eye's optical axis has no circumferential direction; any fixed tangent will do there.
  if (tangent.squaredNorm() < 1e-12) tangent = Eigen::Vector3d::UnitX().cross(normal);
  Eigen::Vector3d x = tangent - tangent.dot(z) * z;
  if (x.squaredNorm() < 1e-12) x = z.unitOrthogonal();  // only for shafts tangent to the sphere (tip outside)
  x.normalize();
  Eigen::Matrix3d basis;
  basis.col(0) = x;
  basis.col(1) = z.cross(x);
  basis.col(2) = z;
  return (Eigen::Quaterniond(basis) * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ())).normalized();
}

ScriptedPose scriptedPose(const SceneDescription& scene, const InstrumentDescription& instrument, double t) {
  const auto& path = instrument.path;
  if (path.empty()) throw std::invalid_argument("scriptedPose: instrument has no path");
  const InstrumentWaypoint sample = samplePath(path, t);
  const Eigen::Vector3d tip = sample.tip_in_eye + instrument.tremor.offset(t);
  ScriptedPose input;
  // Instrument frame: +z from the handle to the tip, i.e. from the trocar (the pivot) to the tip.
  const Trocar* trocar = scene.findTrocar(instrument.trocar);
  Eigen::Vector3d axis = trocar != nullptr ? Eigen::Vector3d(tip - trocar->position_in_eye) : Eigen::Vector3d(0, 0, -1);
  if (axis.norm() < 1e-9) axis = Eigen::Vector3d(0, 0, -1);
  input.pose = Eigen::Isometry3d::Identity();
  if (trocar != nullptr) {
    input.pose.linear() =
        shaftOrientation(trocar->position_in_eye, axis, sample.roll_deg * kDegToRad).toRotationMatrix();
  } else {
    const Eigen::Vector3d z = axis.normalized();
    const Eigen::Vector3d x = z.unitOrthogonal();
    input.pose.linear().col(0) = x;
    input.pose.linear().col(1) = z.cross(x);
    input.pose.linear().col(2) = z;
  }
  input.pose.translation() = tip;
  input.jaw_angle = sample.jaw_angle_deg * kDegToRad;
  return input;
}

}  // namespace scene
}  // namespace vrm_sim
