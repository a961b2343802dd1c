#include "vrm_sim/bag/session_bag.h"

#include <bzlib.h>
#include <ros/serialization.h>
#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>
#include <roslz4/lz4s.h>
#include <topic_tools/shape_shifter.h>
#include <unistd.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cstdint>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/InputFrame.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/PedalState.h"
#include "vrm_msgs/ScenarioCommand.h"

namespace vrm_sim {
namespace bag {

namespace {

// to − from in seconds. ros::Time's own difference is a Duration, which throws beyond ±2^31 s (a corrupt bag's
// times; fuzz_session_bag); the nanoseconds' difference fits an int64 for every ros::Time.
double secondsBetween(const ros::Time& from, const ros::Time& to) {
  return static_cast<double>(static_cast<std::int64_t>(to.toNSec()) - static_cast<std::int64_t>(from.toNSec())) * 1e-9;
}

namespace fs = std::filesystem;

constexpr char kMagic[] = "#ROSBAG V2.0\n";
constexpr std::size_t kMagicLength = sizeof(kMagic) - 1;
constexpr std::uint8_t kOpMessageData = 0x02;
constexpr std::uint8_t kOpFileHeader = 0x03;
constexpr std::uint8_t kOpIndexData = 0x04;
constexpr std::uint8_t kOpChunk = 0x05;
constexpr std::uint8_t kOpChunkInfo = 0x06;
constexpr std::uint8_t kOpConnection = 0x07;
// A record header is a handful of short fields (a connection's is the longest: topic + type + definition are in the
// data, not the header); anything larger is a broken length.
constexpr std::uint32_t kMaxHeaderLength = 1 << 16;

std::uint32_t readU32(const std::uint8_t* bytes) {
  std::uint32_t value;
  std::memcpy(&value, bytes, 4);  // rosbag is little-endian, like every machine this runs on
  return value;
}

// "name=value" fields of a record header or of a connection's data.
using Fields = std::map<std::string, std::string>;
bool parseFields(const std::uint8_t* bytes, std::size_t length, Fields& fields) {
  std::size_t at = 0;
  while (at < length) {
    if (length - at < 4) return false;
    const std::uint32_t field_length = readU32(bytes + at);
    at += 4;
    if (field_length > length - at) return false;
    const std::string field(reinterpret_cast<const char*>(bytes + at), field_length);
    const auto equals = field.find('=');
    if (equals == std::string::npos || equals == 0) return false;
    fields[field.substr(0, equals)] = field.substr(equals + 1);
    at += field_length;
  }
  return true;
}

struct Record {
  std::uint8_t op = 0;
  Fields header;
  std::uint64_t data_offset = 0;  // in the buffer
  std::uint32_t data_length = 0;
  bool data_complete = false;  // data_length bytes are there
};

// The record at `at` of `bytes[0, end)`: nullopt when its header is not well-formed or not complete.
std::optional<Record> readRecord(const std::vector<std::uint8_t>& bytes, std::uint64_t at, std::uint64_t end) {
  if (end < at + 4) return std::nullopt;
  const std::uint32_t header_length = readU32(bytes.data() + at);
  if (header_length == 0 || header_length > kMaxHeaderLength || end - at - 4 < header_length + 4ull) {
    return std::nullopt;
  }
  Record record;
  if (!parseFields(bytes.data() + at + 4, header_length, record.header)) return std::nullopt;
  const auto op = record.header.find("op");
  if (op == record.header.end() || op->second.size() != 1) return std::nullopt;
  record.op = static_cast<std::uint8_t>(op->second[0]);
  record.data_length = readU32(bytes.data() + at + 4 + header_length);
  record.data_offset = at + 8 + header_length;
  record.data_complete = record.data_offset + record.data_length <= end;
  return record;
}

std::vector<std::uint8_t> readFile(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw BagError(path + ": cannot open (" + std::strerror(errno) + ")");
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(file), {});
}

struct Connection {
  std::string topic;
  boost::shared_ptr<ros::M_string> header;  // type, md5sum, message_definition, callerid, latching
};

// The largest chunk whose uncompressed bytes the structure check and the recovery will hold. rosbag writes chunks of
// 768 KiB (one larger message makes one larger chunk); a session's inputs are far smaller.
constexpr std::uint32_t kMaxChunkSize = 64u << 20;

// A fixed-size little-endian field of a record header; nullopt when it is missing or has another size (rosbag's
// readField refuses those with an exception).
template <typename T>
std::optional<T> headerField(const Record& record, const char* name) {
  const auto field = record.header.find(name);
  if (field == record.header.end() || field->second.size() != sizeof(T)) return std::nullopt;
  T value;
  std::memcpy(&value, field->second.data(), sizeof(T));
  return value;
}

bool plainChunk(const Record& chunk) {
  const auto compression = chunk.header.find("compression");
  return compression != chunk.header.end() && compression->second == "none";
}

// A compressed (bz2, lz4) chunk's data as rosbag's View sees it, "size" bytes; nullopt when rosbag could not have it.
std::optional<std::vector<std::uint8_t>> decompressChunk(const std::vector<std::uint8_t>& bytes, const Record& chunk) {
  const auto compression = chunk.header.find("compression");
  const std::optional<std::uint32_t> size = headerField<std::uint32_t>(chunk, "size");
  if (compression == chunk.header.end() || !size || *size > kMaxChunkSize) return std::nullopt;
  auto* source = reinterpret_cast<char*>(const_cast<std::uint8_t*>(bytes.data() + chunk.data_offset));
  std::vector<std::uint8_t> contents(*size);
  unsigned int produced = *size;
  auto* target = reinterpret_cast<char*>(contents.data());
  bool whole = false;
  if (compression->second == "bz2") {
    whole = BZ2_bzBuffToBuffDecompress(target, &produced, source, chunk.data_length, 0, 0) == BZ_OK;
  } else if (compression->second == "lz4") {
    whole = roslz4_buffToBuffDecompress(source, chunk.data_length, target, &produced) == ROSLZ4_OK;
  }
  // rosbag does not check the length it got: a shorter stream would leave the rest of its buffer stale
  if (!whole || produced != *size) return std::nullopt;
  return contents;
}

struct RawMessage {
  std::uint32_t connection = 0;
  ros::Time time;
  const std::uint8_t* data = nullptr;  // in the file's bytes, or in a decompressed chunk of Scan::chunks
  std::uint32_t length = 0;
};

struct Scan {
  std::map<std::uint32_t, Connection> connections;
  std::vector<RawMessage> messages;
  std::deque<std::vector<std::uint8_t>> chunks;  // decompressed chunks (a deque: the messages point into them)
  std::uint64_t end_offset = 0;
  std::uint64_t lost_compressed_chunks = 0;
  std::string stop_reason;
};

// Adds a connection record rosbag can read: `conn` and `topic` in its header and "name=value" fields as its data.
// rosbag parses that data with ros::Header::parse, which trusts each field's length (it reads past the data's end when
// one points beyond it; found by fuzzing: src/vrm_fuzz/regressions/session_bag/connection_field_length_past_data).
// False, adding nothing, for anything else.
bool addConnection(const std::vector<std::uint8_t>& bytes, const Record& record, Scan& scan) {
  const auto id = record.header.find("conn");
  const auto topic = record.header.find("topic");
  if (id == record.header.end() || id->second.size() != 4 || topic == record.header.end()) return false;
  Fields fields;
  if (!record.data_complete || !parseFields(bytes.data() + record.data_offset, record.data_length, fields)) {
    return false;
  }
  Connection connection;
  connection.topic = topic->second;
  connection.header = boost::make_shared<ros::M_string>(fields.begin(), fields.end());
  (*connection.header)["topic"] = topic->second;
  scan.connections[readU32(reinterpret_cast<const std::uint8_t*>(id->second.data()))] = connection;
  return true;
}

// The records inside one uncompressed chunk, [begin, end): every complete message and connection record; stops at
// the first one that is cut off or not well-formed (the open chunk of a killed recorder ends that way).
// `records`, when given, receives the offset and op of each record read.
std::uint64_t scanChunk(const std::vector<std::uint8_t>& bytes, std::uint64_t begin, std::uint64_t end, Scan& scan,
                        std::vector<std::pair<std::uint64_t, std::uint8_t>>* records = nullptr) {
  std::uint64_t at = begin;
  while (at < end) {
    const std::optional<Record> record = readRecord(bytes, at, end);
    if (!record || !record->data_complete) break;
    if (records) records->emplace_back(at, record->op);
    if (record->op == kOpConnection) {
      if (!addConnection(bytes, *record, scan)) break;
    } else if (record->op == kOpMessageData) {
      const auto id = record->header.find("conn");
      const auto time = record->header.find("time");
      if (id == record->header.end() || id->second.size() != 4 || time == record->header.end() ||
          time->second.size() != 8) {
        break;
      }
      const auto* time_bytes = reinterpret_cast<const std::uint8_t*>(time->second.data());
      RawMessage message;
      message.connection = readU32(reinterpret_cast<const std::uint8_t*>(id->second.data()));
      message.time = ros::Time(readU32(time_bytes), readU32(time_bytes + 4));
      message.data = bytes.data() + record->data_offset;
      message.length = record->data_length;
      scan.messages.push_back(message);
    } else {
      break;  // nothing else lives inside a chunk
    }
    at = record->data_offset + record->data_length;
  }
  return at;
}

Scan scanBag(const std::vector<std::uint8_t>& bytes) {
  Scan scan;
  std::uint64_t at = kMagicLength;
  const std::uint64_t size = bytes.size();
  while (at < size) {
    const std::optional<Record> record = readRecord(bytes, at, size);
    if (!record) {
      scan.stop_reason = "the record at byte " + std::to_string(at) + " is not well-formed";
      break;
    }
    if (record->op == kOpChunk) {
      const bool plain = plainChunk(*record);
      // An open chunk (killed recorder) still has its placeholder length 0; a cut-off one points past the end.
      const bool open = record->data_length == 0 || !record->data_complete;
      if (!plain) {
        // A closed compressed chunk is read whole, as rosbag would; an open one (the recorder's last, killed) has no
        // complete compressed stream to read.
        std::optional<std::vector<std::uint8_t>> contents;
        if (!open) contents = decompressChunk(bytes, *record);
        if (!contents) {
          ++scan.lost_compressed_chunks;
          if (open) {
            scan.stop_reason = "a compressed chunk at byte " + std::to_string(at) + " has no end";
            break;
          }
        } else {
          const std::vector<std::uint8_t>& chunk = scan.chunks.emplace_back(std::move(*contents));
          scanChunk(chunk, 0, chunk.size(), scan);
        }
      } else {
        const std::uint64_t chunk_end = open ? size : record->data_offset + record->data_length;
        const std::uint64_t scanned = scanChunk(bytes, record->data_offset, chunk_end, scan);
        if (open) {
          at = scanned;
          if (scanned < size) scan.stop_reason = "the records end at byte " + std::to_string(scanned);
          break;
        }
      }
    } else if (record->op == kOpConnection && record->data_complete) {
      addConnection(bytes, *record, scan);
    }
    if (!record->data_complete) {
      scan.stop_reason = "the record at byte " + std::to_string(at) + " is cut off";
      break;
    }
    at = record->data_offset + record->data_length;
  }
  scan.end_offset = std::min<std::uint64_t>(at, size);
  return scan;
}

std::string recoveredCopyPath(const std::string& original, const std::string& directory) {
  std::string name = fs::path(original).filename().string();
  for (const std::string suffix : {".active", ".bag"}) {
    if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
      name.erase(name.size() - suffix.size());
    }
  }
  name += ".recovered.bag";
  if (!directory.empty()) return (fs::path(directory) / name).string();
  const fs::path beside = fs::absolute(original).parent_path();
  if (access(beside.c_str(), W_OK) == 0) return (beside / name).string();
  return (fs::temp_directory_path() / name).string();
}

std::string describeTopics(const std::map<std::string, std::uint64_t>& topics) {
  if (topics.empty()) return "no messages at all";
  std::ostringstream out;
  bool first = true;
  for (const auto& [topic, count] : topics) {
    out << (first ? "" : ", ") << topic << " (" << count << ")";
    first = false;
  }
  return out.str();
}

std::string join(const std::vector<std::string>& items) {
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : " ") + item;
  return text;
}

// Deserializes one message of an input topic (a structural error in its bytes throws).
void verify(const rosbag::MessageInstance& message) {
  const std::string& type = message.getDataType();
  if (type == "vrm_msgs/EyeState") {
    message.instantiate<vrm_msgs::EyeState>();
  } else if (type == "vrm_msgs/InstrumentState") {
    message.instantiate<vrm_msgs::InstrumentState>();
  } else if (type == "vrm_msgs/PedalState") {
    message.instantiate<vrm_msgs::PedalState>();
  } else if (type == "vrm_msgs/ScenarioCommand") {
    message.instantiate<vrm_msgs::ScenarioCommand>();
  } else if (type == "vrm_msgs/SessionInfo") {
    message.instantiate<vrm_msgs::SessionInfo>();
  } else if (type == "vrm_msgs/InputFrame") {
    message.instantiate<vrm_msgs::InputFrame>();
  }
}

}  // namespace

const std::vector<std::string>& inputTopics() {
  static const std::vector<std::string> topics = {"/input_frame", "/eye_state", "/instrument_state", "/pedals",
                                                   "/scenario_command"};
  return topics;
}

const std::vector<std::string>& deviceTopics() {
  static const std::vector<std::string> topics = {"/eye_state", "/instrument_state", "/pedals", "/scenario_command"};
  return topics;
}

bool recordsInputFrames(const PreparedBag& bag) {
  const auto frames = bag.topics.find(inputFrameTopic());
  return frames != bag.topics.end() && frames->second > 0;
}

const std::vector<std::string>& sessionTopics() {
  static const std::vector<std::string> topics = [] {
    std::vector<std::string> all = inputTopics();
    all.push_back("/microscope");
    all.push_back("/session_info");
    return all;
  }();
  return topics;
}

std::string softwareVersion() { return VRM_SIM_VERSION; }

namespace {

struct Break {
  std::uint64_t offset = 0;
  bool cut_off = false;  // the file ends inside this record (truncated or unfinished), rather than garbage in it
};

// Whether the record at `at` that readRecord() refused or found incomplete is cut off by the end of the file: its
// lengths are plausible but point past the end.
bool cutOffAt(const std::vector<std::uint8_t>& bytes, std::uint64_t at) {
  const std::uint64_t end = bytes.size();
  if (end < at + 4) return true;
  const std::uint32_t header_length = readU32(bytes.data() + at);
  if (header_length == 0 || header_length > kMaxHeaderLength) return false;
  if (end - at - 4 < header_length + 4ull) return true;
  const std::optional<Record> record = readRecord(bytes, at, end);
  return record && !record->data_complete;
}

struct TopLevelRecord {
  std::uint64_t offset = 0;
  Record record;
};

// The records of a chunk (scanChunk's) an index entry may name, as offsets from the chunk data's start `begin`,
// ascending: rosbag's View reads the record there, skips connection records, and expects a message record, all
// without a bounds check (Bag::readMessageDataHeaderFromBuffer).
using ChunkRecords = std::vector<std::pair<std::uint64_t, std::uint8_t>>;
std::vector<std::uint32_t> messageOffsets(const ChunkRecords& records, std::uint64_t begin) {
  std::vector<std::uint32_t> offsets;
  bool leads_to_message = false;
  for (auto record = records.rbegin(); record != records.rend(); ++record) {
    leads_to_message = record->second == kOpMessageData || (record->second == kOpConnection && leads_to_message);
    if (leads_to_message) offsets.push_back(static_cast<std::uint32_t>(record->first - begin));
  }
  std::reverse(offsets.begin(), offsets.end());
  return offsets;
}

// rosbag follows a bag's index without checking where it points: open() reads the records at the file header's
// index_pos (connections, then chunk infos), each chunk info's chunk and the index records right after it; the View
// then reads each index entry's offset inside the uncompressed chunk. A wrong number there makes rosbag read outside
// its buffers (found by fuzzing: src/vrm_fuzz/regressions/session_bag/index_entry_offset_outside_chunk) or throw
// what is not a BagException. This walks the same path over the records the structure check found intact; nullopt
// when every reference lands where rosbag expects it, or where rosbag refuses cleanly (an unindexed bag, a wrong op).
// `plain_offsets`: messageOffsets() of every uncompressed chunk, by the chunk record's offset.
std::optional<Break> findIndexBreak(const std::vector<std::uint8_t>& bytes, const std::vector<TopLevelRecord>& top,
                                    const std::map<std::uint64_t, std::vector<std::uint32_t>>& plain_offsets) {
  if (top.empty() || top.front().record.op != kOpFileHeader) return std::nullopt;
  const Record& file_header = top.front().record;
  const auto index_pos = headerField<std::uint64_t>(file_header, "index_pos");
  const auto connection_count = headerField<std::uint32_t>(file_header, "conn_count");
  const auto chunk_count = headerField<std::uint32_t>(file_header, "chunk_count");
  if (!index_pos || *index_pos == 0 || !connection_count || !chunk_count) return std::nullopt;
  std::map<std::uint64_t, std::size_t> at_offset;
  for (std::size_t i = 0; i < top.size(); ++i) at_offset[top[i].offset] = i;
  const Break broken_header{top.front().offset, false};
  // The index is the file's tail: a file that ends where it should begin lost it (recovery reads the chunks).
  if (*index_pos == bytes.size()) return Break{bytes.size(), true};
  const auto index = at_offset.find(*index_pos);
  if (index == at_offset.end()) return broken_header;
  if (index->second + *connection_count + *chunk_count > top.size()) return Break{bytes.size(), true};

  std::set<std::uint32_t> connections;
  for (std::size_t i = index->second; i < index->second + *connection_count; ++i) {
    if (top[i].record.op != kOpConnection) return std::nullopt;              // "Expected CONNECTION op not found"
    connections.insert(*headerField<std::uint32_t>(top[i].record, "conn"));  // addConnection checked its size
  }
  for (std::size_t i = index->second + *connection_count; i < index->second + *connection_count + *chunk_count; ++i) {
    const TopLevelRecord& info = top[i];
    if (info.record.op != kOpChunkInfo) return std::nullopt;  // "Expected CHUNK_INFO op not found"
    const auto chunk_pos = headerField<std::uint64_t>(info.record, "chunk_pos");
    const auto count = headerField<std::uint32_t>(info.record, "count");
    // rosbag reads `count` pairs straight from the file, so the data length must be exactly theirs
    if (!chunk_pos || !count || info.record.data_length != 8ull * *count) return Break{info.offset, false};
    std::set<std::uint32_t> chunk_connections;
    for (std::uint32_t k = 0; k < *count; ++k) {
      chunk_connections.insert(readU32(bytes.data() + info.record.data_offset + 8ull * k));
    }
    const auto chunk = at_offset.find(*chunk_pos);
    if (chunk == at_offset.end() || top[chunk->second].record.op != kOpChunk) return Break{info.offset, false};
    const Record& chunk_record = top[chunk->second].record;
    std::optional<std::vector<std::uint32_t>> offsets;
    if (plainChunk(chunk_record)) {
      // rosbag reads the record's data length and asserts it equals "size"
      if (headerField<std::uint32_t>(chunk_record, "size") == chunk_record.data_length) {
        offsets = plain_offsets.at(*chunk_pos);
      }
    } else if (const auto contents = decompressChunk(bytes, chunk_record)) {
      Scan scan;
      ChunkRecords records;
      if (scanChunk(*contents, 0, contents->size(), scan, &records) == contents->size()) {
        offsets = messageOffsets(records, 0);
      }
    }
    if (!offsets) return Break{*chunk_pos, false};
    // One index record per connection of the chunk, right after it.
    for (std::size_t k = 1; k <= chunk_connections.size(); ++k) {
      if (chunk->second + k >= top.size()) return Break{bytes.size(), true};
      const TopLevelRecord& entries = top[chunk->second + k];
      const auto version = headerField<std::uint32_t>(entries.record, "ver");
      const auto connection = headerField<std::uint32_t>(entries.record, "conn");
      const auto entry_count = headerField<std::uint32_t>(entries.record, "count");
      if (entries.record.op != kOpIndexData || version != 1u || !connection || !entry_count ||
          entries.record.data_length != 12ull * *entry_count || connections.count(*connection) == 0) {
        return Break{entries.offset, false};
      }
      for (std::uint32_t e = 0; e < *entry_count; ++e) {
        const std::uint8_t* entry = bytes.data() + entries.record.data_offset + 12ull * e;
        // ros::Time(sec, nsec) normalises nsec and throws std::runtime_error past 2^32 s
        if (readU32(entry + 4) >= 1000000000u ||
            !std::binary_search(offsets->begin(), offsets->end(), readU32(entry + 8))) {
          return Break{entries.offset, false};
        }
      }
    }
  }
  return std::nullopt;
}

std::optional<Break> findBreak(const std::vector<std::uint8_t>& bytes) {
  std::vector<TopLevelRecord> top;
  std::map<std::uint64_t, std::vector<std::uint32_t>> plain_offsets;
  std::uint64_t at = kMagicLength;
  while (at < bytes.size()) {
    const std::optional<Record> record = readRecord(bytes, at, bytes.size());
    if (!record || !record->data_complete) return Break{at, cutOffAt(bytes, at)};
    Scan scan;  // what the records hold is not kept here: only whether they read
    if (record->op == kOpConnection && !addConnection(bytes, *record, scan)) return Break{at, false};
    if (record->op == kOpChunk && plainChunk(*record)) {
      const std::uint64_t end = record->data_offset + record->data_length;
      ChunkRecords records;
      const std::uint64_t scanned = scanChunk(bytes, record->data_offset, end, scan, &records);
      if (scanned != end) return Break{scanned, false};
      plain_offsets[at] = messageOffsets(records, record->data_offset);
    }
    top.push_back({at, *record});
    at = record->data_offset + record->data_length;
  }
  return findIndexBreak(bytes, top, plain_offsets);
}

bool hasMagic(const std::vector<std::uint8_t>& bytes) {
  return bytes.size() >= kMagicLength && std::memcmp(bytes.data(), kMagic, kMagicLength) == 0;
}

}  // namespace

std::optional<std::uint64_t> firstBrokenRecord(const std::string& path) {
  const std::vector<std::uint8_t> bytes = readFile(path);
  if (!hasMagic(bytes)) return 0;
  const std::optional<Break> broken = findBreak(bytes);
  if (!broken) return std::nullopt;
  return broken->offset;
}

RecoveryReport recoverBag(const std::string& broken, const std::string& copy) {
  const std::vector<std::uint8_t> bytes = readFile(broken);
  if (bytes.size() < kMagicLength || std::memcmp(bytes.data(), kMagic, kMagicLength) != 0) {
    throw BagError(broken + ": not a ROS bag (no '#ROSBAG V2.0' header)");
  }
  Scan scan = scanBag(bytes);
  RecoveryReport report;
  report.file_size = bytes.size();
  report.end_offset = scan.end_offset;
  report.lost_compressed_chunks = scan.lost_compressed_chunks;
  report.stop_reason = scan.stop_reason;
  // Bag time order, as rosbag plays (records of one chunk are in write order already; chunks may interleave).
  std::stable_sort(scan.messages.begin(), scan.messages.end(),
                   [](const RawMessage& a, const RawMessage& b) { return a.time < b.time; });
  rosbag::Bag out;
  try {
    out.open(copy, rosbag::bagmode::Write);
    for (const RawMessage& raw : scan.messages) {
      const auto connection = scan.connections.find(raw.connection);
      if (connection == scan.connections.end() || raw.time.isZero()) continue;
      const ros::M_string& header = *connection->second.header;
      auto field = [&header](const char* name) {
        const auto found = header.find(name);
        return found == header.end() ? std::string() : found->second;
      };
      // No input of a session is empty (each has a header), and neither ShapeShifter::read nor rosbag's write can
      // take an empty message without a memcpy through a null pointer (UBSan, fuzz_session_bag): left out, counted.
      if (raw.length == 0) {
        ++report.empty_records;
        continue;
      }
      topic_tools::ShapeShifter message;
      message.morph(field("md5sum"), field("type"), field("message_definition"), field("latching"));
      ros::serialization::IStream stream(const_cast<std::uint8_t*>(raw.data), raw.length);
      message.read(stream);
      out.write(connection->second.topic, raw.time, message, connection->second.header);
      ++report.messages;
    }
    out.close();
  } catch (const rosbag::BagException& error) {
    throw BagError(broken + ": cannot write the recovered copy " + copy + ": " + error.what());
  }
  if (report.messages == 0) {
    std::error_code ignored;
    fs::remove(copy, ignored);
    throw BagError(broken + ": nothing to recover (" + (scan.stop_reason.empty() ? "no messages" : scan.stop_reason) +
                   ")");
  }
  ros::Time first, last;
  bool any = false;
  for (const RawMessage& raw : scan.messages) {
    if (scan.connections.count(raw.connection) == 0 || raw.time.isZero()) continue;
    if (!any) first = raw.time;
    last = raw.time;
    any = true;
  }
  report.seconds = secondsBetween(first, last);
  return report;
}

PreparedBag prepareSessionBag(const std::string& path, const PrepareOptions& options) {
  PreparedBag prepared;
  prepared.original = path;
  prepared.usable = path;
  std::error_code error_code;
  if (!fs::is_regular_file(path, error_code)) {
    // A recorder still running or killed leaves <name>.bag.active.
    if (fs::is_regular_file(path + ".active", error_code)) {
      throw BagError(path + ": no such file, but " + path + ".active exists (an unfinished recording); replay that");
    }
    throw BagError(path + ": no such file");
  }
  bool needs_recovery = path.size() > 7 && path.compare(path.size() - 7, 7, ".active") == 0;
  std::string open_error;
  if (!needs_recovery) {
    // rosbag trusts the length fields of the records it reads: a corrupt one makes it allocate gigabytes and abort on
    // an assert (found by fuzzing: src/vrm_fuzz/regressions/session_bag). So rosbag only opens a file whose record
    // structure is intact or merely cut off at the end (that one it refuses cleanly, and recovery reads it with the
    // scanner above); garbage inside the records is refused here with its position.
    const std::vector<std::uint8_t> bytes = readFile(path);
    if (!hasMagic(bytes)) throw BagError(path + ": not a ROS bag (no '#ROSBAG V2.0' header)");
    if (const std::optional<Break> broken = findBreak(bytes)) {
      if (!broken->cut_off) {
        throw BagError(path + ": corrupt: record structure broken at byte " + std::to_string(broken->offset));
      }
      needs_recovery = true;
      open_error = "cut off at byte " + std::to_string(broken->offset);
    }
  }
  if (!needs_recovery) {
    rosbag::Bag probe;  // a Bag whose open() threw stays unusable
    try {
      probe.open(path, rosbag::bagmode::Read);
    } catch (const rosbag::BagException& error) {
      needs_recovery = true;
      open_error = error.what();
    }
  }
  if (needs_recovery) {
    const std::string copy = recoveredCopyPath(path, options.recovery_dir);
    try {
      prepared.recovery = recoverBag(path, copy);
    } catch (const BagError& error) {
      throw BagError(std::string(error.what()) + (open_error.empty() ? "" : "; rosbag: " + open_error));
    }
    prepared.usable = copy;
  }
  rosbag::Bag bag;
  try {
    bag.open(prepared.usable, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& error) {
    throw BagError(path + ": " + (prepared.recovery ? "the recovered copy " + prepared.usable + " " : std::string()) +
                   "does not open: " + error.what());
  }

  rosbag::View view(bag);
  std::uint64_t index = 0;
  std::string last_topic;
  ros::Time first, last;
  try {
    for (const rosbag::MessageInstance& message : view) {
      last_topic = message.getTopic();
      if (index == 0) first = message.getTime();
      last = message.getTime();
      ++prepared.topics[message.getTopic()];
      if (options.verify_messages) verify(message);
      if (message.getTopic() == "/session_info" && !prepared.session_info) {
        if (auto info = message.instantiate<vrm_msgs::SessionInfo>()) prepared.session_info = *info;
      }
      ++index;
    }
  } catch (const std::exception& error) {
    std::string where = "after " + std::to_string(index) + " intact messages";
    if (index > 0) {
      char seconds[32];
      std::snprintf(seconds, sizeof(seconds), "%.3f", secondsBetween(first, last));
      where += " (the last on " + last_topic + " at +" + seconds + " s)";
    }
    std::string position;
    try {
      if (const auto broken = firstBrokenRecord(prepared.usable)) {
        position = ", record structure broken at byte " + std::to_string(*broken);
      }
    } catch (const std::exception&) {
    }
    throw BagError(path + ": corrupt: " + error.what() + " " + where + position);
  }
  prepared.messages = index;
  prepared.seconds = index > 0 ? secondsBetween(first, last) : 0.0;
  const bool has_input = std::any_of(inputTopics().begin(), inputTopics().end(),
                                     [&](const std::string& topic) { return prepared.topics.count(topic) > 0; });
  if (!has_input) {
    throw BagError(path + ": none of the simulator's input topics (expected " + join(inputTopics()) +
                   "); the bag has " + describeTopics(prepared.topics));
  }
  return prepared;
}

}  // namespace bag
}  // namespace vrm_sim
