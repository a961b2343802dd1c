// Scene files (vrm_scene scene_loader.h): arbitrary text through the loader and the World's check of the physics names
// it read as text (world::checkSimulationNames, issue 42); a scene both accept must also build its
// meshes (object generators, imported files, instruments) and pass mesh validation, since that is what every
// consumer (scene_manager, the World, the renderer) does next. Building the meshes of a whole scene costs ~20 ms
// under ASan, so it runs for inputs whose size is a multiple of 4 (the fuzzer reaches both paths).
#include "fuzz_target.h"
#include "vrm_scene/meshes/mesh_validation.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/world/tissue_setup.h"

VRM_FUZZ_TARGET(scene_yaml) {
  using namespace vrm_sim::scene;
  const std::string text(reinterpret_cast<const char*>(data), size);
  // Relative mesh paths resolve against the shipped scenes' folder, as for a scene file next to them.
  static const std::string virtual_path = vrm_fuzz::packageDirectory("vrm_sim") + "/config/scenes/fuzzed.yaml";
  SceneDescription scene;
  try {
    scene = loadSceneFromString(text, virtual_path);
    vrm_sim::world::checkSimulationNames(scene);
  } catch (const SceneError&) {
    return 0;  // a clear rejection is the expected outcome for most inputs
  }
  if (size % 4 != 0) return 0;
  try {
    for (const vrm_sim::TriangleMesh& mesh : resolveMeshes(scene)) validateMesh(mesh);
    for (const InstrumentDescription& instrument : scene.instruments) validateMesh(buildInstrumentMesh(instrument));
  } catch (const SceneError&) {
  }
  return 0;
}
