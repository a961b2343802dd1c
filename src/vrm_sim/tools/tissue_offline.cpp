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
#include <exception>
#include <string>

#include "vrm_scene/cli/cli.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/world/offline.h"

int main(int argc, char** argv) {
  namespace po = vrm_sim::cli::po;
  vrm_sim::usePackageData();  // --scene NAME: the shipped scene, found through ROS_PACKAGE_PATH (no master)
  std::string scene_argument;
  vrm_sim::world::OfflineOptions options;
  vrm_sim::cli::CommandLine cli("tissue_offline",
                                "--scene FILE.yaml|NAME --seconds T [--rate HZ] [--integrator NAME] [--dt DT] "
                                "[--detector NAME] [--seed N]",
                                "Runs a scene headless through the simulation core and prints one JSON object.",
                                "Exit status: 0 ran (see \"stable\"), 1 bad scene or options, 2 usage.");
  cli.add()("scene", po::value(&scene_argument)->required()->value_name("FILE.yaml|NAME"),
            "the scene: a file, or the name of a shipped scene (e.g. membrane_peeling)")(
      "seconds", vrm_sim::cli::real(&options.seconds)->required()->value_name("T"), "simulated time (s)")(
      "rate", vrm_sim::cli::real(&options.rate)->value_name("HZ"),
      "input ticks of the scripted paths (Hz, default 50)")(
      "integrator", po::value(&options.integrator)->value_name("NAME"), "auto or an integrator (default: the scene's)")(
      "dt", vrm_sim::cli::real(&options.dt)->value_name("DT"), "time step (s, default: the scene's)")(
      "detector", po::value(&options.detector)->value_name("NAME"), "collision detector (default: the scene's)")(
      "seed", vrm_sim::cli::uint64(&options.seed)->value_name("N"),
      "perturbs the initial state by at most 1 um per axis (default 0: none)");
  if (const auto status = cli.parse(argc, argv)) return *status;
  if (!(options.rate > 0.0)) return cli.fail("--rate expects a positive number");
  if (cli.given("dt") && !(options.dt > 0.0)) return cli.fail("--dt expects a positive number");
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
