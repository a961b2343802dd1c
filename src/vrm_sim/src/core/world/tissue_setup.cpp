#include "vrm_sim/world/tissue_setup.h"

#include <algorithm>
#include <string>
#include <vector>

#include "vrm_scene/registry.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_scene/yaml/strict_reader.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/tissue/integrator.h"
#include "vrm_sim/tissue/tissue_model.h"

namespace vrm_sim {
namespace world {
namespace {

using scene::CollisionParameters;
using scene::TissueParameters;

// The message Field::name gives for a choice the loader checks itself, so a typo reads the same at either layer.
void checkName(const std::string& name, const scene::SourceLocation& location, const std::vector<std::string>& names) {
  if (std::find(names.begin(), names.end(), name) != names.end()) return;
  throw scene::SceneError(
      location, "expected one of " + yaml::joinNames(names) + ", got '" + name + "'" + typoSuggestion(name, names));
}

}  // namespace

void checkSimulationNames(const scene::SceneDescription& scene) {
  std::vector<std::string> models = {scene::kRigidTissueModel};
  for (const std::string& name : tissue::tissueModelRegistry().names()) models.push_back(name);
  const std::vector<std::string> integrators = tissue::integratorRegistry().names();
  const std::vector<std::string> detectors = collision::detectorRegistry().names();
  for (const scene::ObjectDescription& object : scene.objects) {
    checkName(object.tissue.model, object.tissue.model_location, models);
    checkName(object.tissue.integrator, object.tissue.integrator_location, integrators);
    checkName(object.collision.detector, object.collision.detector_location, detectors);
  }
}

tissue::TissueConfig tissueConfigFor(const TissueParameters& parameters, const CollisionParameters& collision) {
  tissue::TissueConfig config;
  config.model = parameters.model;
  config.integrator = parameters.integrator;
  config.dt = parameters.dt;
  config.time_budget_ms = parameters.time_budget_ms;
  config.forces.damping = parameters.damping;
  config.strain_limit = parameters.strain_limit;
  config.plastic = parameters.plastic;
  config.adhesion_stiffness = parameters.adhesion_stiffness;
  config.adhesion_break_force = parameters.adhesion_break_force;
  config.tear_strain = parameters.tear_strain;
  config.adhesion_release_time = parameters.adhesion_release_time;
  config.adhesion_tear_force = parameters.adhesion_tear_force;
  config.fluid_modulus = parameters.fluid_modulus;  // fluid_wall_radius: the World's, from the rest mesh
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

mge::MembraneOptions membraneOptionsFor(const TissueParameters& parameters, std::size_t node_count) {
  mge::MembraneOptions options;
  options.total_mass = parameters.node_mass * static_cast<double>(node_count);
  options.stretch_stiffness = parameters.stiffness;
  options.bending_springs = parameters.bending_stiffness > 0.0;
  options.bending_stiffness = parameters.bending_stiffness;
  return options;
}

}  // namespace world
}  // namespace vrm_sim
