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

// SplitMix64 (Steele et al. 2014): a fixed, portable generator, so a seed means the same offsets everywhere.
std::uint64_t splitMix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// In [-1, 1), from the top 53 bits.
double symmetricUnit(std::uint64_t& state) {
  return static_cast<double>(splitMix64(state) >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

std::uint64_t fnv1a(std::uint64_t hash, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) {
    hash ^= p[i];
    hash *= 1099511628211ull;
  }
  return hash;
}

std::string number(double value) {
  if (!std::isfinite(value)) return "null";
  std::ostringstream out;
  out.precision(9);
  out << value;
  return out.str();
}

struct OfflineTissue {
  const scene::ObjectDescription* object = nullptr;
  std::unique_ptr<mge::Membrane> membrane;
  std::unique_ptr<TissueSimulator> simulator;
  Eigen::Isometry3d object_from_eye = Eigen::Isometry3d::Identity();
  double energy_start = 0.0;
};

}  // namespace

std::string OfflineResult::json() const {
  char hash[24];
  std::snprintf(hash, sizeof(hash), "0x%016llx", static_cast<unsigned long long>(final_state_hash));
  std::ostringstream out;
  out << "{\"stable\": " << (stable ? "true" : "false") << ", \"steps\": " << steps
      << ", \"ms_per_step\": " << number(ms_per_step) << ", \"max_strain\": " << number(max_strain)
      << ", \"energy_drift\": " << number(energy_drift) << ", \"fallbacks\": " << fallbacks
      << ", \"final_state_hash\": \"" << hash << "\"}";
  return out.str();
}

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
        if constexpr (std::is_same_v<T, scene::ForcepsParams>) instrument.jaw_length = params.jaw_length;
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
  // Forceps: the jaws grasp; the shaft stays behind them and above the tissue while grasping.
  instrument.collides = !instrument.can_grasp;
  return instrument;
}

InstrumentInput scriptedInstrument(const scene::SceneDescription& scene,
                                   const scene::InstrumentDescription& description, double t) {
  const auto& path = description.path;
  if (path.empty()) throw std::invalid_argument("scriptedInstrument: instrument has no path");
  Eigen::Vector3d tip = path.front().tip_in_eye;
  double jaw_deg = path.front().jaw_angle_deg;
  if (t >= path.back().t) {
    tip = path.back().tip_in_eye;
    jaw_deg = path.back().jaw_angle_deg;
  } else if (t > path.front().t) {
    const auto next = std::upper_bound(path.begin(), path.end(), t,
                                       [](double time, const scene::InstrumentWaypoint& w) { return time < w.t; });
    const auto& b = *next;
    const auto& a = *(next - 1);
    const double alpha = (t - a.t) / (b.t - a.t);
    tip = (1.0 - alpha) * a.tip_in_eye + alpha * b.tip_in_eye;
    jaw_deg = (1.0 - alpha) * a.jaw_angle_deg + alpha * b.jaw_angle_deg;
  }
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

OfflineResult runOffline(const scene::SceneDescription& scene, const OfflineOptions& options) {
  if (!(options.seconds >= 0.0) || !std::isfinite(options.seconds)) {
    throw std::invalid_argument("tissue_offline: --seconds must be a non-negative number");
  }
  if (!(options.dt >= 0.0) || !std::isfinite(options.dt)) {
    throw std::invalid_argument("tissue_offline: --dt must be positive (or 0 for the scene's)");
  }
  if (!(options.frame > 0.0)) throw std::invalid_argument("tissue_offline: the frame time must be positive");
  scene::SourceLocation where;
  where.file = scene.source_file;
  if (!options.integrator.empty()) {
    const auto& known = integratorNames();
    if (std::find(known.begin(), known.end(), options.integrator) == known.end()) {
      std::string names;
      for (const auto& name : known) names += (names.empty() ? "" : ", ") + name;
      throw std::invalid_argument("tissue_offline: unknown integrator '" + options.integrator + "' (known: " + names +
                                  ")");
    }
  }

  const Eigen::Isometry3d world_from_eye = scene::Pose{scene.eye.centre_in_world, scene.eye.rest_rpy_deg}.toIsometry();
  std::vector<OfflineTissue> tissues;
  std::uint64_t seed_state = options.seed;
  for (const auto& object : scene.objects) {
    if (!object.isDeformable()) continue;
    const TriangleMesh mesh = scene::buildMesh(object, scene::MeshFrame::kParent);
    OfflineTissue tissue;
    tissue.object = &object;
    tissue.membrane = mge::buildMembrane(mesh, membraneOptionsFor(object.tissue, mesh.vertexCount()));
    TissueConfig config = tissueConfigFor(object.tissue, object.collision);
    if (!options.integrator.empty()) config.integrator = options.integrator;
    if (options.dt > 0.0) config.dt = options.dt;
    config.max_steps_per_frame =
        std::max(config.max_steps_per_frame, static_cast<int>(std::ceil(options.frame / config.dt)) + 1);
    if (options.seed != 0) {
      Eigen::Vector3d* x = tissue.membrane->positions();
      const std::uint8_t* fixed = tissue.membrane->fixedFlags();
      for (std::size_t i = 0; i < tissue.membrane->nodeCount(); ++i) {
        const Eigen::Vector3d offset(symmetricUnit(seed_state), symmetricUnit(seed_state), symmetricUnit(seed_state));
        if (!fixed[i]) x[i] += 1e-6 * offset;
      }
    }
    try {
      tissue.simulator = std::make_unique<TissueSimulator>(*tissue.membrane, config);
    } catch (const std::invalid_argument& error) {
      throw scene::SceneError(object.location, error.what());
    }
    if (object.frame == scene::ObjectFrame::kWorld) tissue.object_from_eye = world_from_eye;
    tissue.energy_start = tissue.simulator->totalEnergy();
    tissues.push_back(std::move(tissue));
  }
  if (tissues.empty()) throw scene::SceneError(where, "the scene has no deformable object to simulate");

  std::vector<const scene::InstrumentDescription*> scripted;
  for (const auto& instrument : scene.instruments) {
    if (!instrument.path.empty()) scripted.push_back(&instrument);
  }

  OfflineResult result;
  const auto no_clock = [] { return 0.0; };  // no budget: every frame runs all its steps (deterministic)
  double wall = 0.0;
  const int frames = static_cast<int>(std::llround(options.seconds / options.frame));
  std::vector<InstrumentInput> inputs(scripted.size());
  for (int f = 0; f <= frames; ++f) {
    const double t = f * options.frame;
    for (OfflineTissue& tissue : tissues) {
      for (std::size_t k = 0; k < scripted.size(); ++k) {
        inputs[k] = scriptedInstrument(scene, *scripted[k], t);
        inputs[k].pose = tissue.object_from_eye * inputs[k].pose;
      }
      tissue.simulator->setInstruments(inputs);
      if (f == 0) continue;  // the first poses only set where the motion starts
      const auto start = std::chrono::steady_clock::now();
      const FrameReport report = tissue.simulator->advance(options.frame, no_clock);
      wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      result.max_strain = std::max(result.max_strain, report.max_strain);
    }
  }
  std::uint64_t hash = 14695981039346656037ull;
  for (OfflineTissue& tissue : tissues) {
    const SimulatorStatistics& statistics = tissue.simulator->statistics();
    result.steps += statistics.steps;
    result.fallbacks += statistics.fallbacks;
    bool finite = true;
    for (std::size_t i = 0; i < tissue.membrane->nodeCount(); ++i) {
      finite = finite && tissue.membrane->positions()[i].allFinite() && tissue.membrane->velocities()[i].allFinite();
    }
    result.stable = result.stable && finite && statistics.unrecovered == 0;
    result.energy_drift += tissue.simulator->totalEnergy() - tissue.energy_start;
    hash = stateHash(*tissue.membrane, hash);
  }
  result.final_state_hash = hash;
  result.ms_per_step = result.steps > 0 ? 1e3 * wall / static_cast<double>(result.steps) : 0.0;
  return result;
}

}  // namespace tissue
}  // namespace vrm_sim
