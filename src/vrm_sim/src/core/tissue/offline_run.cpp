#include "vrm_sim/tissue/offline_run.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <variant>
#include <vector>

#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/scene/scene_loader.h"

namespace vrm_sim {
namespace tissue {

namespace {

constexpr double kDegToRad = M_PI / 180.0;

std::uint64_t fnv1a(std::uint64_t hash, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) {
    hash ^= p[i];
    hash *= 1099511628211ull;
  }
  return hash;
}

}  // namespace

std::uint64_t hashBytes(std::uint64_t hash, const void* data, std::size_t bytes) { return fnv1a(hash, data, bytes); }

std::uint64_t stateHash(mge::Membrane& membrane, std::uint64_t hash) {
  const std::size_t n = membrane.nodeCount();
  hash = fnv1a(hash, membrane.positions(), n * sizeof(Eigen::Vector3d));
  return fnv1a(hash, membrane.velocities(), n * sizeof(Eigen::Vector3d));
}

TissueConfig tissueConfigFor(const scene::TissueParameters& parameters, const scene::CollisionParameters& collision) {
  TissueConfig config;
  config.model = scene::toString(parameters.model);
  config.integrator = parameters.integrator;
  config.dt = parameters.dt;
  config.time_budget_ms = parameters.time_budget_ms;
  config.forces.damping = parameters.damping;
  config.strain_limit = parameters.strain_limit;
  config.plastic = parameters.plastic;
  config.adhesion_stiffness = parameters.adhesion_stiffness;
  config.adhesion_break_force = parameters.adhesion_break_force;
  config.tear_strain = parameters.tear_strain;
  config.early_stop_force = parameters.early_stop_force;
  config.chainmail.min_stretch = parameters.chainmail.min_stretch;
  config.chainmail.max_stretch = parameters.chainmail.max_stretch;
  config.chainmail.max_shear = parameters.chainmail.max_shear;
  config.chainmail.relaxation = parameters.chainmail.relaxation;
  config.chainmail.relaxation_iterations = parameters.chainmail.relaxation_iterations;
  config.refinement.levels = parameters.refinement.levels;
  config.refinement.radius = parameters.refinement.radius;
  config.refinement.element_budget = static_cast<std::size_t>(std::max(0, parameters.refinement.element_budget));
  config.refinement.chain_stiffness_scaling = parameters.refinement.chain_stiffness_scaling;
  config.shell_scale = collision.epsilon_shell_scale;
  config.integrator_options.cg_max_iterations = 10;
  config.integrator_options.cg_tolerance = 1e-6;
  return config;
}

mge::MembraneOptions membraneOptionsFor(const scene::TissueParameters& parameters, std::size_t node_count) {
  mge::MembraneOptions options;
  options.total_mass = parameters.node_mass * static_cast<double>(node_count);
  options.stretch_stiffness = parameters.stiffness;
  options.bending_springs = parameters.bending_stiffness > 0.0;
  options.bending_stiffness = parameters.bending_stiffness;
  return options;
}

InstrumentInput instrumentInputFor(const scene::InstrumentDescription& description) {
  InstrumentInput instrument;
  const scene::ShaftParams* shaft = nullptr;
  std::visit(
      [&](const auto& params) {
        using T = std::decay_t<decltype(params)>;
        if constexpr (std::is_same_v<T, scene::LightPipeParams> || std::is_same_v<T, scene::ForcepsParams> ||
                      std::is_same_v<T, scene::VitrectorParams> || std::is_same_v<T, scene::NeedleParams> ||
                      std::is_same_v<T, scene::HookParams>) {
          shaft = &params.shaft;
        }
        if constexpr (std::is_same_v<T, scene::ForcepsParams>) {
          instrument.jaw_length = params.jaw_length;
          instrument.jaws = true;
          instrument.jaw_radius = 0.5 * std::max(params.jaw_thickness, params.jaw_tip_width);
        }
        // The vitrector removes what its port aspirates: a capsule over the port, as wide as the shaft. Whether it
        // cuts is the driver's input (suction and cut rate), `cuts` stays false here.
        if constexpr (std::is_same_v<T, scene::VitrectorParams>) {
          instrument.cut_radius = 0.5 * params.shaft.diameter;
          instrument.cut_offset = params.port_distance_from_tip;
          instrument.cut_length = params.port_length;
        }
      },
      description.params);
  instrument.radius = shaft ? 0.5 * shaft->diameter : 3e-4;
  instrument.length = shaft ? shaft->length : 0.0;
  instrument.can_grasp = description.type == scene::InstrumentType::kForceps;
  // Every instrument pushes tissue; the forceps with their jaw blades and shaft (not while they hold a grasp).
  instrument.collides = true;
  return instrument;
}

InstrumentInput scriptedInstrument(const scene::SceneDescription& scene,
                                   const scene::InstrumentDescription& description, double t) {
  const auto& path = description.path;
  if (path.empty()) throw std::invalid_argument("scriptedInstrument: instrument has no path");
  const scene::InstrumentWaypoint sample = scene::samplePath(path, t);
  const Eigen::Vector3d tip = sample.tip_in_eye + description.tremor.offset(t);
  const double jaw_deg = sample.jaw_angle_deg;
  InstrumentInput instrument = instrumentInputFor(description);
  // Instrument frame: +z from the handle to the tip, i.e. from the trocar (the pivot) to the tip.
  const scene::Trocar* trocar = scene.findTrocar(description.trocar);
  Eigen::Vector3d axis = trocar != nullptr ? Eigen::Vector3d(tip - trocar->position_in_eye) : Eigen::Vector3d(0, 0, -1);
  if (axis.norm() < 1e-9) axis = Eigen::Vector3d(0, 0, -1);
  const Eigen::Vector3d z = axis.normalized();
  const Eigen::Vector3d x = z.unitOrthogonal();
  instrument.pose = Eigen::Isometry3d::Identity();
  instrument.pose.linear().col(0) = x;
  instrument.pose.linear().col(1) = z.cross(x);
  instrument.pose.linear().col(2) = z;
  instrument.pose.translation() = tip;
  instrument.jaw_angle = jaw_deg * kDegToRad;
  return instrument;
}

}  // namespace tissue
}  // namespace vrm_sim
