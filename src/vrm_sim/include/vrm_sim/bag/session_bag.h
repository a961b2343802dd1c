#pragma once
// Session bags as a user hands them over (thesis §2.4.2: a session is its recorded inputs): checked before a replay
// starts, recovered when the recorder was killed or the file was cut off, refused with a reason when they cannot
// drive the simulator. Shared by the offline replayer (rosrun vrm_sim session_replay) and replay.launch (which runs
// `session_replay --prepare` before it starts anything, then plays the bag it names with session_player).
//
// Recovery reads the rosbag 2.0 records directly (the index of an unfinished or truncated bag is missing or points
// past the end): every complete message record of every uncompressed chunk, the open last chunk included, goes into
// a new, indexed copy; the original is never modified. Compressed chunks without their index cannot be recovered
// and are reported.

#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "vrm_msgs/SessionInfo.h"

namespace vrm_sim {
namespace bag {

// A bag that cannot drive a replay; what() names the bag and why (and where, for a corrupt one).
class BagError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The topics the VR part consumes: the input frames its mediator closed (issue 31) and the raw device topics (frame
// sources and state inputs; the only input of a bag recorded before input frames), and the rest of a session's
// record.
inline const std::string& inputFrameTopic() {
  static const std::string topic = "/input_frame";
  return topic;
}
// Frames a simulation node resent after resuming a session (vrm_msgs/InputFrames, issue 39).
inline const std::string& resentFramesTopic() {
  static const std::string topic = "/input_frame_resent";
  return topic;
}
const std::vector<std::string>& inputTopics();   // inputFrameTopic() + deviceTopics()
const std::vector<std::string>& deviceTopics();  // /eye_state /instrument_state /pedals /scenario_command
const std::vector<std::string>& sessionTopics();  // inputTopics() + /microscope + /session_info

struct RecoveryReport {
  std::uint64_t messages = 0;    // complete message records copied
  double seconds = 0.0;          // from the first to the last recovered message (bag time)
  std::uint64_t end_offset = 0;  // where the intact records end (byte offset in the original)
  std::uint64_t file_size = 0;
  // Compressed (bz2, lz4) chunks whose messages are lost: the open one a killed recorder leaves (its compressed stream
  // has no end), or one that does not decompress to its size. Closed ones are read whole.
  std::uint64_t lost_compressed_chunks = 0;
  std::uint64_t empty_records = 0;  // message records of zero bytes, not copied
  std::string stop_reason;  // why the scan stopped before the end of the file ("" = it reached the end)
};

struct PreparedBag {
  std::string original;  // the path the user gave
  std::string usable;    // the original, or the recovered copy
  std::optional<RecoveryReport> recovery;
  std::map<std::string, std::uint64_t> topics;  // message count per topic
  std::uint64_t messages = 0;
  double seconds = 0.0;  // bag time from the first to the last message
  std::optional<vrm_msgs::SessionInfo> session_info;
};

struct PrepareOptions {
  // Where a recovered copy goes: "" = next to the original (<name>.recovered.bag), or the temp folder when that is
  // not writable.
  std::string recovery_dir;
  // Read and deserialize every input message once (a corrupt record fails here, with its position, instead of in
  // the middle of a replay).
  bool verify_messages = true;
};

// Checks `path` and returns what a replay needs. Throws BagError when the file is missing, is not a bag, is corrupt
// (with the byte offset where its records break), or holds none of inputTopics() (listing the topics it has).
PreparedBag prepareSessionBag(const std::string& path, const PrepareOptions& options = {});

// Copies every complete message of `broken` (an unindexed, truncated or unfinished bag) into a new bag at `copy`.
// Throws BagError when `broken` is not a rosbag 2.0 file or nothing can be recovered.
RecoveryReport recoverBag(const std::string& broken, const std::string& copy);

// Scans the record structure of a bag file: the offset of the first record that is not well-formed, or nullopt when
// every record up to the end of the file is.
std::optional<std::uint64_t> firstBrokenRecord(const std::string& path);

// Whether the bag holds the session's input frames (else it predates them and replays from the device topics).
bool recordsInputFrames(const PreparedBag& bag);

// The software version a session records in session_info and a replay compares against.
std::string softwareVersion();

}  // namespace bag
}  // namespace vrm_sim
