#pragma once
// Shared by the rigid object scenarios (object_manipulation.cpp, bimanual.cpp; not installed): the scene objects they
// move, checked against their generator, and the rigid body options their parameters set.
#include <string>
#include <variant>

#include "common.h"
#include "vrm_sim/scenario/rigid_body.h"

namespace vrm_sim {
namespace scenario {

constexpr double kDegree = kPi / 180.0;

template <typename T>
const T& generatorOf(const scene::ObjectDescription& object, Params& params, const std::string& parameter,
                     const char* generator) {
  const auto* found = object.mesh.generator ? std::get_if<T>(&*object.mesh.generator) : nullptr;
  if (found == nullptr) {
    params.fail(parameter, "object '" + object.name + "' must be a " + generator + " (generator " + generator + ")");
  }
  if (object.frame != scene::ObjectFrame::kEye) {
    params.fail(parameter, "object '" + object.name + "' must be in the eye frame");
  }
  return *found;
}

RigidBodyOptions bodyOptions(const scene::SceneDescription& scene, Params& params);

}  // namespace scenario
}  // namespace vrm_sim
