// scenario_offline: plays a training scenario headless, without a ROS master, through the simulation core the
// scenario_manager nodelet wraps (vrm_sim::world::World with its scenario): the instruments follow one of the
// scene's scripted sessions (scenario.scripts: expert, novice, ...) or a script file, sampled into instrument states
// at --rate Hz, from START until the scenario finishes or fails, or --grace s after the script's last waypoint.
// Prints one JSON object:
//   {"scenario", "type", "difficulty", "script", "seed", "state" (finished | failed | timeout), "message", "total"
//    (0..100), "items" {name: value}, "points" {scored name: 0..100}, "final_state_hash", "frames", "sim_seconds",
//    "wall_seconds", "ms_per_frame", "ms_scenario", "ms_tissue", "ms_collision", "ms_bleeding", "simulations"}
//
// Usage: rosrun vrm_sim scenario_offline --scene NAME_OR_PATH [--difficulty LEVEL] [--script expert|novice|FILE]
//        [--seed N] [--rate HZ] [--grace S] [--detector NAME]
//        rosrun vrm_sim scenario_offline --list
// Exit status: 0 the run completed (whatever the score), 1 bad input (file:line:col: field: reason on stderr),
// 2 usage.
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include "vrm_scene/cli/cli.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/world/offline.h"

namespace {

int list() {
  for (const std::string& name : vrm_sim::scene::shippedScenes()) {
    try {
      const auto scene = vrm_sim::scene::loadScene(vrm_sim::scene::shippedScenePath(name));
      if (scene.scenario) std::printf("%s\n", name.c_str());
    } catch (const std::exception& error) {
      std::fprintf(stderr, "scenario_offline: %s\n", error.what());
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  vrm_sim::usePackageData();  // --scene NAME and --list: the shipped scenes, found through ROS_PACKAGE_PATH
  namespace po = vrm_sim::cli::po;
  std::string scene_argument, difficulty, script = "expert";
  vrm_sim::world::ScenarioRunOptions options;
  bool list_scenarios = false;
  vrm_sim::cli::CommandLine cli(
      "scenario_offline",
      "--scene NAME_OR_PATH [--difficulty LEVEL] [--script expert|novice|FILE] [--seed N] [--rate HZ] [--grace S] "
      "[--detector NAME]\n--list",
      "Plays a training scenario headless through the simulation core and prints one JSON object (--list: the "
      "shipped scenes with a scenario).",
      "Exit status: 0 the run completed (whatever the score), 1 bad input, 2 usage.");
  cli.add()("scene", po::value(&scene_argument)->value_name("NAME_OR_PATH"), "the scene: a shipped name or a file")(
      "difficulty", po::value(&difficulty)->value_name("LEVEL"), "the scenario's difficulty level")(
      "script", po::value(&script)->value_name("expert|novice|FILE"),
      "one of the scene's scripted sessions, a script file or a shipped script (config/scripts; default expert)")(
      "seed", vrm_sim::cli::uint32(&options.seed)->value_name("N"), "recorded with the result (default 0)")(
      "rate", vrm_sim::cli::real(&options.rate)->value_name("HZ"), "input ticks (Hz, default 50)")(
      "grace", vrm_sim::cli::real(&options.grace)->value_name("S"),
      "simulated seconds after the script's last waypoint before a timeout (default 5)")(
      "detector", po::value(&options.detector)->value_name("NAME"), "collision detector (default: the scene's)")(
      "list", po::bool_switch(&list_scenarios), "print the shipped scenes that have a scenario");
  if (const auto status = cli.parse(argc, argv)) return *status;
  if (list_scenarios) {
    if (argc != 2) return cli.fail("--list takes no other arguments");
    return list();
  }
  if (!(options.rate > 0.0)) return cli.fail("--rate expects a positive number");
  if (!(options.grace >= 0.0)) return cli.fail("--grace expects a non-negative number");
  if (scene_argument.empty()) return cli.fail("--scene is required");
  try {
    const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(scene_argument, difficulty);
    if (!scene.scenario) {
      std::fprintf(stderr, "scenario_offline: %s: scene '%s' has no scenario section (scenario_offline --list)\n",
                   scene.source_file.c_str(), scene.name.c_str());
      return 1;
    }
    std::error_code error;
    if (scene.scenario->scripts.count(script) == 0 &&
        std::filesystem::is_regular_file(vrm_sim::scene::resolveScriptPath(script), error)) {
      options.script_file = vrm_sim::scene::loadScript(script);
    } else {
      options.script = script;
    }
    const vrm_sim::world::ScenarioRunResult result = vrm_sim::world::runScenario(scene, options);
    std::printf("%s\n", result.json().c_str());
    return 0;
  } catch (const vrm_sim::scene::SceneError& error) {
    std::fprintf(stderr, "scenario_offline: %s\n", error.what());
    return 1;
  } catch (const std::invalid_argument& error) {
    std::fprintf(stderr, "scenario_offline: %s\n", error.what());
    return 1;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "scenario_offline: %s\n", error.what());
    return 1;
  }
}
