#include "vrm_scene/meshes/mesh_generators.h"

#include <type_traits>

namespace vrm_sim {
namespace scene {
namespace {

template <typename Params>
struct Generator;

#define VRM_SCENE_GENERATOR(ParamsType, generator_name, make_function)                   \
  template <>                                                                            \
  struct Generator<ParamsType> {                                                         \
    static constexpr const char* kName = generator_name;                                 \
    static TriangleMesh make(const ParamsType& params) { return make_function(params); } \
  };

VRM_SCENE_GENERATOR(RetinaParams, "retina", makeRetina)
VRM_SCENE_GENERATOR(MembraneParams, "membrane", makeMembrane)
VRM_SCENE_GENERATOR(SphereParams, "sphere", makeSphere)
VRM_SCENE_GENERATOR(BoxParams, "box", makeBox)
VRM_SCENE_GENERATOR(CylinderParams, "cylinder", makeCylinder)
VRM_SCENE_GENERATOR(CapsuleParams, "capsule", makeCapsule)
VRM_SCENE_GENERATOR(ConeParams, "cone", makeCone)
VRM_SCENE_GENERATOR(TorusParams, "torus", makeTorus)
VRM_SCENE_GENERATOR(DiscParams, "disc", makeDisc)
VRM_SCENE_GENERATOR(PlaneParams, "plane", makePlane)
VRM_SCENE_GENERATOR(LightPipeParams, "light_pipe", makeLightPipe)
VRM_SCENE_GENERATOR(ForcepsParams, "forceps", makeForceps)
VRM_SCENE_GENERATOR(VitrectorParams, "vitrector", makeVitrector)
VRM_SCENE_GENERATOR(NeedleParams, "needle", makeNeedle)
VRM_SCENE_GENERATOR(HookParams, "hook", makeHook)
VRM_SCENE_GENERATOR(LaserProbeParams, "laser_probe", makeLaserProbe)
#undef VRM_SCENE_GENERATOR

template <std::size_t... kIndices>
std::vector<std::string> namesOfAlternatives(std::index_sequence<kIndices...>) {
  return {Generator<std::variant_alternative_t<kIndices, GeneratorParams>>::kName...};
}

template <std::size_t kIndex = 0>
std::optional<GeneratorParams> defaultsByName(const std::string& name) {
  if constexpr (kIndex == std::variant_size_v<GeneratorParams>) {
    return std::nullopt;
  } else {
    using Params = std::variant_alternative_t<kIndex, GeneratorParams>;
    if (name == Generator<Params>::kName) return GeneratorParams(Params{});
    return defaultsByName<kIndex + 1>(name);
  }
}

}  // namespace

const std::vector<std::string>& generatorNames() {
  static const std::vector<std::string> names =
      namesOfAlternatives(std::make_index_sequence<std::variant_size_v<GeneratorParams>>());
  return names;
}

std::string generatorName(const GeneratorParams& params) {
  return std::visit([](const auto& typed) { return std::string(Generator<std::decay_t<decltype(typed)>>::kName); },
                    params);
}

std::optional<GeneratorParams> defaultGeneratorParams(const std::string& name) { return defaultsByName(name); }

TriangleMesh generateMesh(const GeneratorParams& params) {
  return std::visit([](const auto& typed) { return Generator<std::decay_t<decltype(typed)>>::make(typed); }, params);
}

}  // namespace scene
}  // namespace vrm_sim
