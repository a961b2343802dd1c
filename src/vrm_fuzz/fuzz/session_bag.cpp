// The bag-reading path of the offline tools (vrm_sim bag/session_bag.h, session_replay.h) as session_replay and
// replay.launch's `session_replay --prepare` run it: the fuzz bytes are written to a file and opened as a session
// bag: the record scan, the recovery of an unindexed or cut-off bag, message verification, session_info, and for a
// bag that prepares, the replay of its inputs through the simulation core. The replay builds a World (about a
// second under ASan), so it runs only for inputs whose size is a multiple of 32 and with at most 48 inputs: the
// fuzzer still reaches it, and the bag parsing, the part this target is for, runs at a useful rate. The same
// handlers are fuzzed message by message in sim_messages.
#include "vrm_sim/bag/session_bag.h"

#include <rosbag/bag.h>

#include <filesystem>

#include "fuzz_target.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/bag/session_replay.h"

VRM_FUZZ_TARGET(session_bag) {
  using namespace vrm_sim::bag;
  // Every rosbag::Bag loads rosbag's encryptor plugin library through pluginlib, and the last one destroyed unloads
  // it: a dlopen per input, whose atexit registrations outlive the input, so libFuzzer took every input for a possible
  // leak and ran LeakSanitizer's whole-heap scan after it (15 exec/s; 70 % of the time in LSan and the dynamic
  // linker). One Bag kept for the process holds the library as a running session_replay does.
  static const rosbag::Bag keeps_encryptor_plugin_loaded;
  (void)keeps_encryptor_plugin_loaded;
  const std::string path = vrm_fuzz::writeScratchFile("session.bag", data, size);
  const std::string recovery_dir = vrm_fuzz::scratchDirectory() + "/recovered";
  std::filesystem::create_directories(recovery_dir);
  firstBrokenRecord(path);
  try {
    recoverBag(path, vrm_fuzz::scratchDirectory() + "/copy.bag");
  } catch (const BagError&) {
  }
  PrepareOptions options;
  options.recovery_dir = recovery_dir;
  PreparedBag bag;
  try {
    bag = prepareSessionBag(path, options);
  } catch (const BagError&) {
    return 0;
  }
  std::uint64_t inputs = 0;
  for (const std::string& topic : inputTopics()) {
    auto found = bag.topics.find(topic);
    if (found != bag.topics.end()) inputs += found->second;
  }
  if (inputs > 48 || size % 32 != 0) return 0;
  try {
    const SessionSetup setup = resolveSession(bag, bag.session_info ? "" : "navigation");
    const ReplayResult result = replaySession(bag, setup);
    (void)result.json(bag);
  } catch (const BagError&) {
  } catch (const vrm_sim::scene::SceneError&) {
  }
  return 0;
}
