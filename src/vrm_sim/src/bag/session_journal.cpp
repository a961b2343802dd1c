#include "vrm_sim/bag/session_journal.h"

#include <fcntl.h>
#include <ros/serialization.h>
#include <unistd.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>

namespace vrm_sim {
namespace bag {
namespace {

constexpr char kMagic[4] = {'V', 'R', 'M', 'J'};
constexpr std::uint32_t kVersion = 1;
// Far above any frame (two instruments and an eye: ~1 KB); a larger length is corruption, not a frame.
constexpr std::uint32_t kMaxRecord = 16u << 20;

void putU32(std::vector<std::uint8_t>& out, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(value >> (8 * i)));
}
void putU64(std::vector<std::uint8_t>& out, std::uint64_t value) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<std::uint8_t>(value >> (8 * i)));
}
void putString(std::vector<std::uint8_t>& out, const std::string& text) {
  putU32(out, static_cast<std::uint32_t>(text.size()));
  out.insert(out.end(), text.begin(), text.end());
}

class Reader {
 public:
  Reader(const std::string& path, const std::vector<std::uint8_t>& data, const char* kind = "session journal")
      : path_(path), data_(data), kind_(kind) {}
  bool has(std::size_t bytes) const { return data_.size() - offset_ >= bytes; }
  std::uint32_t u32() {
    need(4, "a number");
    std::uint32_t value = 0;
    for (int i = 0; i < 4; ++i) value |= static_cast<std::uint32_t>(data_[offset_ + i]) << (8 * i);
    offset_ += 4;
    return value;
  }
  std::uint64_t u64() {
    need(8, "a number");
    std::uint64_t value = 0;
    for (int i = 0; i < 8; ++i) value |= static_cast<std::uint64_t>(data_[offset_ + i]) << (8 * i);
    offset_ += 8;
    return value;
  }
  std::string string() {
    const std::uint32_t size = u32();
    if (size > 4096) fail("a header string of " + std::to_string(size) + " bytes");
    need(size, "a header string");
    std::string text(reinterpret_cast<const char*>(data_.data() + offset_), size);
    offset_ += size;
    return text;
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw JournalError(path_ + ": not a readable " + kind_ + ": " + what + " at byte " + std::to_string(offset_));
  }
  void need(std::size_t bytes, const char* what) const {
    if (!has(bytes)) fail(std::string("the file ends inside ") + what);
  }
  std::size_t offset_ = 0;

 private:
  const std::string& path_;
  const std::vector<std::uint8_t>& data_;
  std::string kind_;
};

std::string reason() { return std::strerror(errno); }

}  // namespace

std::string journalPath(const std::string& bag_path) {
  const bool has_suffix = bag_path.size() > 4 && bag_path.compare(bag_path.size() - 4, 4, ".bag") == 0;
  return (has_suffix ? bag_path.substr(0, bag_path.size() - 4) : bag_path) + ".journal";
}

JournalWriter::~JournalWriter() { close(); }

void JournalWriter::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void JournalWriter::writeAll(const std::uint8_t* data, std::size_t size) {
  std::size_t written = 0;
  while (written < size) {
    const ssize_t count = ::write(fd_, data + written, size - written);
    if (count < 0 && errno == EINTR) continue;
    if (count <= 0) {
      const std::string why = count < 0 ? reason() : "nothing written";
      // A partial record would be read as a torn tail; cut it so that appends after a transient error stay readable.
      if (written > 0 && ::ftruncate(fd_, static_cast<off_t>(bytes_)) == 0) ::lseek(fd_, 0, SEEK_END);
      throw JournalError(path_ + ": cannot write the session journal: " + why);
    }
    written += static_cast<std::size_t>(count);
  }
  bytes_ += size;
}

void JournalWriter::create(const std::string& path, const JournalHeader& header) {
  close();
  path_ = path;
  bytes_ = records_ = 0;
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) throw JournalError(path + ": cannot create the session journal: " + reason());
  std::vector<std::uint8_t> bytes(kMagic, kMagic + 4);
  putU32(bytes, kVersion);
  putString(bytes, header.scene);
  putString(bytes, header.difficulty);
  putU32(bytes, header.seed);
  putU64(bytes, header.run);
  writeAll(bytes.data(), bytes.size());
}

void JournalWriter::reopen(const std::string& path, std::uint64_t valid_bytes) {
  close();
  path_ = path;
  fd_ = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd_ < 0) throw JournalError(path + ": cannot open the session journal: " + reason());
  if (::ftruncate(fd_, static_cast<off_t>(valid_bytes)) != 0 || ::lseek(fd_, 0, SEEK_END) < 0) {
    const std::string why = reason();
    close();
    throw JournalError(path + ": cannot continue the session journal: " + why);
  }
  bytes_ = valid_bytes;
  records_ = 0;
}

void JournalWriter::append(const vrm_msgs::InputFrame& frame) {
  if (fd_ < 0) throw JournalError("the session journal is not open");
  const std::uint32_t size = ros::serialization::serializationLength(frame);
  buffer_.resize(4 + static_cast<std::size_t>(size));
  for (int i = 0; i < 4; ++i) buffer_[i] = static_cast<std::uint8_t>(size >> (8 * i));
  ros::serialization::OStream stream(buffer_.data() + 4, size);
  ros::serialization::serialize(stream, frame);
  writeAll(buffer_.data(), buffer_.size());
  ++records_;
}

JournalContents readJournal(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw JournalError(path + ": cannot open the session journal");
  const std::vector<std::uint8_t> data((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  Reader reader(path, data);
  reader.need(4, "the magic");
  if (std::memcmp(data.data(), kMagic, 4) != 0) reader.fail("no VRMJ magic");
  reader.offset_ = 4;
  const std::uint32_t version = reader.u32();
  if (version != kVersion) reader.fail("version " + std::to_string(version) + " (this reads 1)");
  JournalContents contents;
  contents.header.scene = reader.string();
  contents.header.difficulty = reader.string();
  contents.header.seed = reader.u32();
  contents.header.run = reader.u64();
  contents.valid_bytes = reader.offset_;
  while (reader.has(1)) {
    if (!reader.has(4)) break;  // torn inside the length
    const std::size_t record_start = reader.offset_;
    const std::uint32_t size = reader.u32();
    if (size > kMaxRecord) {
      reader.offset_ = record_start;
      reader.fail("a record of " + std::to_string(size) + " bytes");
    }
    if (!reader.has(size)) {
      reader.offset_ = record_start;
      break;  // torn: the writer died inside this record
    }
    auto frame = boost::make_shared<vrm_msgs::InputFrame>();
    try {
      ros::serialization::IStream stream(const_cast<std::uint8_t*>(data.data() + reader.offset_), size);
      ros::serialization::deserialize(stream, *frame);
    } catch (const std::exception& error) {
      reader.offset_ = record_start;
      reader.fail(std::string("a frame that does not deserialise (") + error.what() + ")");
    }
    reader.offset_ += size;
    contents.frames.push_back(std::move(frame));
    contents.valid_bytes = reader.offset_;
  }
  contents.torn_bytes = data.size() - contents.valid_bytes;
  return contents;
}

}  // namespace bag
}  // namespace vrm_sim

// ---- checkpoints ----

namespace vrm_sim {
namespace bag {
namespace {

constexpr char kCheckpointMagic[4] = {'V', 'R', 'M', 'C'};
constexpr std::uint32_t kCheckpointVersion = 1;

std::uint64_t fnv1a(const std::string& bytes) {
  std::uint64_t hash = 1469598103934665603ull;
  for (unsigned char c : bytes) hash = (hash ^ c) * 1099511628211ull;
  return hash;
}

}  // namespace

std::string checkpointPath(const std::string& bag_path) {
  const std::string journal = journalPath(bag_path);
  return journal.substr(0, journal.size() - std::strlen(".journal")) + ".checkpoint";
}

void writeCheckpoint(const std::string& path, const Checkpoint& checkpoint) {
  std::vector<std::uint8_t> head(kCheckpointMagic, kCheckpointMagic + 4);
  putU32(head, kCheckpointVersion);
  putString(head, checkpoint.header.scene);
  putString(head, checkpoint.header.difficulty);
  putU32(head, checkpoint.header.seed);
  putU64(head, checkpoint.header.run);
  putU64(head, checkpoint.sequence);
  putU64(head, static_cast<std::uint64_t>(checkpoint.stamp));
  putU64(head, checkpoint.state_hash);
  putU64(head, checkpoint.state.size());
  std::vector<std::uint8_t> tail;
  putU64(tail, fnv1a(checkpoint.state));
  const std::string temporary = path + ".tmp";
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw JournalError("cannot write the checkpoint " + temporary + ": " + reason());
  auto write_all = [&](const void* data, std::size_t size) {
    const char* p = static_cast<const char*>(data);
    while (size > 0) {
      const ssize_t written = ::write(fd, p, size);
      if (written < 0 && errno == EINTR) continue;
      if (written <= 0) return false;
      p += written;
      size -= static_cast<std::size_t>(written);
    }
    return true;
  };
  const bool ok = write_all(head.data(), head.size()) && write_all(checkpoint.state.data(), checkpoint.state.size()) &&
                  write_all(tail.data(), tail.size()) && ::fsync(fd) == 0;
  const std::string why = ok ? "" : reason();
  ::close(fd);
  if (!ok || std::rename(temporary.c_str(), path.c_str()) != 0) {
    const std::string message = "cannot write the checkpoint " + path + ": " + (ok ? reason() : why);
    ::unlink(temporary.c_str());
    throw JournalError(message);
  }
}

Checkpoint readCheckpoint(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw JournalError("cannot read the checkpoint " + path + ": " + reason());
  const std::vector<std::uint8_t> data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Reader reader(path, data, "session checkpoint");
  reader.need(4, "the magic");
  if (!std::equal(kCheckpointMagic, kCheckpointMagic + 4, data.begin())) {
    throw JournalError(path + ": not a session checkpoint (no VRMC magic)");
  }
  reader.offset_ = 4;
  if (const std::uint32_t version = reader.u32(); version != kCheckpointVersion) {
    reader.fail("version " + std::to_string(version) + " (this build reads " + std::to_string(kCheckpointVersion) +
                ")");
  }
  Checkpoint checkpoint;
  checkpoint.header.scene = reader.string();
  checkpoint.header.difficulty = reader.string();
  checkpoint.header.seed = reader.u32();
  checkpoint.header.run = reader.u64();
  checkpoint.sequence = reader.u64();
  checkpoint.stamp = static_cast<std::int64_t>(reader.u64());
  checkpoint.state_hash = reader.u64();
  const std::uint64_t size = reader.u64();
  if (!reader.has(size) || data.size() - reader.offset_ - size != 8)
    reader.fail("a state length that is not the file's");
  checkpoint.state.assign(reinterpret_cast<const char*>(data.data() + reader.offset_), size);
  reader.offset_ += size;
  if (reader.u64() != fnv1a(checkpoint.state)) reader.fail("a state whose checksum does not match");
  return checkpoint;
}

}  // namespace bag
}  // namespace vrm_sim
