#pragma once
// The procedural generators by name, as a scene file selects them (`mesh: {generator: <name>, params: {...}}`).
// Each generator has its own typed parameter struct; GeneratorParams holds exactly one of them, so a scene
// description cannot carry parameters that belong to another generator.

#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "vrm_scene/meshes/eye_meshes.h"
#include "vrm_scene/meshes/instrument_meshes.h"
#include "vrm_scene/meshes/primitive_meshes.h"

namespace vrm_sim {
namespace scene {

using GeneratorParams = std::variant<RetinaParams, MembraneParams, SphereParams, BoxParams, CylinderParams,
                                     CapsuleParams, ConeParams, TorusParams, DiscParams, PlaneParams, LightPipeParams,
                                     ForcepsParams, VitrectorParams, NeedleParams, HookParams, LaserProbeParams>;

// "retina", "membrane", "sphere", "box", "cylinder", "capsule", "cone", "torus", "disc", "plane", "light_pipe",
// "forceps", "vitrector", "needle", "hook", "laser_probe".
const std::vector<std::string>& generatorNames();
std::string generatorName(const GeneratorParams& params);
// Default parameters of the named generator, or nullopt for an unknown name.
std::optional<GeneratorParams> defaultGeneratorParams(const std::string& name);
// Runs the generator; the mesh is named after the generator. Throws std::invalid_argument for parameters outside
// the generator's domain (the scene loader rejects those earlier with the file position).
TriangleMesh generateMesh(const GeneratorParams& params);

}  // namespace scene
}  // namespace vrm_sim
