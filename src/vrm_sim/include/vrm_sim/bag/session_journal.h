#pragma once
// A session's journal (issue 39: crash = pause): every input frame the simulation node applied, appended before the
// frame is published, so a node that dies (kill -9 of its manager) leaves on disk every frame the recorder could have
// seen. A node restarted into the same session reads it back and hands the frames to the Session as a replay does;
// the World is deterministic in its frames, so the restored state is the crashed one bit for bit. The journal is the
// checkpoint: no World state is serialised, so no field can be forgotten, at the cost of a restore that replays the
// session so far (bench_journal measures both).
//
// Format (little-endian): "VRMJ", u32 version (1), then length-prefixed strings scene and difficulty, u32 seed,
// u64 run; then records: u32 length + a ROS-serialised vrm_msgs/InputFrame. Each record goes to the file in one
// write(2) into the page cache (no fsync: the journal must survive the process, not the machine). A record cut off
// by the process's death is the frame that was never published, and is dropped on reading.

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "vrm_msgs/InputFrame.h"

namespace vrm_sim {
namespace bag {

class JournalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct JournalHeader {
  std::string scene;       // the simulation node's ~scene parameter
  std::string difficulty;  // its ~difficulty
  std::uint32_t seed = 0;
  std::uint64_t run = 0;  // the InputFrame run the session's frames carry
};

// <bag without .bag>.journal
std::string journalPath(const std::string& bag_path);

class JournalWriter {
 public:
  JournalWriter() = default;
  ~JournalWriter();
  JournalWriter(const JournalWriter&) = delete;
  JournalWriter& operator=(const JournalWriter&) = delete;

  // A new journal (an existing file is replaced). Throws JournalError naming the path and errno's reason.
  void create(const std::string& path, const JournalHeader& header);
  // Appends to a journal read back by readJournal (its torn tail, if any, cut off first at `valid_bytes`).
  void reopen(const std::string& path, std::uint64_t valid_bytes);
  // One frame, one write(2). Throws JournalError (disk full, I/O error); the file then ends at the last whole record.
  void append(const vrm_msgs::InputFrame& frame);
  void close();
  bool isOpen() const { return fd_ >= 0; }
  std::uint64_t bytes() const { return bytes_; }
  std::uint64_t records() const { return records_; }
  const std::string& path() const { return path_; }

 private:
  void writeAll(const std::uint8_t* data, std::size_t size);
  int fd_ = -1;
  std::string path_;
  std::uint64_t bytes_ = 0, records_ = 0;
  std::vector<std::uint8_t> buffer_;
};

struct JournalContents {
  JournalHeader header;
  std::vector<vrm_msgs::InputFrame::Ptr> frames;
  std::uint64_t valid_bytes = 0;  // where the last whole record ends
  std::uint64_t torn_bytes = 0;   // bytes of a record cut off by the writer's death (dropped)
};

// Throws JournalError for a file that is not a journal or whose records are corrupt (a length past any frame's size,
// a record that does not deserialise); a torn last record is not an error.
JournalContents readJournal(const std::string& path);

// A checkpoint beside the journal (issue 39 §1): the Session's state (world::Session::checkpoint) after the frame
// `sequence`, so a restore replays only the journal's frames after it. Written whole to a temporary file and renamed
// over the last one, so a crash while writing leaves the previous checkpoint; fsync'd like nothing else here (a
// checkpoint that names a frame the journal lost in a machine crash is refused by the restore, which then replays the
// whole journal).
struct Checkpoint {
  JournalHeader header;        // the journal's: a checkpoint of another session is not restored
  std::uint64_t sequence = 0;  // the last input frame it includes
  std::int64_t stamp = 0;      // that frame's stamp (ns): with the sequence, which frame of which journal
  // The World's state hash when it was taken: a restore checks it, so bytes of a build whose state layout differs in
  // a way the archive's section tags and lengths do not catch are refused rather than run.
  std::uint64_t state_hash = 0;
  std::string state;  // world::Session::checkpoint()
};

// <bag without .bag>.checkpoint
std::string checkpointPath(const std::string& bag_path);
// Throws JournalError naming the path and the reason (the previous checkpoint then stays).
void writeCheckpoint(const std::string& path, const Checkpoint& checkpoint);
// Throws JournalError for a file that is not a whole checkpoint.
Checkpoint readCheckpoint(const std::string& path);

}  // namespace bag
}  // namespace vrm_sim
