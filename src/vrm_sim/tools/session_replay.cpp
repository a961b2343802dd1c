// session_replay: replays a recorded session headless, without a ROS master (thesis §2.4.2: a session is its
// recorded inputs), through the simulation core the scenario_manager nodelet wraps, as fast as the CPU allows, and
// prints one JSON line (session_replay.h: frames, final_state_hash, score_total, wall_seconds, speedup,
// recovered_messages, recovered_seconds, ...). The scene, difficulty, collision detector and start mode come from
// the bag's session_info unless --scene overrides the scene. Unfinished (.active) or cut-off bags are recovered into
// a copy first; the original is never modified.
//
// Usage: rosrun vrm_sim session_replay --bag FILE [--scene NAME_OR_PATH] [--input devices]
//            --input devices: the bag's device topics through the mediator even when it recorded input frames (how
//            a bag replayed before input frames existed: the "before" of live = replay under load, issue 31)
//        rosrun vrm_sim session_replay --bag FILE [--scene NAME_OR_PATH] --prepare
//            checks (and if needed recovers) the bag and prints the path to play (replay.launch runs this before it
//            starts anything, so a bag it cannot use stops the launch with the reason)
//        rosrun vrm_sim session_replay --bag FILE [--scene NAME_OR_PATH] --print scene|difficulty|collision_detector|
//            auto_start|seed      one value of the session's set-up (replay.launch's node parameters)
// Exit status: 0 success (also after a recovery), 1 a bag or scene it cannot use (reason on stderr), 2 usage.
#include "vrm_sim/bag/session_replay.h"

#include <cstdio>
#include <exception>
#include <string>

#include "vrm_scene/cli/cli.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/bag/session_bag.h"

namespace {

void reportRecovery(const vrm_sim::bag::PreparedBag& bag) {
  if (!bag.recovery) return;
  const vrm_sim::bag::RecoveryReport& recovery = *bag.recovery;
  std::fprintf(stderr,
               "session_replay: %s was not closed properly (no index); recovered %llu messages, %.2f s, into %s "
               "(intact up to byte %llu of %llu%s%s)\n",
               bag.original.c_str(), static_cast<unsigned long long>(recovery.messages), recovery.seconds,
               bag.usable.c_str(), static_cast<unsigned long long>(recovery.end_offset),
               static_cast<unsigned long long>(recovery.file_size), recovery.stop_reason.empty() ? "" : "; ",
               recovery.stop_reason.c_str());
  if (recovery.lost_compressed_chunks > 0) {
    std::fprintf(stderr, "session_replay: %llu compressed chunks could not be recovered\n",
                 static_cast<unsigned long long>(recovery.lost_compressed_chunks));
  }
  if (recovery.empty_records > 0) {
    std::fprintf(stderr, "session_replay: %llu empty message records were left out\n",
                 static_cast<unsigned long long>(recovery.empty_records));
  }
}

}  // namespace

int main(int argc, char** argv) {
  vrm_sim::usePackageData();  // the recorded scene by name when its file is not on this machine
  namespace po = vrm_sim::cli::po;
  std::string bag_path, scene, print, input_name;
  bool prepare_only = false;
  vrm_sim::cli::CommandLine cli(
      "session_replay",
      "--bag FILE [--scene NAME_OR_PATH] [--input devices] [--prepare | --print "
      "scene|difficulty|collision_detector|auto_start|seed|input]",
      "Replays a recorded session headless, as fast as the CPU allows, and prints one JSON line.",
      "Exit status: 0 success (also after a recovery), 1 a bag or scene it cannot use, 2 usage.");
  cli.add()("bag", po::value(&bag_path)->required()->value_name("FILE"),
            "the session bag (recovered first if cut off)")("scene", po::value(&scene)->value_name("NAME_OR_PATH"),
                                                            "overrides the bag's scene")(
      "input", vrm_sim::cli::choice(&input_name, {"devices"})->value_name("devices"),
      "the bag's device topics through the mediator even when it recorded input frames")(
      "prepare", po::bool_switch(&prepare_only), "check (and if needed recover) the bag; print the path to play")(
      "print",
      vrm_sim::cli::choice(&print, {"scene", "difficulty", "collision_detector", "auto_start", "seed", "input"})
          ->value_name("WHAT"),
      "print one value of the session's set-up (scene, difficulty, collision_detector, auto_start, seed or input)");
  if (const auto status = cli.parse(argc, argv)) return *status;
  const vrm_sim::bag::ReplayInput input =
      input_name == "devices" ? vrm_sim::bag::ReplayInput::kDevices : vrm_sim::bag::ReplayInput::kAsRecorded;
  if (bag_path.empty()) return cli.fail("--bag is required");
  if (prepare_only && !print.empty()) return cli.fail("--prepare and --print exclude each other");
  try {
    vrm_sim::bag::PrepareOptions options;
    options.verify_messages = print.empty();  // --print follows a --prepare that verified already
    const vrm_sim::bag::PreparedBag bag = vrm_sim::bag::prepareSessionBag(bag_path, options);
    if (!print.empty()) {
      const vrm_sim::bag::SessionSetup setup = vrm_sim::bag::resolveSession(bag, scene);
      if (print == "scene") std::printf("%s", setup.scene.c_str());
      if (print == "difficulty") std::printf("%s", setup.difficulty.c_str());
      if (print == "collision_detector") std::printf("%s", setup.collision_detector.c_str());
      if (print == "auto_start") std::printf("%s", setup.auto_start ? "true" : "false");
      if (print == "seed") std::printf("%u", setup.seed);
      if (print == "input") std::printf("%s", vrm_sim::bag::recordsInputFrames(bag) ? "frames" : "devices");
      return 0;
    }
    reportRecovery(bag);
    const vrm_sim::bag::SessionSetup setup = vrm_sim::bag::resolveSession(bag, scene);
    for (const std::string& warning : setup.warnings) {
      std::fprintf(stderr, "session_replay: warning: %s: %s\n", bag_path.c_str(), warning.c_str());
    }
    if (prepare_only) {
      std::fprintf(stderr, "session_replay: %s: %llu messages, %.2f s, scene '%s'%s\n", bag_path.c_str(),
                   static_cast<unsigned long long>(bag.messages), bag.seconds, setup.scene_name.c_str(),
                   setup.difficulty.empty() ? "" : (" (" + setup.difficulty + ")").c_str());
      std::printf("%s", bag.usable.c_str());
      return 0;
    }
    const vrm_sim::bag::ReplayResult result = vrm_sim::bag::replaySession(bag, setup, input);
    std::printf("%s\n", result.json(bag).c_str());
    return 0;
  } catch (const vrm_sim::bag::BagError& error) {
    std::fprintf(stderr, "session_replay: %s\n", error.what());
    return 1;
  } catch (const vrm_sim::scene::SceneError& error) {
    std::fprintf(stderr, "session_replay: %s: %s\n", bag_path.c_str(), error.what());
    return 1;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "session_replay: %s: %s\n", bag_path.c_str(), error.what());
    return 1;
  }
}
