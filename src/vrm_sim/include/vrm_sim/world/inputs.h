#pragma once
// The inputs of the VR part (core types; vrm_sim/conversions.h converts the messages): what the devices or their
// twins deliver, and what the mediator (world/mediator.h) groups into frames for the World (world/world.h).

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "vrm_scene/scene_description.h"
#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace world {

using Stamp = std::int64_t;  // ns since the epoch of the input stamps
constexpr double toSeconds(Stamp stamp) { return 1e-9 * static_cast<double>(stamp); }
Stamp fromSeconds(double seconds);

// ---- inputs (core types; vrm_sim/conversions.h converts the messages) ----

struct EyeState {
  Stamp stamp = 0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // world <- eye about the rotation centre
  Eigen::Vector3d rotation_center = Eigen::Vector3d::Zero();     // m, world
  bool valid = true;
};

struct InstrumentState {
  Stamp stamp = 0;
  std::string slot;                           // "left" | "right"
  std::optional<scene::InstrumentType> type;  // nullopt: keep the slot's current type
  // The instrument frame (origin at the tip, +z from the handle towards the tip) in frame_id, as position and unit
  // quaternion like the message, so converting a message is lossless and a replay feeds the very same numbers.
  Eigen::Vector3d tip_position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond tip_orientation = Eigen::Quaterniond::Identity();
  std::string frame_id = "eye";  // "eye" | "world" ("" = eye)
  double jaw_angle = 1.0;        // rad, forceps opening
  double suction = 0.0;          // 0..1
  double cut_rate = 0.0;         // Hz
  double injection_flow = 0.0;   // m^3/s, the needle's injection (subretinal fluid)
  bool valid = true;             // false: not tracked; keeps its pose, stops interacting

  void setPose(const Eigen::Isometry3d& pose);
  Eigen::Isometry3d pose() const;  // the quaternion normalised
};

struct PedalState {
  Stamp stamp = 0;
  double travel = 0.0;
  bool reflux = false;
  bool instrument_switch = false;
  bool zoom_in = false, zoom_out = false, focus_near = false, focus_far = false;
  void transferState(StateArchive& archive) {
    archive(stamp)(travel)(reflux)(instrument_switch)(zoom_in)(zoom_out)(focus_near)(focus_far);
  }
};

struct ScenarioCommand {
  enum class Type { kLoad, kStart, kPause, kResume, kStop, kReset, kSelectInstrument };
  Stamp stamp = 0;
  Type command = Type::kStart;
  std::string scenario;  // kLoad
  std::string argument;  // kSelectInstrument: "slot:type", e.g. "right:vitrector"; kLoad: difficulty; kStop: reason
  std::uint32_t seed = 0;
};

enum class Severity { kInfo, kWarning };
using Log = std::function<void(Severity, const std::string&)>;

}  // namespace world
}  // namespace vrm_sim
