// Session bags as users hand them over (issue 12): every committed reference bag replays to its expected final state
// and score (scripts/update_reference_bags.sh regenerates them when a change is meant to change a session), and bags
// that are unfinished, cut off, corrupt, foreign or from another scene give a clear answer — recovered, refused with
// the reason, or warned about — without a crash or a hang, and without touching the original.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <std_msgs/Empty.h>
#include <std_msgs/String.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>

#include "../test_files.h"
#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/SessionInfo.h"
#include "vrm_sim/bag/session_bag.h"
#include "vrm_sim/bag/session_journal.h"
#include "vrm_sim/bag/session_replay.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/testing/sanitizer.h"
#include "vrm_sim/world/offline.h"
#include "vrm_sim/world/session.h"

namespace vrm_sim {
namespace bag {
namespace {

namespace fs = std::filesystem;

const fs::path kBags = fs::path(VRM_SIM_SOURCE_DIR) / "test" / "bags";

using test::jsonField;
using test::readText;

struct Process {
  int status = -1;
  std::string out, err;
};
Process run(const std::string& arguments) {
  const fs::path err_file = fs::temp_directory_path() / ("vrm_session_bags_err_" + std::to_string(getpid()));
  Process process;
  FILE* pipe =
      popen((std::string(VRM_SESSION_REPLAY_BINARY) + " " + arguments + " 2>" + err_file.string()).c_str(), "r");
  if (pipe == nullptr) return process;
  char buffer[4096];
  while (std::fgets(buffer, sizeof(buffer), pipe) != nullptr) process.out += buffer;
  const int status = pclose(pipe);
  process.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  process.err = readText(err_file);
  fs::remove(err_file);
  return process;
}

// Copies the first `limit` messages of `source` into `path` in a child process that exits without closing the bag,
// exactly as a killed rosbag record leaves <name>.bag.active (no index, the last chunk open); `after_each(out, message,
// n)` may write more records after the n-th message.
// `compression`: the chunks' (rosbag record --bz2 / --lz4), in chunks of 16 KiB then.
void writeUnfinishedBag(
    const fs::path& path, const std::string& source, std::size_t limit = std::numeric_limits<std::size_t>::max(),
    const std::function<void(rosbag::Bag&, const rosbag::MessageInstance&, std::size_t)>& after_each = {},
    rosbag::CompressionType compression = rosbag::compression::Uncompressed) {
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    rosbag::Bag in(source, rosbag::bagmode::Read);
    rosbag::Bag out(path.string(), rosbag::bagmode::Write);
    if (compression != rosbag::compression::Uncompressed) {
      out.setCompression(compression);
      out.setChunkThreshold(16 * 1024);
    }
    rosbag::View view(in);
    std::size_t n = 0;
    for (const rosbag::MessageInstance& message : view) {
      if (n == limit) break;
      out.write(message.getTopic(), message.getTime(), message);
      if (after_each) after_each(out, message, n);
      ++n;
    }
    _exit(0);  // no close
  }
  int status = 0;
  waitpid(child, &status, 0);
}

class WorkFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    work_ = fs::temp_directory_path() / ("vrm_session_bags_" + std::to_string(getpid()) + "_" +
                                         ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(work_);
    fs::create_directories(work_);
  }
  void TearDown() override { fs::remove_all(work_); }
  fs::path work_;
};

// ---- every bag a regression test ----

class ReferenceBag : public ::testing::TestWithParam<std::string> {};

TEST_P(ReferenceBag, ReplaysToTheExpectedFinalStateAndScore) {
  const fs::path bag = kBags / (GetParam() + ".bag");
  const std::string expected = readText(kBags / (GetParam() + ".expected.json"));
  ASSERT_FALSE(expected.empty()) << "no " << GetParam() << ".expected.json (scripts/update_reference_bags.sh)";
  const PreparedBag prepared = prepareSessionBag(bag.string());
  const ReplayResult result = replaySession(prepared, resolveSession(prepared));
  const std::string why = " (if the change is intended: scripts/update_reference_bags.sh)";
  EXPECT_EQ(world::hashString(result.final_state_hash), jsonField(expected, "final_state_hash")) << why;
  ASSERT_TRUE(result.score_total.has_value());
  EXPECT_NEAR(*result.score_total, std::stod(jsonField(expected, "score_total")), 1e-9) << why;
  EXPECT_EQ(result.scenario_state, jsonField(expected, "state")) << why;
  EXPECT_EQ(std::to_string(result.simulated_frames), jsonField(expected, "simulated_frames")) << why;
  EXPECT_EQ(result.late_inputs, 0u);
  // The replay's session result (issue 34) carries the same state, and reads back through the one reader.
  ASSERT_TRUE(result.session_result.has_value());
  EXPECT_EQ(result.session_result->final_state_hash, jsonField(expected, "final_state_hash"));
  EXPECT_EQ(result.session_result->state.value_or(""), jsonField(expected, "state"));
  EXPECT_EQ(result.session_result->bag, bag.string());
  const nlohmann::json line = nlohmann::json::parse(result.json(prepared));
  const result::SessionResult read = result::resultFromJson(line.at("result").dump(), "the replay line's result");
  EXPECT_EQ(result::toJson(read), result::toJson(*result.session_result));
  EXPECT_EQ(line.at("final_state_hash"), read.final_state_hash);
  // And the live session that recorded the bag ended in that state, too (its result file beside the bag).
  const std::string live = readText(kBags / (GetParam() + ".result.json"));
  if (!live.empty() && jsonField(live, "software_version") == softwareVersion()) {
    EXPECT_EQ(jsonField(live, "final_state_hash"), jsonField(expected, "final_state_hash"))
        << "the expected values no longer match the recording's live session";
  }
}

INSTANTIATE_TEST_SUITE_P(Committed, ReferenceBag,
                         ::testing::Values("navigation_expert", "membrane_peeling_novice", "vitrectomy_expert"));

TEST(SessionReplayTool, PrintsOneJsonLineWithTheFieldsOtherToolsReadAndExitsZero) {
  const Process process = run("--bag " + (kBags / "vitrectomy_expert.bag").string());
  ASSERT_EQ(process.status, 0) << process.err;
  EXPECT_EQ(std::count(process.out.begin(), process.out.end(), '\n'), 1) << process.out;
  for (const char* key : {"frames", "final_state_hash", "score_total", "wall_seconds", "speedup", "recovered_messages",
                          "recovered_seconds"}) {
    EXPECT_FALSE(jsonField(process.out, key).empty()) << key << " missing in " << process.out;
  }
  // Not under ASan (scripts/test.sh --sanitize): the instrumented World runs at 0.8x real time there (measured).
  if (!vrm_sim::testing::kUnderSanitizer) {
    EXPECT_GT(std::stod(jsonField(process.out, "speedup")), 1.0) << "offline replay runs faster than real time";
  }
  EXPECT_EQ(run("--scene vitrectomy").status, 2) << "usage: no --bag";
  EXPECT_EQ(run("--bag").status, 2);
}

// ---- robust bag handling ----

TEST_F(WorkFolder, ABagFromAnotherRobotIsRefusedNamingTheExpectedAndThePresentTopics) {
  const fs::path foreign = work_ / "turtle.bag";
  {
    rosbag::Bag bag(foreign.string(), rosbag::bagmode::Write);
    std_msgs::String message;
    message.data = "hello";
    for (int i = 0; i < 5; ++i) bag.write("/chatter", ros::Time(100 + i), message);
  }
  try {
    prepareSessionBag(foreign.string());
    FAIL() << "a bag without input topics was accepted";
  } catch (const BagError& error) {
    const std::string what = error.what();
    EXPECT_NE(what.find("/eye_state"), std::string::npos) << what;
    EXPECT_NE(what.find("/instrument_state"), std::string::npos) << what;
    EXPECT_NE(what.find("/chatter (5)"), std::string::npos) << what;
  }
  const Process process = run("--bag " + foreign.string());
  EXPECT_EQ(process.status, 1);
  EXPECT_NE(process.err.find("/chatter (5)"), std::string::npos) << process.err;
  EXPECT_EQ(run("--bag " + (work_ / "missing.bag").string()).status, 1);
}

TEST_F(WorkFolder, AGarbageFileIsNotABag) {
  const fs::path garbage = work_ / "garbage.bag";
  std::ofstream(garbage) << "this is a text file, not a recording\n";
  const Process process = run("--bag " + garbage.string());
  EXPECT_EQ(process.status, 1);
  EXPECT_NE(process.err.find("not a ROS bag"), std::string::npos) << process.err;
}

// A recorder killed mid-session (SIGKILL: nothing closed, stdio buffers lost): written in a child process that
// exits without closing the bag, exactly as rosbag record leaves <name>.bag.active.
TEST_F(WorkFolder, AnUnfinishedBagIsRecoveredIntoACopyAndTheOriginalIsLeftAlone) {
  const fs::path active = work_ / "killed.bag.active";
  const PreparedBag reference = prepareSessionBag((kBags / "membrane_peeling_novice.bag").string());
  writeUnfinishedBag(active, reference.usable);
  ASSERT_TRUE(fs::exists(active));
  const std::string original_bytes = readText(active);
  {
    rosbag::Bag bag;
    EXPECT_THROW(bag.open(active.string(), rosbag::bagmode::Read), rosbag::BagException) << "it really is unindexed";
  }
  const PreparedBag prepared = prepareSessionBag(active.string());
  ASSERT_TRUE(prepared.recovery.has_value());
  EXPECT_NE(prepared.usable, prepared.original);
  EXPECT_EQ(readText(active), original_bytes) << "the original must not be modified";
  EXPECT_GT(prepared.recovery->messages, reference.messages / 2);
  EXPECT_LE(prepared.recovery->messages, reference.messages);
  EXPECT_GT(prepared.recovery->seconds, 1.0);
  // The tool replays what was recovered, says so, and exits 0.
  const Process process = run("--bag " + active.string());
  EXPECT_EQ(process.status, 0) << process.err;
  EXPECT_NE(process.err.find("recovered"), std::string::npos) << process.err;
  EXPECT_EQ(jsonField(process.out, "recovered_messages"), std::to_string(prepared.recovery->messages));
  EXPECT_GT(std::stoi(jsonField(process.out, "simulated_frames")), 0);
}

// rosbag record --bz2 / --lz4 killed mid-session: the closed chunks are decompressed and recovered, only the open one
// (its compressed stream has no end) is lost, and said so.
TEST_F(WorkFolder, AnUnfinishedCompressedBagLosesOnlyItsOpenChunk) {
  const PreparedBag reference = prepareSessionBag((kBags / "membrane_peeling_novice.bag").string());
  for (const auto& [name, compression] :
       {std::pair{"bz2", rosbag::compression::BZ2}, std::pair{"lz4", rosbag::compression::LZ4}}) {
    SCOPED_TRACE(name);
    const fs::path active = work_ / (std::string(name) + ".bag.active");
    writeUnfinishedBag(active, reference.usable, std::numeric_limits<std::size_t>::max(), {}, compression);
    const PreparedBag prepared = prepareSessionBag(active.string());
    ASSERT_TRUE(prepared.recovery.has_value());
    EXPECT_EQ(prepared.recovery->lost_compressed_chunks, 1u);
    EXPECT_NE(prepared.recovery->stop_reason.find("compressed chunk"), std::string::npos)
        << prepared.recovery->stop_reason;
    // 16 KiB chunks of a session of some MB: one lost chunk is a small part of it.
    EXPECT_GT(prepared.recovery->messages, reference.messages * 9 / 10);
    EXPECT_LT(prepared.recovery->messages, reference.messages);
    EXPECT_GT(prepared.recovery->seconds, 1.0);
    rosbag::Bag recovered(prepared.usable, rosbag::bagmode::Read);
    EXPECT_EQ(rosbag::View(recovered).size(), prepared.recovery->messages);
  }
}

// A message record of zero bytes (a std_msgs/Empty, or a fuzzed length): recovery leaves it out and counts it, since
// rosbag cannot copy an empty message without a memcpy through a null pointer (fuzz_session_bag, UBSan).
TEST_F(WorkFolder, AnEmptyMessageInAnUnfinishedBagIsLeftOutOfTheRecoveredCopyAndCounted) {
  const fs::path active = work_ / "with_empty.bag.active";
  const PreparedBag reference = prepareSessionBag((kBags / "navigation_expert.bag").string());
  constexpr std::size_t kCopied = 200;
  // After a non-empty message: rosbag's own write of a first empty one is what the recovery avoids.
  writeUnfinishedBag(active, reference.usable, kCopied,
                     [](rosbag::Bag& out, const rosbag::MessageInstance& message, std::size_t n) {
                       if (n == 0) out.write("/empty", message.getTime(), std_msgs::Empty());
                     });
  const PreparedBag prepared = prepareSessionBag(active.string());
  ASSERT_TRUE(prepared.recovery.has_value());
  EXPECT_EQ(prepared.recovery->empty_records, 1u);
  EXPECT_GT(prepared.recovery->messages, 0u);
  EXPECT_LE(prepared.recovery->messages, static_cast<std::uint64_t>(kCopied));
  EXPECT_EQ(prepared.topics.count("/empty"), 0u);
}

// Under load the recorder, a process of its own, falls behind on one topic: instrument states were recorded up to
// 188 ms after the eye states of their stamps. The live simulation received them in-process in stamp order, so the
// replay must follow the stamps, not the recorded order (else it counts late inputs the live session never had and
// ends in another state).
TEST_F(WorkFolder, ABagWhoseRecorderFellBehindOnOneTopicReplaysToTheSameStateAsInOrder) {
  const PreparedBag reference = prepareSessionBag((kBags / "membrane_peeling_novice.bag").string());
  const ReplayResult in_order = replaySession(reference, resolveSession(reference));
  const fs::path late = work_ / "late_instruments.bag";
  {
    rosbag::Bag source(reference.usable, rosbag::bagmode::Read);
    rosbag::Bag out(late.string(), rosbag::bagmode::Write);
    for (const rosbag::MessageInstance& message : rosbag::View(source)) {
      const bool instrument = message.getDataType() == "vrm_msgs/InstrumentState";
      out.write(message.getTopic(), message.getTime() + ros::Duration(instrument ? 0.15 : 0.0), message);
    }
  }
  {
    // The rewritten bag really is out of order: some eye state is recorded after a later-stamped instrument's tick.
    rosbag::Bag bag(late.string(), rosbag::bagmode::Read);
    ros::Time newest_eye_stamp;
    bool eye_ahead = false;
    for (const rosbag::MessageInstance& message : rosbag::View(bag)) {
      if (auto eye = message.instantiate<vrm_msgs::EyeState>()) newest_eye_stamp = eye->header.stamp;
      if (auto instrument = message.instantiate<vrm_msgs::InstrumentState>()) {
        eye_ahead = eye_ahead || newest_eye_stamp > instrument->header.stamp + ros::Duration(0.1);
      }
    }
    ASSERT_TRUE(eye_ahead) << "the test bag must have instruments recorded behind the eye states";
  }
  const PreparedBag prepared = prepareSessionBag(late.string());
  const ReplayResult result = replaySession(prepared, resolveSession(prepared));
  EXPECT_EQ(result.late_inputs, in_order.late_inputs);
  EXPECT_EQ(result.frames, in_order.frames);
  EXPECT_EQ(world::hashString(result.final_state_hash), world::hashString(in_order.final_state_hash));
}

TEST_F(WorkFolder, ABagCutOffInTheMiddleReplaysItsIntactPart) {
  const std::string bytes = readText(kBags / "navigation_expert.bag");
  const fs::path cut = work_ / "cut.bag";
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() * 6 / 10);
  const PreparedBag prepared = prepareSessionBag(cut.string());
  ASSERT_TRUE(prepared.recovery.has_value());
  EXPECT_GT(prepared.recovery->messages, 100u);
  EXPECT_LT(prepared.recovery->seconds, 7.0);
  const ReplayResult result = replaySession(prepared, resolveSession(prepared));
  EXPECT_GT(result.simulated_frames, 50u);
  EXPECT_LT(result.simulated_frames, 350u);
}

TEST_F(WorkFolder, CorruptBytesInTheMiddleGiveAClearErrorWithThePosition) {
  std::string bytes = readText(kBags / "vitrectomy_expert.bag");
  const std::size_t middle = bytes.size() / 2;
  for (std::size_t i = middle; i < middle + 4096 && i < bytes.size(); ++i) bytes[i] = '\xff';
  const fs::path corrupt = work_ / "corrupt.bag";
  std::ofstream(corrupt, std::ios::binary) << bytes;
  const Process process = run("--bag " + corrupt.string());
  EXPECT_EQ(process.status, 1) << process.out;
  EXPECT_NE(process.err.find(corrupt.string()), std::string::npos) << process.err;
  EXPECT_NE(process.err.find("corrupt"), std::string::npos) << process.err;
  EXPECT_NE(process.err.find("byte"), std::string::npos) << process.err;
  const auto broken = firstBrokenRecord(corrupt.string());
  ASSERT_TRUE(broken.has_value());
  EXPECT_LE(*broken, middle + 4096);
  EXPECT_FALSE(firstBrokenRecord((kBags / "vitrectomy_expert.bag").string()).has_value());
}

// rosbag parses a connection record's data with ros::Header::parse, which trusts each field's length: one that points
// past the data made it read beyond its buffer (ASan, found by fuzzing session_bag). The length field is checked
// before rosbag reads the bag, and such a bag is refused as corrupt with the record's position.
TEST_F(WorkFolder, AConnectionFieldLongerThanItsRecordIsRefusedBeforeRosbagReadsIt) {
  std::string bytes = readText(kBags / "navigation_expert.bag");
  // The last connection record is in the index section, which rosbag reads first when it opens a bag.
  const std::size_t field = bytes.rfind("message_definition=");
  ASSERT_NE(field, std::string::npos);
  ASSERT_GE(field, 4u);
  const std::uint32_t past_the_end = 900000;  // under ros::Header's own 10^6 limit, beyond this record's data
  std::memcpy(&bytes[field - 4], &past_the_end, 4);
  const fs::path corrupt = work_ / "connection_field.bag";
  std::ofstream(corrupt, std::ios::binary) << bytes;
  try {
    prepareSessionBag(corrupt.string());
    ADD_FAILURE() << "a bag with a connection field past its record was accepted";
  } catch (const BagError& error) {
    EXPECT_NE(std::string(error.what()).find("corrupt"), std::string::npos) << error.what();
  }
  const auto broken = firstBrokenRecord(corrupt.string());
  ASSERT_TRUE(broken.has_value());
  EXPECT_LT(*broken, field);
}

// A top-level record of a bag file, as the tests below need to corrupt one on purpose.
struct BagRecord {
  std::size_t offset = 0, data_offset = 0;
  std::uint32_t data_length = 0;
  std::map<std::string, std::string> header;
  std::uint8_t op() const { return static_cast<std::uint8_t>(header.at("op").at(0)); }
};
std::vector<BagRecord> topLevelRecords(const std::string& bytes) {
  std::vector<BagRecord> records;
  std::size_t at = std::strlen("#ROSBAG V2.0\n");
  auto u32 = [&bytes](std::size_t offset) {
    std::uint32_t value;
    std::memcpy(&value, bytes.data() + offset, 4);
    return value;
  };
  while (at + 4 <= bytes.size()) {
    BagRecord record;
    record.offset = at;
    const std::uint32_t header_length = u32(at);
    for (std::size_t field = at + 4; field < at + 4 + header_length;) {
      const std::string text = bytes.substr(field + 4, u32(field));
      record.header[text.substr(0, text.find('='))] = text.substr(text.find('=') + 1);
      field += 4 + text.size();
    }
    record.data_length = u32(at + 4 + header_length);
    record.data_offset = at + 8 + header_length;
    records.push_back(record);
    at = record.data_offset + record.data_length;
  }
  return records;
}

// A copy of `source` written by rosbag with chunks compressed by `compression`.
void writeCompressedCopy(const std::string& source, const fs::path& path, rosbag::CompressionType compression) {
  rosbag::Bag in(source, rosbag::bagmode::Read);
  rosbag::Bag out(path.string(), rosbag::bagmode::Write);
  out.setCompression(compression);
  out.setChunkThreshold(16 * 1024);  // several chunks, so the index check walks more than one
  for (const rosbag::MessageInstance& message : rosbag::View(in))
    out.write(message.getTopic(), message.getTime(), message);
}

void expectRefusedAsCorrupt(const fs::path& bag, std::size_t broken_at) {
  try {
    prepareSessionBag(bag.string());
    ADD_FAILURE() << bag << " was accepted";
  } catch (const BagError& error) {
    EXPECT_NE(std::string(error.what()).find("corrupt"), std::string::npos) << error.what();
  }
  const auto broken = firstBrokenRecord(bag.string());
  ASSERT_TRUE(broken.has_value());
  EXPECT_EQ(*broken, broken_at);
}

// rosbag's View reads the record at an index entry's offset in the chunk without a bounds check (found by fuzzing:
// src/vrm_fuzz/regressions/session_bag/index_entry_offset_outside_chunk). Every index reference is checked first.
TEST_F(WorkFolder, AnIndexEntryThatDoesNotNameAMessageOfItsChunkIsRefusedBeforeRosbagFollowsIt) {
  const std::string original = readText(kBags / "navigation_expert.bag");
  const std::vector<BagRecord> records = topLevelRecords(original);
  const auto chunk = std::find_if(records.begin(), records.end(), [](const BagRecord& r) { return r.op() == 0x05; });
  ASSERT_NE(chunk, records.end());
  const BagRecord& index = *(chunk + 1);
  ASSERT_EQ(index.op(), 0x04) << "an index record follows its chunk";
  ASSERT_GE(index.data_length, 24u);
  const std::size_t second_offset = index.data_offset + 12 + 8;
  std::uint32_t offset;
  std::memcpy(&offset, original.data() + second_offset, 4);
  struct Corruption {
    const char* what;
    std::size_t at;
    std::uint32_t value;
  };
  for (const Corruption& corruption : {
           Corruption{"past the chunk", second_offset, chunk->data_length + 4096},
           Corruption{"inside a record", second_offset, offset + 1},
           Corruption{"inside the chunk's last bytes", second_offset, chunk->data_length - 2},
           Corruption{"nanoseconds of 10^9 or more", second_offset - 4, 1000000000u},
       }) {
    SCOPED_TRACE(corruption.what);
    std::string bytes = original;
    std::memcpy(&bytes[corruption.at], &corruption.value, 4);
    const fs::path corrupt = work_ / "index_entry.bag";
    std::ofstream(corrupt, std::ios::binary) << bytes;
    expectRefusedAsCorrupt(corrupt, index.offset);
  }
  // The index record itself: a connection the index section does not declare (rosbag's open would dereference the
  // missing connection to log an entry's invalid time), or a count its data does not hold (rosbag reads `count`
  // entries from the file, into the records after it).
  for (const std::string field : {"conn=", "count="}) {
    SCOPED_TRACE(field);
    std::string bytes = original;
    const std::size_t at = bytes.find(field, index.offset) + field.size();
    ASSERT_LT(at, index.data_offset) << "a field of the index record's header";
    std::uint32_t number;
    std::memcpy(&number, bytes.data() + at, 4);
    number = field == "conn=" ? 999 : number + 1;
    std::memcpy(&bytes[at], &number, 4);
    const fs::path corrupt = work_ / "index_record.bag";
    std::ofstream(corrupt, std::ios::binary) << bytes;
    expectRefusedAsCorrupt(corrupt, index.offset);
  }
  // The entry may name a connection record before its message (rosbag writes it so for a connection's first message):
  // that is the first entry of the first index record here, and the original is accepted as it is.
  EXPECT_FALSE(firstBrokenRecord((kBags / "navigation_expert.bag").string()).has_value());
}

TEST_F(WorkFolder, AChunkInfoOrFileHeaderThatPointsOffARecordIsRefused) {
  const std::string original = readText(kBags / "navigation_expert.bag");
  const std::vector<BagRecord> records = topLevelRecords(original);
  const auto info = std::find_if(records.begin(), records.end(), [](const BagRecord& r) { return r.op() == 0x06; });
  ASSERT_NE(info, records.end());
  {
    std::string bytes = original;
    const std::size_t chunk_pos = bytes.find("chunk_pos=", info->offset) + std::strlen("chunk_pos=");
    bytes[chunk_pos] = static_cast<char>(bytes[chunk_pos] + 1);  // one byte into the chunk record
    const fs::path corrupt = work_ / "chunk_pos.bag";
    std::ofstream(corrupt, std::ios::binary) << bytes;
    expectRefusedAsCorrupt(corrupt, info->offset);
  }
  {
    std::string bytes = original;  // one connection more than its data lists
    const std::size_t count = bytes.find("count=", info->offset) + std::strlen("count=");
    ASSERT_LT(count, info->data_offset);
    bytes[count] = static_cast<char>(bytes[count] + 1);
    const fs::path corrupt = work_ / "chunk_info_count.bag";
    std::ofstream(corrupt, std::ios::binary) << bytes;
    expectRefusedAsCorrupt(corrupt, info->offset);
  }
  {
    std::string bytes = original;
    const std::size_t index_pos = bytes.find("index_pos=") + std::strlen("index_pos=");
    bytes[index_pos] = static_cast<char>(bytes[index_pos] + 1);
    const fs::path corrupt = work_ / "index_pos.bag";
    std::ofstream(corrupt, std::ios::binary) << bytes;
    expectRefusedAsCorrupt(corrupt, records.front().offset);
  }
}

// The index check reads bz2 and lz4 chunks as rosbag does, so a compressed session bag (rosbag compress) still
// replays, to the same final state as the original, and a wrong index entry in one is refused all the same.
TEST_F(WorkFolder, ACompressedBagIsCheckedThroughItsChunksAndReplaysLikeTheOriginal) {
  const std::string source = (kBags / "navigation_expert.bag").string();
  const std::string expected = readText(kBags / "navigation_expert.expected.json");
  for (const auto& [name, compression] :
       {std::pair{"bz2", rosbag::compression::BZ2}, std::pair{"lz4", rosbag::compression::LZ4}}) {
    SCOPED_TRACE(name);
    const fs::path compressed = work_ / (std::string(name) + ".bag");
    writeCompressedCopy(source, compressed, compression);
    EXPECT_FALSE(firstBrokenRecord(compressed.string()).has_value());
    const PreparedBag prepared = prepareSessionBag(compressed.string());
    EXPECT_FALSE(prepared.recovery.has_value()) << "rosbag opens it as it is";
    const ReplayResult result = replaySession(prepared, resolveSession(prepared));
    EXPECT_EQ(world::hashString(result.final_state_hash), jsonField(expected, "final_state_hash"));

    std::string bytes = readText(compressed);
    const std::vector<BagRecord> records = topLevelRecords(bytes);
    const auto chunk = std::find_if(records.begin(), records.end(), [](const BagRecord& r) { return r.op() == 0x05; });
    ASSERT_NE(chunk, records.end());
    ASSERT_EQ(chunk->header.at("compression"), name);
    const BagRecord& index = *(chunk + 1);
    const std::uint32_t past_the_chunk = 1u << 24;
    std::memcpy(&bytes[index.data_offset + 8], &past_the_chunk, 4);
    const fs::path corrupt = work_ / (std::string(name) + "_corrupt.bag");
    std::ofstream(corrupt, std::ios::binary) << bytes;
    expectRefusedAsCorrupt(corrupt, index.offset);
  }
}

TEST_F(WorkFolder, ABagOfAnotherSceneOrVersionIsReplayedWithItsOwnSceneAndAWarning) {
  const PreparedBag reference = prepareSessionBag((kBags / "navigation_expert.bag").string());
  const fs::path old_version = work_ / "old.bag";
  {
    rosbag::Bag source(reference.usable, rosbag::bagmode::Read);
    rosbag::Bag out(old_version.string(), rosbag::bagmode::Write);
    for (const rosbag::MessageInstance& message : rosbag::View(source)) {
      if (auto info = message.instantiate<vrm_msgs::SessionInfo>()) {
        info->software_version = "vrm_sim 0.0.9";
        out.write(message.getTopic(), message.getTime(), *info);
      } else {
        out.write(message.getTopic(), message.getTime(), message);
      }
    }
  }
  const PreparedBag prepared = prepareSessionBag(old_version.string());
  const SessionSetup setup = resolveSession(prepared);
  EXPECT_EQ(setup.scene_name, "navigation") << "the bag's scene is used";
  ASSERT_EQ(setup.warnings.size(), 1u);
  EXPECT_NE(setup.warnings[0].find("0.0.9"), std::string::npos) << setup.warnings[0];
  // The user overrides the scene: done, with a warning that the state will differ.
  const SessionSetup overridden = resolveSession(prepared, "membrane_peeling");
  EXPECT_EQ(overridden.scene, "membrane_peeling");
  ASSERT_EQ(overridden.warnings.size(), 2u);
  EXPECT_NE(overridden.warnings[0].find("recorded with scene 'navigation'"), std::string::npos);
  const Process process = run("--bag " + old_version.string() + " --print scene");
  EXPECT_EQ(process.status, 0);
  EXPECT_NE(process.out.find("navigation"), std::string::npos) << process.out;
}

// ---- the session journal (issue 39: crash = pause) ----

vrm_msgs::InputFrame journalFrame(std::uint64_t sequence) {
  vrm_msgs::InputFrame frame;
  frame.header.stamp = ros::Time(100, static_cast<std::uint32_t>(sequence * 20000000));
  frame.run = 42;
  frame.sequence = sequence;
  frame.kind = vrm_msgs::InputFrame::KIND_FRAME;
  vrm_msgs::InstrumentState instrument;
  instrument.header.stamp = frame.header.stamp;
  instrument.instrument_id = "right";
  instrument.tip_pose.orientation.w = 1.0;
  instrument.tip_pose.position.z = 0.001 * static_cast<double>(sequence);
  instrument.valid = true;
  frame.instrument_inputs.push_back(instrument);
  if (sequence == 1) {
    vrm_msgs::ScenarioCommand start;
    start.header.stamp = frame.header.stamp;
    start.command = vrm_msgs::ScenarioCommand::START;
    frame.commands.push_back(start);
  }
  frame.missing.push_back("eye");
  return frame;
}

TEST_F(WorkFolder, AJournalReadsBackItsHeaderAndEveryFrameAsWritten) {
  const std::string path = journalPath((work_ / "session.bag").string());
  EXPECT_EQ(path, (work_ / "session.journal").string());
  JournalWriter writer;
  writer.create(path, JournalHeader{"membrane_peeling", "hard", 7, 42});
  for (std::uint64_t sequence = 1; sequence <= 3; ++sequence) writer.append(journalFrame(sequence));
  writer.close();
  const JournalContents contents = readJournal(path);
  EXPECT_EQ(contents.header.scene, "membrane_peeling");
  EXPECT_EQ(contents.header.difficulty, "hard");
  EXPECT_EQ(contents.header.seed, 7u);
  EXPECT_EQ(contents.header.run, 42u);
  EXPECT_EQ(contents.torn_bytes, 0u);
  ASSERT_EQ(contents.frames.size(), 3u);
  for (std::uint64_t i = 0; i < 3; ++i) {
    const vrm_msgs::InputFrame expected = journalFrame(i + 1);
    const vrm_msgs::InputFrame& read = *contents.frames[i];
    EXPECT_EQ(read.sequence, expected.sequence);
    EXPECT_EQ(read.header.stamp, expected.header.stamp);
    ASSERT_EQ(read.instrument_inputs.size(), 1u);
    EXPECT_EQ(read.instrument_inputs[0].tip_pose.position.z, expected.instrument_inputs[0].tip_pose.position.z);
    EXPECT_EQ(read.commands.size(), expected.commands.size());
    EXPECT_EQ(read.missing, expected.missing);
  }
}

TEST_F(WorkFolder, ARecordCutOffByTheWritersDeathIsDroppedAndTheJournalGoesOnAfterTheLastWholeOne) {
  const std::string path = (work_ / "s.journal").string();
  JournalWriter writer;
  writer.create(path, JournalHeader{"navigation", "", 1, 5});
  for (std::uint64_t sequence = 1; sequence <= 4; ++sequence) writer.append(journalFrame(sequence));
  writer.close();
  fs::resize_file(path, fs::file_size(path) - 7);  // the process died inside the 4th write
  JournalContents contents = readJournal(path);
  ASSERT_EQ(contents.frames.size(), 3u);
  EXPECT_GT(contents.torn_bytes, 0u);
  EXPECT_EQ(contents.valid_bytes + contents.torn_bytes, fs::file_size(path));
  writer.reopen(path, contents.valid_bytes);
  writer.append(journalFrame(4));
  writer.close();
  contents = readJournal(path);
  ASSERT_EQ(contents.frames.size(), 4u);
  EXPECT_EQ(contents.torn_bytes, 0u);
  EXPECT_EQ(contents.frames.back()->sequence, 4u);
  // Cut inside a record's length: still the last whole record.
  fs::resize_file(path, contents.valid_bytes - (fs::file_size(path) - contents.valid_bytes) + 2);
  EXPECT_NO_THROW(readJournal(path));
}

TEST_F(WorkFolder, AFileThatIsNoJournalOrACorruptRecordIsAClearErrorNamingThePath) {
  const fs::path garbage = work_ / "garbage.journal";
  std::ofstream(garbage) << "this is not a journal at all";
  try {
    readJournal(garbage.string());
    FAIL() << "no error";
  } catch (const JournalError& error) {
    EXPECT_NE(std::string(error.what()).find(garbage.string()), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("VRMJ"), std::string::npos) << error.what();
  }
  EXPECT_THROW(readJournal((work_ / "absent.journal").string()), JournalError);
  // A sane header, then a record whose length no frame has.
  const std::string path = (work_ / "huge.journal").string();
  {
    JournalWriter writer;
    writer.create(path, JournalHeader{"navigation", "", 1, 5});
    writer.append(journalFrame(1));
  }
  {
    std::ofstream append(path, std::ios::binary | std::ios::app);
    const unsigned char huge[4] = {0xff, 0xff, 0xff, 0x7f};
    append.write(reinterpret_cast<const char*>(huge), 4);
    append << std::string(64, 'x');
  }
  try {
    readJournal(path);
    FAIL() << "no error";
  } catch (const JournalError& error) {
    EXPECT_NE(std::string(error.what()).find("a record of"), std::string::npos) << error.what();
  }
  // A record of a plausible length whose bytes are no frame (string lengths past the record).
  {
    JournalWriter writer;
    writer.create(path, JournalHeader{"navigation", "", 1, 5});
  }
  {
    std::ofstream append(path, std::ios::binary | std::ios::app);
    const unsigned char length[4] = {16, 0, 0, 0};
    append.write(reinterpret_cast<const char*>(length), 4);
    append << std::string(16, '\xff');
  }
  try {
    readJournal(path);
    FAIL() << "no error";
  } catch (const JournalError& error) {
    EXPECT_NE(std::string(error.what()).find("does not deserialise"), std::string::npos) << error.what();
  }
  JournalWriter writer;
  EXPECT_THROW(writer.create((work_ / "no" / "such" / "folder.journal").string(), JournalHeader{}), JournalError);
}

// The property crash = pause rests on: a Session handed the journal of a live one, midway, is in the live one's state
// and stays in it as both go on with the same inputs.
TEST_F(WorkFolder, ASessionRestoredFromTheJournalMidwayGoesOnInTheStateOfTheUninterruptedOne) {
  // The scene with its expert's paths (what scenario_offline plays).
  const scene::SceneDescription scene = scene::withScript(world::Session::loadByName("membrane_peeling", ""), "expert");
  const world::Stamp start = 1'000'000'000'000;
  const std::vector<world::InstrumentState> inputs = world::scriptedInputs(scene, 50.0, 6.0, start);
  ASSERT_GT(inputs.size(), 100u);
  world::WorldOptions options;
  options.log = [](world::Severity, const std::string&) {};
  const std::string path = (work_ / "s.journal").string();
  JournalWriter journal;
  journal.create(path, JournalHeader{"membrane_peeling", "", 0, 9});
  world::Session live(scene, options);
  live.setInputObserver([&journal](const world::InputFrame& frame) {
    vrm_msgs::InputFrame message;
    fillInputFrame(frame, "world", "eye", message);
    message.run = 9;
    journal.append(message);
  });
  // 4 s in (the expert holds the membrane), between two ticks: the crashed process applied whole frames.
  const std::size_t per_tick =
      static_cast<std::size_t>(std::count_if(inputs.begin(), inputs.end(), [&](const world::InstrumentState& input) {
        return input.stamp == inputs[0].stamp;
      }));
  const std::size_t crash = inputs.size() * 2 / 3 / per_tick * per_tick;
  for (std::size_t i = 0; i < crash; ++i) live.handle(inputs[i]);
  live.flush();  // what the live session applied is what its journal holds
  std::size_t grasped = 0;
  for (const std::string& name : live.world().tissueNames()) grasped += live.world().tissueReport(name).grasped_nodes;
  EXPECT_GT(grasped, 0u) << "the journal is cut while the expert holds the membrane";

  const JournalContents contents = readJournal(path);
  ASSERT_FALSE(contents.frames.empty());
  world::Session restored(scene, options);
  for (const vrm_msgs::InputFrame::Ptr& frame : contents.frames) restored.handle(toWorld(*frame));
  restored.continueSequence(contents.frames.back()->sequence + 1);
  EXPECT_EQ(restored.world().stateHash(), live.world().stateHash()) << "after " << contents.frames.size() << " frames";
  EXPECT_EQ(restored.nextSequence(), live.nextSequence());
  std::size_t restored_grasped = 0;
  for (const std::string& name : restored.world().tissueNames())
    restored_grasped += restored.world().tissueReport(name).grasped_nodes;
  EXPECT_EQ(restored_grasped, grasped);

  for (std::size_t i = crash; i < inputs.size(); ++i) {
    live.handle(inputs[i]);
    restored.handle(inputs[i]);
  }
  live.flush();
  restored.flush();
  EXPECT_EQ(restored.world().stateHash(), live.world().stateHash());
  EXPECT_EQ(restored.world().statistics().frames, live.world().statistics().frames);
}

// ---- checkpoints beside the journal (issue 39 §1) ----

TEST_F(WorkFolder, ACheckpointFileReadsBackWholeAndRefusesDamage) {
  Checkpoint checkpoint;
  checkpoint.header = JournalHeader{"membrane_peeling", "hard", 7, 3};
  checkpoint.sequence = 1234;
  checkpoint.stamp = 1800000000123456789;
  checkpoint.state_hash = 0xc1d1327e963450a8;
  checkpoint.state = std::string("state\0with zero bytes", 21) + std::string(5000, 'x');
  const std::string path = checkpointPath((work_ / "session.bag").string());
  EXPECT_EQ(path, (work_ / "session.checkpoint").string());
  writeCheckpoint(path, checkpoint);
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  const Checkpoint back = readCheckpoint(path);
  EXPECT_EQ(back.header.scene, "membrane_peeling");
  EXPECT_EQ(back.header.difficulty, "hard");
  EXPECT_EQ(back.header.seed, 7u);
  EXPECT_EQ(back.header.run, 3u);
  EXPECT_EQ(back.sequence, 1234u);
  EXPECT_EQ(back.stamp, 1800000000123456789);
  EXPECT_EQ(back.state_hash, 0xc1d1327e963450a8u);
  EXPECT_EQ(back.state, checkpoint.state);

  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  auto write = [&path](const std::string& content) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << content;
  };
  write(bytes.substr(0, bytes.size() - 3));  // cut short
  EXPECT_THROW(readCheckpoint(path), JournalError);
  std::string flipped = bytes;
  flipped[flipped.size() - 100] ^= 0x20;  // a bit of the state: the checksum says so
  write(flipped);
  try {
    readCheckpoint(path);
    ADD_FAILURE() << "accepted";
  } catch (const JournalError& error) {
    EXPECT_NE(std::string(error.what()).find("checksum"), std::string::npos) << error.what();
  }
  write("VRMJ" + bytes.substr(4));
  EXPECT_THROW(readCheckpoint(path), JournalError);

  // A write that fails (no such folder) leaves the previous checkpoint as it was.
  write(bytes);
  EXPECT_THROW(writeCheckpoint((work_ / "missing" / "session.checkpoint").string(), checkpoint), JournalError);
  EXPECT_EQ(readCheckpoint(path).state, checkpoint.state);
}

}  // namespace
}  // namespace bag
}  // namespace vrm_sim
