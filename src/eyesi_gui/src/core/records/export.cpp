#include "eyesi_gui/records/export.h"

#include <fcntl.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "eyesi_gui/records/csv.h"
#include "eyesi_gui/records/server.h"

namespace eyesi_gui::records {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t kKeyBytes = 32;

std::string readOrCreateKey(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    unsigned char key[kKeyBytes];
    if (RAND_bytes(key, sizeof(key)) != 1) throw StoreError("RAND_bytes failed (OpenSSL)");
    // 0600 from the start: the key turns every pseudonym back into a name for whoever can guess the names.
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0) throw StoreError(path + ": cannot create the pseudonym key: " + std::strerror(errno));
    const bool written = ::write(fd, key, sizeof(key)) == static_cast<ssize_t>(sizeof(key));
    ::close(fd);
    if (!written) throw StoreError(path + ": cannot write the pseudonym key");
    return std::string(reinterpret_cast<const char*>(key), sizeof(key));
  }
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (bytes.str().size() < 16) throw StoreError(path + ": a pseudonym key needs at least 16 bytes");
  return bytes.str();
}

std::string number(double x) { return std::isfinite(x) ? formatNumber(x) : ""; }

class Table {
 public:
  Table(const fs::path& path, const std::vector<std::string>& header) : path_(path.string()), out_(path_) {
    if (!out_) throw StoreError(path_ + ": cannot write the export table");
    writeCsvRow(out_, header);
  }
  void row(const std::vector<std::string>& fields) {
    writeCsvRow(out_, fields);
    ++rows_;
  }
  std::size_t close() {
    out_.close();
    if (!out_) throw StoreError(path_ + ": writing the export table failed");
    return rows_;
  }

 private:
  std::string path_;
  std::ofstream out_;
  std::size_t rows_ = 0;
};

}  // namespace

std::string pseudonym(const std::string& key, const std::string& kind, const std::string& name) {
  const std::string message = kind + ":" + name;
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  if (HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()),
           reinterpret_cast<const unsigned char*>(message.data()), message.size(), digest, &length) == nullptr) {
    throw StoreError("HMAC-SHA256 failed (OpenSSL)");
  }
  std::string text = "p-";
  char hex[3];
  for (unsigned int i = 0; i < 8 && i < length; ++i) {
    std::snprintf(hex, sizeof(hex), "%02x", digest[i]);
    text += hex;
  }
  return text;
}

namespace {

ExportCounts writeTables(const std::vector<SessionRecord>& all_sessions,
                         const std::function<std::vector<TrajectorySample>(std::int64_t)>& trajectory_of,
                         const std::string& folder, const ExportOptions& options) {
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) throw StoreError(folder + ": cannot create the export folder: " + ec.message());
  const bool pseudonymise = !options.pseudonym_key_file.empty();
  const std::string key = pseudonymise ? readOrCreateKey(options.pseudonym_key_file) : "";
  const auto user = [&](const std::string& name) { return pseudonymise ? pseudonym(key, "user", name) : name; };
  const auto station = [&](const std::string& name) {
    return pseudonymise && !name.empty() ? pseudonym(key, "station", name) : name;
  };
  const auto when = [&](const std::string& iso) { return pseudonymise ? iso.substr(0, 10) : iso; };

  const fs::path dir(folder);
  Table sessions(dir / "sessions.csv", {"session_key", "user", "station", "scene", "scenario", "difficulty", "seed",
                                        "state", "passed", "total", "elapsed", "start_stamp", "end_stamp",
                                        "recorded_at", "software_version", "frames", "events_dropped"});
  Table items(dir / "score_items.csv", {"session_key", "position", "item", "value", "unit", "weight", "points"});
  Table groups(dir / "score_groups.csv", {"session_key", "position", "group", "points", "weight"});
  Table events(dir / "penalty_events.csv",
               {"session_key", "position", "time", "kind", "item", "slot", "instrument", "x", "y", "z", "points"});
  Table samples(dir / "trajectories.csv",
                {"session_key", "frame", "time", "source", "frame_id", "x", "y", "z", "qx", "qy", "qz", "qw", "valid"});
  for (const SessionRecord& s : all_sessions) {
    const std::string& k = s.global_key;
    sessions.row({k, user(s.user), station(s.station), s.scene, s.scenario, s.difficulty, std::to_string(s.seed),
                  s.state, s.passed ? "1" : "0", number(s.total), number(s.elapsed), number(s.start_stamp),
                  number(s.end_stamp), when(s.recorded_at), s.software_version, std::to_string(s.frames),
                  std::to_string(s.events_dropped)});
    for (std::size_t i = 0; i < s.items.size(); ++i) {
      const ScoreItemRecord& it = s.items[i];
      items.row({k, std::to_string(i), it.name, number(it.value), it.unit, number(it.weight), number(it.points)});
    }
    for (std::size_t i = 0; i < s.groups.size(); ++i) {
      const GroupRecord& g = s.groups[i];
      groups.row({k, std::to_string(i), g.name, number(g.points), number(g.weight)});
    }
    for (std::size_t i = 0; i < s.events.size(); ++i) {
      const PenaltyEventRecord& e = s.events[i];
      events.row({k, std::to_string(i), number(e.time), e.kind, e.item, e.slot, e.instrument, number(e.position[0]),
                  number(e.position[1]), number(e.position[2]), number(e.points)});
    }
    for (const TrajectorySample& t : trajectory_of(s.id)) {
      samples.row({k, std::to_string(t.frame), number(t.time), t.source, t.frame_id, number(t.position[0]),
                   number(t.position[1]), number(t.position[2]), number(t.orientation[0]), number(t.orientation[1]),
                   number(t.orientation[2]), number(t.orientation[3]), t.valid ? "1" : "0"});
    }
  }
  ExportCounts counts;
  counts.sessions = sessions.close();
  counts.items = items.close();
  counts.groups = groups.close();
  counts.events = events.close();
  counts.samples = samples.close();
  return counts;
}

}  // namespace

ExportCounts exportTables(const Store& store, const std::string& folder, const ExportOptions& options) {
  return writeTables(
      store.sessions(options.filter), [&store](std::int64_t id) { return store.trajectory(id); }, folder, options);
}

ExportCounts exportServerTables(const std::string& connection, const std::string& folder,
                                const ExportOptions& options) {
  ServerReader reader(connection);
  return writeTables(
      reader.sessions(options.filter), [&reader](std::int64_t id) { return reader.trajectory(id); }, folder, options);
}

}  // namespace eyesi_gui::records
