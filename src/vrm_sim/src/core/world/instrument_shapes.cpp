#include "vrm_sim/world/instrument_shapes.h"

#include <algorithm>
#include <type_traits>
#include <variant>

namespace vrm_sim {
namespace world {
namespace {
constexpr double kRadToDeg = 180.0 / M_PI;  // as scene::jawStepDeg rounds with it, so the capsules match the mesh
}  // namespace

using namespace scene;  // the instrument description's parameter types

tissue::InstrumentInput tissueShape(const InstrumentDescription& instrument) {
  tissue::InstrumentInput shape;
  const ShaftParams* shaft = nullptr;
  std::visit(
      [&](const auto& params) {
        using T = std::decay_t<decltype(params)>;
        if constexpr (std::is_same_v<T, LightPipeParams> || std::is_same_v<T, ForcepsParams> ||
                      std::is_same_v<T, VitrectorParams> || std::is_same_v<T, NeedleParams> ||
                      std::is_same_v<T, HookParams> || std::is_same_v<T, LaserProbeParams>) {
          shaft = &params.shaft;
        }
        if constexpr (std::is_same_v<T, ForcepsParams>) {
          shape.jaw_length = params.jaw_length;
          shape.jaws = true;
          shape.jaw_radius = 0.5 * std::max(params.jaw_thickness, params.jaw_tip_width);
        }
        // The vitrector removes what its port aspirates: a capsule over the port, as wide as the shaft. Whether it
        // cuts is the driver's input (suction and cut rate), `cuts` stays false here.
        if constexpr (std::is_same_v<T, VitrectorParams>) {
          shape.cut_radius = 0.5 * params.shaft.diameter;
          shape.cut_offset = params.port_distance_from_tip;
          shape.cut_length = params.port_length;
        }
      },
      instrument.params);
  shape.radius = shaft ? 0.5 * shaft->diameter : 3e-4;
  shape.length = shaft ? shaft->length : 0.0;
  shape.can_grasp = instrument.type == InstrumentType::kForceps;
  // Every instrument pushes tissue; the forceps with their jaw blades and shaft (not while they hold a grasp).
  shape.collides = true;
  return shape;
}

collision::InstrumentModel collisionModel(const InstrumentDescription& instrument, int jaw_deg) {
  collision::InstrumentModel model;
  model.mesh = instrumentMesh(instrument, jaw_deg);
  // The geometric detector's exact shape: the simulator's capsules at the same jaw opening.
  tissue::InstrumentInput at_origin = tissueShape(instrument);
  at_origin.pose = Eigen::Isometry3d::Identity();
  at_origin.jaw_angle = jaw_deg / kRadToDeg;
  for (const tissue::Capsule& capsule : tissue::instrumentCapsules(at_origin)) {
    model.primitives.push_back(collision::Primitive::capsule(capsule.a, capsule.b, capsule.radius));
  }
  return model;
}

tissue::InstrumentInput scriptedInstrument(const SceneDescription& scene, const InstrumentDescription& instrument,
                                           double t) {
  const ScriptedPose scripted = scriptedPose(scene, instrument, t);
  tissue::InstrumentInput input = tissueShape(instrument);
  input.pose = scripted.pose;
  input.jaw_angle = scripted.jaw_angle;
  return input;
}

}  // namespace world
}  // namespace vrm_sim
