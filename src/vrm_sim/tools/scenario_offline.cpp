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
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>

#include "vrm_sim/package_data.h"
#include "vrm_sim/scene/scene_loader.h"
#include "vrm_sim/world/offline.h"

namespace {

int usage(const std::string& problem) {
  std::fprintf(stderr,
               "scenario_offline: %s\nusage: scenario_offline --scene NAME_OR_PATH [--difficulty LEVEL] "
               "[--script expert|novice|FILE] [--seed N] [--rate HZ] [--grace S] [--detector NAME]\n"
               "       scenario_offline --list\n",
               problem.c_str());
  return 2;
}

bool parseDouble(const char* text, double& value) {
  char* end = nullptr;
  value = std::strtod(text, &end);
  return end != text && *end == '\0';
}

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
  std::string scene_argument, difficulty, script = "expert";
  vrm_sim::world::ScenarioRunOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--list") {
      if (argc != 2) return usage("--list takes no other arguments");
      return list();
    }
    if (flag == "-h" || flag == "--help") return usage("help");
    if (i + 1 >= argc) return usage("missing value after " + flag);
    const char* value = argv[++i];
    if (flag == "--scene") {
      scene_argument = value;
    } else if (flag == "--difficulty") {
      difficulty = value;
    } else if (flag == "--script") {
      script = value;
    } else if (flag == "--seed") {
      char* end = nullptr;
      const unsigned long seed = std::strtoul(value, &end, 10);
      if (end == value || *end != '\0' || seed > 0xffffffffUL) return usage("--seed expects an integer in [0, 2^32)");
      options.seed = static_cast<std::uint32_t>(seed);
    } else if (flag == "--rate") {
      if (!parseDouble(value, options.rate) || !(options.rate > 0.0)) return usage("--rate expects a positive number");
    } else if (flag == "--grace") {
      if (!parseDouble(value, options.grace) || !(options.grace >= 0.0)) {
        return usage("--grace expects a non-negative number");
      }
    } else if (flag == "--detector") {
      options.detector = value;
    } else {
      return usage("unknown option " + flag);
    }
  }
  if (scene_argument.empty()) return usage("--scene is required");
  try {
    const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(scene_argument, difficulty);
    if (!scene.scenario) {
      std::fprintf(stderr, "scenario_offline: %s: scene '%s' has no scenario section (scenario_offline --list)\n",
                   scene.source_file.c_str(), scene.name.c_str());
      return 1;
    }
    std::error_code error;
    if (scene.scenario->scripts.count(script) == 0 && std::filesystem::is_regular_file(script, error)) {
      options.script_parts = vrm_sim::scene::loadScript(script);
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
