// tissue_offline: runs a scene headless, without a ROS master, through the same simulation core as the
// scenario_manager nodelet (vrm_sim::world::World): the instruments follow their scripted paths from the scene file,
// sampled into instrument states at --rate Hz; prints one JSON object
//   {"stable", "frames", "steps", "ms_per_step", "ms_per_frame", "ms_per_frame_max", "max_strain",
//    "max_grasped_nodes", "energy_drift", "fallbacks", "retina_contacts", "max_injury",
//    "tissues": [{"object", "outcome", "torn_springs", "released_adhesions", "topology_version", "max_lift"}],
//    "final_state_hash"}.
// Same scene, options and seed -> the same final_state_hash, bit for bit.
//
// Usage: rosrun vrm_sim tissue_offline --scene FILE.yaml|NAME --seconds T [--rate HZ] [--integrator auto|NAME] [--dt
// DT]
//        [--detector NAME] [--seed N]
// (NAME: a shipped scene, e.g. membrane_peeling). Exit status: 0 ran (see "stable"), 1 bad scene or options,
// 2 usage.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "vrm_sim/package_data.h"
#include "vrm_sim/scene/scene_loader.h"
#include "vrm_sim/world/offline.h"

namespace {

int usage(const char* problem) {
  std::fprintf(stderr,
               "tissue_offline: %s\nusage: tissue_offline --scene FILE.yaml|NAME --seconds T [--rate HZ] "
               "[--integrator NAME] [--dt DT] [--detector NAME] [--seed N]\n",
               problem);
  return 2;
}

bool parseDouble(const char* text, double& value) {
  char* end = nullptr;
  value = std::strtod(text, &end);
  return end != text && *end == '\0';
}

}  // namespace

int main(int argc, char** argv) {
  vrm_sim::usePackageData();  // --scene NAME: the shipped scene, found through ROS_PACKAGE_PATH (no master)
  std::string scene_argument;
  bool have_seconds = false;
  vrm_sim::world::OfflineOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (i + 1 >= argc) return usage(("missing value after " + flag).c_str());
    const char* value = argv[++i];
    if (flag == "--scene") {
      scene_argument = value;
    } else if (flag == "--seconds") {
      if (!parseDouble(value, options.seconds)) return usage("--seconds expects a number");
      have_seconds = true;
    } else if (flag == "--rate") {
      if (!parseDouble(value, options.rate) || !(options.rate > 0.0)) return usage("--rate expects a positive number");
    } else if (flag == "--detector") {
      options.detector = value;
    } else if (flag == "--integrator") {
      options.integrator = value;
    } else if (flag == "--dt") {
      if (!parseDouble(value, options.dt) || !(options.dt > 0.0)) return usage("--dt expects a positive number");
    } else if (flag == "--seed") {
      char* end = nullptr;
      options.seed = std::strtoull(value, &end, 10);
      if (end == value || *end != '\0') return usage("--seed expects a non-negative integer");
    } else {
      return usage(("unknown option " + flag).c_str());
    }
  }
  if (scene_argument.empty() || !have_seconds) return usage("--scene and --seconds are required");
  try {
    const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(scene_argument);
    const vrm_sim::world::OfflineResult result = vrm_sim::world::runOffline(scene, options);
    std::printf("%s\n", result.json().c_str());
  } catch (const std::exception& error) {
    std::fprintf(stderr, "tissue_offline: %s\n", error.what());
    return 1;
  }
  return 0;
}
