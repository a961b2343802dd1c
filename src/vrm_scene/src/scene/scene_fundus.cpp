#include "vrm_scene/scene_fundus.h"

#include <cmath>
#include <string>
#include <variant>

#include "vrm_scene/scene_loader.h"

namespace vrm_sim {
namespace scene {

anatomy::FundusParams fundusParams(const SceneDescription& scene, long long seed) {
  anatomy::FundusParams params;
  params.eye_radius = static_cast<float>(scene.eye.radius);
  if (seed >= 0) {
    params.seed = static_cast<std::uint32_t>(seed);
  } else {
    std::uint32_t hash = 2166136261u;  // FNV-1a: stable across runs and platforms (std::hash is not)
    for (const char c : scene.name) hash = (hash ^ static_cast<unsigned char>(c)) * 16777619u;
    params.seed = hash;
  }
  // Issue 33: one optic disc. The scene's disc (the object named kOpticDiscName) places the fundus's disc, so that the
  // disc the scene describes (and the simulation and scoring know) is the one the fundus draws, with its cup and its
  // vessels; without one the anatomical default stays.
  if (const ObjectDescription* disc = opticDisc(scene)) {
    const Eigen::Vector3f centre = disc->pose.xyz.cast<float>();
    const Eigen::Vector2f f = anatomy::fundusCoordinates(centre, params.eye_radius);
    params.nasal_sign = f.x() < 0.0f ? -1.0f : 1.0f;
    params.disc_fovea_distance = std::abs(f.x());
    params.disc_above_fovea = f.y();
    params.disc_diameter = static_cast<float>(2.0 * std::get<DiscParams>(*disc->mesh.generator).radius);
  }
  return params;
}

const ObjectDescription* opticDisc(const SceneDescription& scene) {
  for (const ObjectDescription& object : scene.objects) {
    if (object.name != kOpticDiscName) continue;
    // Bad input gets a clear error: the fundus can only take a disc's centre and radius from a disc on the retina.
    if (object.frame != ObjectFrame::kEye || !object.mesh.generator ||
        !std::holds_alternative<DiscParams>(*object.mesh.generator)) {
      throw SceneError(object.location, std::string("object '") + kOpticDiscName +
                                            "' must be a `disc` generator in the eye frame: the fundus draws "
                                            "its optic disc there, with the disc's radius");
    }
    const double radius = std::get<DiscParams>(*object.mesh.generator).radius;
    const double from_centre = object.pose.xyz.norm();
    if (!(radius > 0.0) || std::abs(from_centre - scene.eye.radius) > 0.1 * scene.eye.radius) {
      throw SceneError(object.location, std::string("object '") + kOpticDiscName +
                                            "' must lie on the retina (its centre within 10 % of the eye "
                                            "radius from the eye centre) with a positive radius");
    }
    return &object;
  }
  return nullptr;
}

}  // namespace scene
}  // namespace vrm_sim
