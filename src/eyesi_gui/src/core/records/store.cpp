#include "eyesi_gui/records/store.h"

#include <fcntl.h>
#include <openssl/rand.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <ostream>
#include <sstream>

#include "eyesi_gui/records/csv.h"
#include "eyesi_gui/records/pin_hash.h"
#include "eyesi_gui/records/result_json.h"
#include "eyesi_gui/records/schema.h"

namespace eyesi_gui::records {
namespace fs = std::filesystem;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

constexpr int kBusyTimeoutMs = 5000;
constexpr const char* kGuest = "guest";

bool isDamageCode(int code) {
  const int primary = code & 0xff;
  // IOERR covers the short read of a file cut off mid-write.
  return primary == SQLITE_CORRUPT || primary == SQLITE_NOTADB || primary == SQLITE_IOERR;
}

struct CloseDb {
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
using DbHandle = std::unique_ptr<sqlite3, CloseDb>;

// Read-only, never created: the checks below must not write a byte to a file that may be damaged (no journal
// rollback, no WAL checkpoint — a read-only connection does neither).
DbHandle openReadOnly(const std::string& path) {
  sqlite3* raw = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &raw, SQLITE_OPEN_READONLY, nullptr);
  DbHandle db(raw);
  if (rc != SQLITE_OK) {
    throw StoreError(path + ": cannot open the database: " + (raw ? sqlite3_errmsg(raw) : sqlite3_errstr(rc)));
  }
  sqlite3_extended_result_codes(raw, 1);
  sqlite3_busy_timeout(raw, kBusyTimeoutMs);
  return db;
}

// The rows of a single-column query (a PRAGMA); returns the SQLite result code, `error` holding its message.
int queryColumn(sqlite3* db, const char* sql, std::vector<std::string>* rows, std::string* error) {
  sqlite3_stmt* stmt = nullptr;
  int rc = sqlite3_prepare_v2(db, sql, -1, &stmt, nullptr);
  while (rc == SQLITE_OK && (rc = sqlite3_step(stmt)) == SQLITE_ROW) {
    const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
    rows->push_back(text ? text : "");
    rc = SQLITE_OK;
  }
  if (rc == SQLITE_DONE) rc = SQLITE_OK;
  if (rc != SQLITE_OK) *error = sqlite3_errmsg(db);
  sqlite3_finalize(stmt);
  return rc;
}

std::string joinLines(const std::vector<std::string>& lines) {
  std::string joined;
  for (const auto& line : lines) joined += (joined.empty() ? "" : "\n") + line;
  return joined;
}

std::string damagedMessage(const std::string& path, const std::string& report) {
  // One line (the tool prints what() as its error line); the whole report is in integrityReport().
  std::istringstream lines(report);
  std::string line, summary;
  int shown = 0, more = 0;
  while (std::getline(lines, line)) {
    if (shown < 3) {
      summary += (shown++ ? "; " : "") + line;
    } else {
      ++more;
    }
  }
  if (more > 0) summary += "; ... " + std::to_string(more) + " more";
  return path + ": the database is damaged (integrity_check: " + summary + "); the file was left untouched";
}

std::string nowIso8601() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  gmtime_r(&now, &utc);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return buffer;
}

// A random (version 4) UUID: the session's key on the records server. Random rather than station id + row id, so a
// station rebuilt from a backup, or two stations given the same name by mistake, still never reuse a key.
std::string newGlobalKey() {
  unsigned char bytes[16];
  if (RAND_bytes(bytes, sizeof(bytes)) != 1) throw StoreError("RAND_bytes failed (OpenSSL)");
  bytes[6] = static_cast<unsigned char>((bytes[6] & 0x0f) | 0x40);
  bytes[8] = static_cast<unsigned char>((bytes[8] & 0x3f) | 0x80);
  char text[37];
  std::snprintf(text, sizeof(text), "%02x%02x%02x%02x-%02x%02x-%02x%02x-%02x%02x-%02x%02x%02x%02x%02x%02x", bytes[0],
                bytes[1], bytes[2], bytes[3], bytes[4], bytes[5], bytes[6], bytes[7], bytes[8], bytes[9], bytes[10],
                bytes[11], bytes[12], bytes[13], bytes[14], bytes[15]);
  return text;
}

Role roleFromString(const std::string& text) { return text == "instructor" ? Role::kInstructor : Role::kTrainee; }

bool isBlank(const std::string& text) {
  return std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isspace(c) != 0; });
}

// Trainee names, scores and PIN hashes are personal data (SECURITY.md): the database is readable by its owner only.
// SQLite creates a new database with 0644 & ~umask, and its -wal and -shm files with the database file's mode, so
// the file is created here with 0600 before SQLite opens it, and files of an older version are tightened to 0600.
// Best effort for files of another owner (chmod is refused; the store still opens them).
void restrictToOwner(const std::string& path) {
  for (const std::string& file : {path, path + "-wal", path + "-shm", path + "-journal"}) {
    struct stat info {};
    if (::stat(file.c_str(), &info) == 0 && S_ISREG(info.st_mode) && (info.st_mode & 0077) != 0) {
      ::chmod(file.c_str(), info.st_mode & 0600);
    }
  }
}

// The folders the store creates (e.g. ~/.ros/eyesi) are private too: 0700. Existing folders are left as they are.
void createPrivateFolders(const fs::path& folder) {
  if (folder.empty() || fs::exists(folder)) return;
  createPrivateFolders(folder.parent_path());
  if (::mkdir(folder.c_str(), 0700) != 0 && errno != EEXIST) {
    throw StoreError(folder.string() + ": cannot create the folder: " + std::strerror(errno));
  }
}

void createPrivateFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (fd >= 0) {
    ::close(fd);
  } else if (errno != EEXIST) {  // another process may have created it meanwhile: then SQLite opens that one
    throw StoreError(path + ": cannot create the database file: " + std::strerror(errno));
  }
}

}  // namespace

const char* toString(Role role) { return role == Role::kInstructor ? "instructor" : "trainee"; }

std::string Store::integrityCheck(const std::string& path) {
  const DbHandle db = openReadOnly(path);
  std::vector<std::string> rows;
  std::string error;
  if (queryColumn(db.get(), "PRAGMA integrity_check", &rows, &error) != SQLITE_OK) {
    // "file is not a database", or a page so broken that the check itself stops: still a report, not "ok".
    rows.push_back("integrity_check failed: " + error);
  }
  return joinLines(rows);
}

struct Store::Impl {
  std::string path;
  sqlite3* db = nullptr;
  int version = 0;
  // One connection, so one transaction at a time: the mutex makes a Store safe to share between threads.
  mutable std::mutex mutex;

  ~Impl() {
    // The last connection to close checkpoints the WAL into the file and removes it.
    if (db != nullptr) sqlite3_close_v2(db);
  }

  [[noreturn]] void fail(const std::string& what, int code) const {
    if (isDamageCode(code)) {
      std::string report;
      try {
        report = integrityCheck(path);
      } catch (const StoreError& e) {
        report = e.what();
      }
      throw StoreError(damagedMessage(path, report), report);
    }
    throw StoreError(path + ": " + what + ": " + sqlite3_errmsg(db));
  }

  void exec(const char* sql, const char* what) const {
    char* message = nullptr;
    const int rc = sqlite3_exec(db, sql, nullptr, nullptr, &message);
    if (rc != SQLITE_OK) {
      const std::string text = message ? message : sqlite3_errstr(rc);
      sqlite3_free(message);
      if (isDamageCode(rc)) fail(what, rc);
      throw StoreError(path + ": " + what + ": " + text);
    }
  }

  // A prepared statement with typed binds and column reads; errors name the database file.
  class Statement {
   public:
    Statement(const Impl& impl, const char* sql) : impl_(impl) {
      const int rc = sqlite3_prepare_v2(impl.db, sql, -1, &stmt_, nullptr);
      if (rc != SQLITE_OK) impl.fail("cannot prepare a query", rc);
    }
    ~Statement() { sqlite3_finalize(stmt_); }
    Statement(const Statement&) = delete;
    Statement& operator=(const Statement&) = delete;

    Statement& text(int index, const std::string& value) {
      sqlite3_bind_text(stmt_, index, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT);
      return *this;
    }
    Statement& real(int index, double value) {
      sqlite3_bind_double(stmt_, index, value);
      return *this;
    }
    Statement& integer(int index, std::int64_t value) {
      sqlite3_bind_int64(stmt_, index, value);
      return *this;
    }
    Statement& blob(int index, const std::vector<unsigned char>& value) {
      sqlite3_bind_blob(stmt_, index, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT);
      return *this;
    }
    Statement& null(int index) {
      sqlite3_bind_null(stmt_, index);
      return *this;
    }

    // true: a row is ready; false: done.
    bool step() {
      const int rc = sqlite3_step(stmt_);
      if (rc == SQLITE_ROW) return true;
      if (rc == SQLITE_DONE) return false;
      impl_.fail("query failed", rc);
    }
    void reset() {
      sqlite3_reset(stmt_);
      sqlite3_clear_bindings(stmt_);
    }

    std::string textAt(int column) const {
      const auto* value = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, column));
      return value ? std::string(value, static_cast<std::size_t>(sqlite3_column_bytes(stmt_, column))) : "";
    }
    double realAt(int column) const { return sqlite3_column_double(stmt_, column); }
    std::int64_t integerAt(int column) const { return sqlite3_column_int64(stmt_, column); }
    std::vector<unsigned char> blobAt(int column) const {
      const auto* data = static_cast<const unsigned char*>(sqlite3_column_blob(stmt_, column));
      return data ? std::vector<unsigned char>(data, data + sqlite3_column_bytes(stmt_, column))
                  : std::vector<unsigned char>();
    }
    bool isNull(int column) const { return sqlite3_column_type(stmt_, column) == SQLITE_NULL; }

   private:
    const Impl& impl_;
    sqlite3_stmt* stmt_ = nullptr;
  };

  // BEGIN ... COMMIT, rolled back when left without commit() (an exception on the way).
  class Transaction {
   public:
    // Writers take the write lock up front (IMMEDIATE): a deferred read that later upgrades can fail with
    // SQLITE_BUSY at once, without the busy timeout ever being applied.
    Transaction(const Impl& impl, bool write) : impl_(impl) {
      impl.exec(write ? "BEGIN IMMEDIATE" : "BEGIN", "cannot begin a transaction");
    }
    ~Transaction() {
      if (!done_) sqlite3_exec(impl_.db, "ROLLBACK", nullptr, nullptr, nullptr);
    }
    void commit() {
      impl_.exec("COMMIT", "cannot commit");
      done_ = true;
    }

   private:
    const Impl& impl_;
    bool done_ = false;
  };

  int userVersion() const {
    Statement stmt(*this, "PRAGMA user_version");
    return stmt.step() ? static_cast<int>(stmt.integerAt(0)) : 0;
  }

  std::int64_t tableCount() const {
    Statement stmt(*this, "SELECT count(*) FROM sqlite_master WHERE type = 'table'");
    return stmt.step() ? stmt.integerAt(0) : 0;
  }

  void migrate() {
    for (;;) {
      Transaction tx(*this, true);
      // Read inside the write lock: another process may have migrated since this one looked.
      const int current = userVersion();
      if (current > Store::kSchemaVersion) {
        throw StoreError(path + ": schema version " + std::to_string(current) + " is newer than this software (" +
                         std::to_string(Store::kSchemaVersion) + "); update the console");
      }
      if (current == Store::kSchemaVersion) {
        tx.commit();
        version = current;
        return;
      }
      if (current == 0 && tableCount() > 0) {
        throw StoreError(path + ": holds tables but no records schema version; not a training-records database");
      }
      exec(migrationSql(current + 1), "schema migration failed");
      exec(("PRAGMA user_version = " + std::to_string(current + 1)).c_str(), "schema migration failed");
      tx.commit();
    }
  }

  std::optional<std::int64_t> userId(const std::string& name) const {
    Statement stmt(*this, "SELECT id FROM users WHERE name = ?1");
    stmt.text(1, name);
    if (!stmt.step()) return std::nullopt;
    return stmt.integerAt(0);
  }

  std::int64_t insertUser(const std::string& name, Role role, const std::optional<PinHash>& pin) {
    Statement stmt(*this,
                   "INSERT INTO users (name, role, pin_salt, pin_hash, iterations, created_at) "
                   "VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
    stmt.text(1, name).text(2, toString(role)).text(6, nowIso8601());
    if (pin) {
      stmt.blob(3, pin->salt).blob(4, pin->hash).integer(5, pin->iterations);
    } else {
      stmt.null(3).null(4).integer(5, 0);
    }
    stmt.step();
    return sqlite3_last_insert_rowid(db);
  }

  void ensureGuest() {
    if (userId(kGuest)) return;  // the usual case writes nothing
    Transaction tx(*this, true);
    if (!userId(kGuest)) insertUser(kGuest, Role::kTrainee, std::nullopt);
    tx.commit();
  }

  static constexpr const char* kSessionColumns =
      "SELECT s.id, u.name, s.scene, s.scenario, s.difficulty, s.seed, s.state, s.message, s.total, s.passed, "
      "s.elapsed, s.start_stamp, s.end_stamp, s.recorded_at, s.bag_path, s.result_path, s.software_version, "
      "s.final_state_hash, s.frames, s.station, s.annotation, s.global_key FROM sessions s "
      "JOIN users u ON u.id = s.user_id ";

  static SessionRecord sessionFromRow(const Statement& row) {
    SessionRecord s;
    s.id = row.integerAt(0);
    s.user = row.textAt(1);
    s.scene = row.textAt(2);
    s.scenario = row.textAt(3);
    s.difficulty = row.textAt(4);
    s.seed = static_cast<std::uint32_t>(row.integerAt(5));
    s.state = row.textAt(6);
    s.message = row.textAt(7);
    s.total = row.realAt(8);
    s.passed = row.integerAt(9) != 0;
    s.elapsed = row.realAt(10);
    s.start_stamp = row.realAt(11);
    s.end_stamp = row.realAt(12);
    s.recorded_at = row.textAt(13);
    s.bag_path = row.textAt(14);
    s.result_path = row.textAt(15);
    s.software_version = row.textAt(16);
    s.final_state_hash = row.textAt(17);
    s.frames = static_cast<std::uint64_t>(row.integerAt(18));
    s.station = row.textAt(19);
    s.annotation = row.textAt(20);
    s.global_key = row.textAt(21);
    return s;
  }

  void loadItems(std::vector<SessionRecord>* sessions) const {
    Statement stmt(*this,
                   "SELECT name, value, unit, weight, points FROM score_items WHERE session_id = ?1 ORDER BY position");
    for (auto& s : *sessions) {
      stmt.reset();
      stmt.integer(1, s.id);
      while (stmt.step()) {
        s.items.push_back({stmt.textAt(0), stmt.realAt(1), stmt.textAt(2), stmt.realAt(3), stmt.realAt(4)});
      }
    }
    loadGroupsAndEvents(sessions);
  }

  void insertTrajectory(std::int64_t id, const std::vector<TrajectorySample>& trajectory) {
    if (trajectory.empty()) return;
    Statement sample(*this,
                     "INSERT INTO trajectory_samples (session_id, position, frame, time, source, frame_id, x, y, z, "
                     "qx, qy, qz, qw, valid) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14)");
    for (std::size_t i = 0; i < trajectory.size(); ++i) {
      const TrajectorySample& t = trajectory[i];
      sample.reset();
      sample.integer(1, id)
          .integer(2, static_cast<std::int64_t>(i))
          .integer(3, static_cast<std::int64_t>(t.frame))
          .real(4, t.time)
          .text(5, t.source)
          .text(6, t.frame_id)
          .integer(14, t.valid ? 1 : 0);
      const double values[] = {t.position[0],    t.position[1],    t.position[2],   t.orientation[0],
                               t.orientation[1], t.orientation[2], t.orientation[3]};
      for (int k = 0; k < 7; ++k) {
        if (std::isfinite(values[k])) {
          sample.real(7 + k, values[k]);
        } else {
          sample.null(7 + k);
        }
      }
      sample.step();
    }
  }

  std::vector<TrajectorySample> loadTrajectory(std::int64_t session_id) const {
    Statement stmt(*this,
                   "SELECT frame, time, source, frame_id, x, y, z, qx, qy, qz, qw, valid FROM trajectory_samples "
                   "WHERE session_id = ?1 ORDER BY position");
    stmt.integer(1, session_id);
    std::vector<TrajectorySample> samples;
    while (stmt.step()) {
      TrajectorySample t;
      t.frame = static_cast<std::uint64_t>(stmt.integerAt(0));
      t.time = stmt.realAt(1);
      t.source = stmt.textAt(2);
      t.frame_id = stmt.textAt(3);
      double* values[] = {&t.position[0],    &t.position[1],    &t.position[2],   &t.orientation[0],
                          &t.orientation[1], &t.orientation[2], &t.orientation[3]};
      for (int k = 0; k < 7; ++k) *values[k] = stmt.isNull(4 + k) ? kNaN : stmt.realAt(4 + k);
      t.valid = stmt.integerAt(11) != 0;
      samples.push_back(std::move(t));
    }
    return samples;
  }

  void loadGroupsAndEvents(std::vector<SessionRecord>* sessions) const {
    Statement dropped(*this, "SELECT events_dropped FROM sessions WHERE id = ?1");
    Statement groups(*this, "SELECT name, points, weight FROM score_groups WHERE session_id = ?1 ORDER BY position");
    Statement events(*this,
                     "SELECT time, kind, item, slot, instrument, x, y, z, points FROM penalty_events "
                     "WHERE session_id = ?1 ORDER BY position");
    const auto coordinate = [&events](int column) { return events.isNull(column) ? kNaN : events.realAt(column); };
    for (auto& s : *sessions) {
      dropped.reset();
      dropped.integer(1, s.id);
      if (dropped.step()) s.events_dropped = static_cast<std::uint64_t>(dropped.integerAt(0));
      groups.reset();
      groups.integer(1, s.id);
      while (groups.step()) s.groups.push_back({groups.textAt(0), groups.realAt(1), groups.realAt(2)});
      events.reset();
      events.integer(1, s.id);
      while (events.step()) {
        PenaltyEventRecord event;
        event.time = events.realAt(0);
        event.kind = events.textAt(1);
        event.item = events.textAt(2);
        event.slot = events.textAt(3);
        event.instrument = events.textAt(4);
        for (int axis = 0; axis < 3; ++axis) event.position[axis] = coordinate(5 + axis);
        event.points = events.realAt(8);
        s.events.push_back(std::move(event));
      }
    }
  }
};

Store::Store(const std::string& path) : impl_(nullptr) {
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  if (path.empty()) throw StoreError("records database: empty path");

  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (fs::exists(status)) {
    if (fs::is_directory(status)) throw StoreError(path + ": is a folder, not a records database");
    if (fs::file_size(path, ec) > 0 && !ec) {
      // Check read-only before the read-write open: switching to WAL, rolling back a journal or checkpointing
      // would write into a damaged file and could destroy what is left to rescue.
      const DbHandle ro = openReadOnly(path);
      std::vector<std::string> rows;
      std::string error;
      const int rc = queryColumn(ro.get(), "PRAGMA quick_check", &rows, &error);
      if (rc != SQLITE_OK && !isDamageCode(rc)) throw StoreError(path + ": cannot read the database: " + error);
      if (rc != SQLITE_OK || rows != std::vector<std::string>{"ok"}) {
        const std::string report = integrityCheck(path);
        throw StoreError(damagedMessage(path, report), report);
      }
      rows.clear();
      if (queryColumn(ro.get(), "SELECT count(*) FROM sqlite_master WHERE type = 'table'", &rows, &error) ==
              SQLITE_OK &&
          rows.size() == 1 && rows[0] != "0") {
        rows.clear();
        queryColumn(ro.get(), "PRAGMA user_version", &rows, &error);
        if (rows.size() == 1 && rows[0] == "0") {
          throw StoreError(path + ": an SQLite database of another program (no records schema version); not opened");
        }
      }
    }
  } else {
    try {
      createPrivateFolders(fs::path(path).parent_path());
    } catch (const StoreError& error) {
      throw StoreError(path + ": " + error.what());
    }
    createPrivateFile(path);
  }
  restrictToOwner(path);

  const int rc = sqlite3_open_v2(path.c_str(), &impl->db,
                                 SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    throw StoreError(path +
                     ": cannot open the database: " + (impl->db ? sqlite3_errmsg(impl->db) : sqlite3_errstr(rc)));
  }
  sqlite3_extended_result_codes(impl->db, 1);
  sqlite3_busy_timeout(impl->db, kBusyTimeoutMs);
  impl->exec("PRAGMA foreign_keys = ON", "cannot enable foreign keys");
  {
    // WAL: readers (the console, the records tool, a backup) see a consistent snapshot while a session is written.
    Impl::Statement stmt(*impl, "PRAGMA journal_mode = WAL");
    const std::string mode = stmt.step() ? stmt.textAt(0) : "";
    if (mode != "wal") {
      throw StoreError(path + ": the file system does not support the WAL journal (journal mode \"" + mode + "\")");
    }
  }
  impl->migrate();
  impl->ensureGuest();
  impl_ = impl.release();
}

Store::~Store() { delete impl_; }

const std::string& Store::path() const { return impl_->path; }

int Store::schemaVersion() const { return impl_->version; }

User Store::addUser(const std::string& name, Role role, const std::string& pin) {
  if (isBlank(name)) throw StoreError(impl_->path + ": a user needs a name");
  // PBKDF2 takes tens of milliseconds; hash before taking the lock.
  std::optional<PinHash> hash;
  if (!pin.empty()) hash = hashPin(pin);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Transaction tx(*impl_, true);
  if (impl_->userId(name)) throw StoreError(impl_->path + ": user \"" + name + "\" already exists");
  User user;
  user.id = impl_->insertUser(name, role, hash);
  tx.commit();
  user.name = name;
  user.role = role;
  user.has_pin = hash.has_value();
  return user;
}

void Store::setPin(const std::string& name, const std::string& pin) {
  if (name == kGuest) throw StoreError(impl_->path + ": guest has no PIN");
  std::optional<PinHash> hash;
  if (!pin.empty()) hash = hashPin(pin);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Statement stmt(*impl_, "UPDATE users SET pin_salt = ?2, pin_hash = ?3, iterations = ?4 WHERE name = ?1");
  stmt.text(1, name);
  if (hash) {
    stmt.blob(2, hash->salt).blob(3, hash->hash).integer(4, hash->iterations);
  } else {
    stmt.null(2).null(3).integer(4, 0);
  }
  stmt.step();
  if (sqlite3_changes(impl_->db) == 0) throw StoreError(impl_->path + ": no user \"" + name + "\"");
}

std::vector<User> Store::users() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Statement stmt(*impl_,
                       "SELECT id, name, role, pin_hash IS NOT NULL, origin = 'server' FROM users ORDER BY name");
  std::vector<User> users;
  while (stmt.step()) {
    users.push_back({stmt.integerAt(0), stmt.textAt(1), roleFromString(stmt.textAt(2)), stmt.integerAt(3) != 0,
                     stmt.integerAt(4) != 0});
  }
  return users;
}

std::optional<User> Store::findUser(const std::string& name) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Statement stmt(*impl_,
                       "SELECT id, name, role, pin_hash IS NOT NULL, origin = 'server' FROM users WHERE name = ?1");
  stmt.text(1, name);
  if (!stmt.step()) return std::nullopt;
  return User{stmt.integerAt(0), stmt.textAt(1), roleFromString(stmt.textAt(2)), stmt.integerAt(3) != 0,
              stmt.integerAt(4) != 0};
}

bool Store::checkPin(const std::string& name, const std::string& pin) const {
  if (name == kGuest) return true;
  PinHash stored;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    Impl::Statement stmt(*impl_, "SELECT pin_salt, pin_hash, iterations FROM users WHERE name = ?1");
    stmt.text(1, name);
    if (!stmt.step()) return false;
    // A user without a PIN (created by an import from another station) logs in with an empty PIN only.
    if (stmt.isNull(1)) return pin.empty();
    stored = {stmt.blobAt(0), stmt.blobAt(1), static_cast<int>(stmt.integerAt(2))};
  }
  return verifyPin(pin, stored);
}

ImportResult Store::recordSession(const SessionRecord& session) {
  if (session.scene.empty()) throw StoreError(impl_->path + ": a session needs a scene");
  const std::string key = sessionKey(session);
  const std::string recorded_at = session.recorded_at.empty() ? nowIso8601() : session.recorded_at;
  const std::string user = session.user.empty() ? kGuest : session.user;

  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Transaction tx(*impl_, true);
  {
    Impl::Statement existing(*impl_, "SELECT id FROM sessions WHERE session_key = ?1");
    existing.text(1, key);
    if (existing.step()) {
      const ImportResult result{existing.integerAt(0), false};
      tx.commit();
      return result;
    }
  }
  // A result from another station may name a user this one does not know; keep the session, create the trainee.
  std::optional<std::int64_t> user_id = impl_->userId(user);
  if (!user_id) user_id = impl_->insertUser(user, Role::kTrainee, std::nullopt);

  Impl::Statement insert(*impl_,
                         "INSERT INTO sessions (session_key, user_id, scene, scenario, difficulty, seed, state, "
                         "message, total, passed, elapsed, start_stamp, end_stamp, recorded_at, bag_path, "
                         "result_path, software_version, final_state_hash, frames, station, annotation, global_key) "
                         "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, "
                         "?19, ?20, ?21, ?22)");
  insert.text(1, key)
      .integer(2, *user_id)
      .text(3, session.scene)
      .text(4, session.scenario)
      .text(5, session.difficulty)
      .integer(6, session.seed)
      .text(7, session.state)
      .text(8, session.message)
      .real(9, session.total)
      .integer(10, session.passed ? 1 : 0)
      .real(11, session.elapsed)
      .real(12, session.start_stamp)
      .real(13, session.end_stamp)
      .text(14, recorded_at)
      .text(15, session.bag_path)
      .text(16, session.result_path)
      .text(17, session.software_version)
      .text(18, session.final_state_hash)
      .integer(19, static_cast<std::int64_t>(session.frames))
      .text(20, session.station)
      .text(21, session.annotation)
      .text(22, session.global_key.empty() ? newGlobalKey() : session.global_key);
  insert.step();
  const std::int64_t id = sqlite3_last_insert_rowid(impl_->db);

  Impl::Statement item(*impl_,
                       "INSERT INTO score_items (session_id, position, name, value, unit, weight, points) "
                       "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)");
  for (std::size_t i = 0; i < session.items.size(); ++i) {
    const ScoreItemRecord& it = session.items[i];
    item.reset();
    item.integer(1, id)
        .integer(2, static_cast<std::int64_t>(i))
        .text(3, it.name)
        .real(4, it.value)
        .text(5, it.unit)
        .real(6, it.weight)
        .real(7, it.points);
    item.step();
  }
  Impl::Statement group(
      *impl_, "INSERT INTO score_groups (session_id, position, name, points, weight) VALUES (?1, ?2, ?3, ?4, ?5)");
  for (std::size_t i = 0; i < session.groups.size(); ++i) {
    const GroupRecord& g = session.groups[i];
    group.reset();
    group.integer(1, id).integer(2, static_cast<std::int64_t>(i)).text(3, g.name).real(4, g.points).real(5, g.weight);
    group.step();
  }
  Impl::Statement event(*impl_,
                        "INSERT INTO penalty_events (session_id, position, time, kind, item, slot, instrument, x, y, "
                        "z, points) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)");
  for (std::size_t i = 0; i < session.events.size(); ++i) {
    const PenaltyEventRecord& e = session.events[i];
    event.reset();
    event.integer(1, id)
        .integer(2, static_cast<std::int64_t>(i))
        .real(3, e.time)
        .text(4, e.kind)
        .text(5, e.item)
        .text(6, e.slot)
        .text(7, e.instrument)
        .real(11, e.points);
    // An unknown coordinate is NULL (SQLite would store a NaN as NULL anyway; say so).
    for (int axis = 0; axis < 3; ++axis) {
      if (std::isfinite(e.position[axis])) {
        event.real(8 + axis, e.position[axis]);
      } else {
        event.null(8 + axis);
      }
    }
    event.step();
  }
  impl_->insertTrajectory(id, session.trajectory);
  if (session.events_dropped > 0) {
    Impl::Statement dropped(*impl_, "UPDATE sessions SET events_dropped = ?2 WHERE id = ?1");
    dropped.integer(1, id).integer(2, static_cast<std::int64_t>(session.events_dropped));
    dropped.step();
  }
  tx.commit();
  return {id, true};
}

ImportResult Store::importResultJson(const std::string& json_text, const std::string& origin, const std::string& user,
                                     const std::string& bag) {
  SessionRecord session = parseResultJson(json_text, origin);
  if (!user.empty()) session.user = user;
  if (!bag.empty()) session.bag_path = bag;
  return recordSession(session);
}

ImportResult Store::importResultFile(const std::string& path, const std::string& user) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw StoreError(path + ": cannot read the result file: " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  SessionRecord session = parseResultJson(text.str(), path);
  std::error_code ec;
  const fs::path absolute = fs::absolute(path, ec);
  // Absolute, so the console can find the file again whatever folder the import ran in.
  session.result_path = ec ? path : absolute.lexically_normal().string();
  if (!user.empty()) session.user = user;
  const std::string trajectory_path = trajectoryPathFor(path);
  if (fs::exists(trajectory_path, ec)) {
    std::ifstream trajectory(trajectory_path, std::ios::binary);
    if (!trajectory) throw StoreError(trajectory_path + ": cannot read the trajectory file: " + std::strerror(errno));
    std::ostringstream trajectory_text;
    trajectory_text << trajectory.rdbuf();
    session.trajectory = parseTrajectoryJson(trajectory_text.str(), trajectory_path);
  }
  return recordSession(session);
}

std::vector<std::string> Store::findResultFiles(const std::string& folder) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) throw StoreError(folder + ": not a folder");
  std::vector<std::string> files;
  const std::string suffix = ".result.json";
  for (fs::recursive_directory_iterator it(folder, fs::directory_options::skip_permission_denied, ec), end;
       !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (it->is_regular_file(ec) && name.size() > suffix.size() &&
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
      files.push_back(it->path().string());
    }
  }
  if (ec) throw StoreError(folder + ": cannot list the folder: " + ec.message());
  std::sort(files.begin(), files.end());  // a stable order: ids follow the file names
  return files;
}

std::vector<ImportResult> Store::importFolder(const std::string& folder, std::vector<std::string>* errors) {
  std::vector<ImportResult> results;
  for (const std::string& file : findResultFiles(folder)) {
    try {
      results.push_back(importResultFile(file));
    } catch (const StoreError& e) {
      if (errors != nullptr) errors->push_back(e.what());
    }
  }
  return results;
}

std::vector<SessionRecord> Store::sessions(const SessionFilter& filter) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  // One read transaction: the sessions and their items come from the same snapshot even while another
  // connection writes.
  Impl::Transaction tx(*impl_, false);
  Impl::Statement stmt(
      *impl_, (std::string(Impl::kSessionColumns) + "WHERE (?1 = '' OR u.name = ?1) AND (?2 = '' OR s.scene = ?2) "
                                                    "ORDER BY s.start_stamp, s.id")
                  .c_str());
  stmt.text(1, filter.user).text(2, filter.scene);
  std::vector<SessionRecord> sessions;
  while (stmt.step()) sessions.push_back(Impl::sessionFromRow(stmt));
  impl_->loadItems(&sessions);
  tx.commit();
  return sessions;
}

std::optional<SessionRecord> Store::session(std::int64_t id) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Transaction tx(*impl_, false);
  Impl::Statement stmt(*impl_, (std::string(Impl::kSessionColumns) + "WHERE s.id = ?1").c_str());
  stmt.integer(1, id);
  if (!stmt.step()) return std::nullopt;
  std::vector<SessionRecord> one{Impl::sessionFromRow(stmt)};
  impl_->loadItems(&one);
  tx.commit();
  return one.front();
}

std::vector<SceneSummary> Store::summaries(const std::string& user) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Transaction tx(*impl_, false);
  Impl::Statement stmt(*impl_,
                       "SELECT s.scene, count(*), max(s.total) FROM sessions s JOIN users u ON u.id = s.user_id "
                       "WHERE (?1 = '' OR u.name = ?1) GROUP BY s.scene ORDER BY s.scene");
  stmt.text(1, user);
  std::vector<SceneSummary> summaries;
  while (stmt.step()) {
    SceneSummary summary;
    summary.scene = stmt.textAt(0);
    summary.sessions = static_cast<int>(stmt.integerAt(1));
    summary.best = stmt.realAt(2);
    summaries.push_back(summary);
  }
  // "last" is the latest session in input time, the same order sessions() lists them in.
  Impl::Statement last(*impl_,
                       "SELECT s.total, s.recorded_at FROM sessions s JOIN users u ON u.id = s.user_id "
                       "WHERE (?1 = '' OR u.name = ?1) AND s.scene = ?2 ORDER BY s.start_stamp DESC, s.id DESC "
                       "LIMIT 1");
  for (auto& summary : summaries) {
    last.reset();
    last.text(1, user).text(2, summary.scene);
    if (last.step()) {
      summary.last = last.realAt(0);
      summary.last_recorded_at = last.textAt(1);
    }
  }
  tx.commit();
  return summaries;
}

void Store::annotate(std::int64_t session_id, const std::string& text) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Statement stmt(*impl_, "UPDATE sessions SET annotation = ?2 WHERE id = ?1");
  stmt.integer(1, session_id).text(2, text);
  stmt.step();
  if (sqlite3_changes(impl_->db) == 0) {
    throw StoreError(impl_->path + ": no session " + std::to_string(session_id) + " to annotate");
  }
}

void Store::assignCourse(const CourseAssignment& assignment) {
  if (isBlank(assignment.course_name) || isBlank(assignment.course_text)) {
    throw StoreError(impl_->path + ": a course assignment needs the course's name and text");
  }
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Transaction tx(*impl_, true);
  auto idWithRole = [&](const std::string& name, Role role) {
    Impl::Statement stmt(*impl_, "SELECT id, role FROM users WHERE name = ?1");
    stmt.text(1, name);
    if (!stmt.step()) throw StoreError(impl_->path + ": no user \"" + name + "\"");
    if (roleFromString(stmt.textAt(1)) != role) {
      throw StoreError(impl_->path + ": \"" + name + "\" is not " + (role == Role::kTrainee ? "a " : "an ") +
                       toString(role));
    }
    return stmt.integerAt(0);
  };
  const std::int64_t trainee = idWithRole(assignment.user, Role::kTrainee);
  const std::int64_t instructor = idWithRole(assignment.assigned_by, Role::kInstructor);
  Impl::Statement stmt(*impl_,
                       "INSERT OR REPLACE INTO course_assignments (user_id, course_name, course_file, course_text, "
                       "assigned_by, assigned_at) VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
  stmt.integer(1, trainee)
      .text(2, assignment.course_name)
      .text(3, assignment.course_file)
      .text(4, assignment.course_text)
      .integer(5, instructor)
      .text(6, assignment.assigned_at.empty() ? nowIso8601() : assignment.assigned_at);
  stmt.step();
  tx.commit();
}

std::optional<CourseAssignment> Store::courseAssignment(const std::string& trainee) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Statement stmt(*impl_,
                       "SELECT u.name, c.course_name, c.course_file, c.course_text, coalesce(i.name, ''), "
                       "c.assigned_at FROM course_assignments c JOIN users u ON u.id = c.user_id "
                       "LEFT JOIN users i ON i.id = c.assigned_by WHERE u.name = ?1");
  stmt.text(1, trainee);
  if (!stmt.step()) return std::nullopt;
  return CourseAssignment{stmt.textAt(0), stmt.textAt(1), stmt.textAt(2),
                          stmt.textAt(3), stmt.textAt(4), stmt.textAt(5)};
}

std::vector<SessionRecord> Store::unsyncedSessions(std::int64_t after_id, std::size_t limit) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Transaction tx(*impl_, false);
  Impl::Statement stmt(
      *impl_,
      (std::string(Impl::kSessionColumns) + "WHERE s.synced_at IS NULL AND s.id > ?2 ORDER BY s.id LIMIT ?1").c_str());
  stmt.integer(1, static_cast<std::int64_t>(std::min<std::size_t>(limit, std::numeric_limits<std::int64_t>::max())))
      .integer(2, after_id);
  std::vector<SessionRecord> sessions;
  while (stmt.step()) sessions.push_back(Impl::sessionFromRow(stmt));
  impl_->loadItems(&sessions);
  for (SessionRecord& s : sessions) s.trajectory = impl_->loadTrajectory(s.id);
  tx.commit();
  return sessions;
}

std::vector<TrajectorySample> Store::trajectory(std::int64_t session_id) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->loadTrajectory(session_id);
}

std::int64_t Store::unsyncedCount() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Statement stmt(*impl_, "SELECT count(*) FROM sessions WHERE synced_at IS NULL");
  return stmt.step() ? stmt.integerAt(0) : 0;
}

void Store::markSynced(const std::vector<std::string>& global_keys) {
  if (global_keys.empty()) return;
  const std::string now = nowIso8601();
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Transaction tx(*impl_, true);
  Impl::Statement stmt(*impl_, "UPDATE sessions SET synced_at = ?2 WHERE global_key = ?1 AND synced_at IS NULL");
  for (const std::string& key : global_keys) {
    stmt.reset();
    stmt.text(1, key).text(2, now);
    stmt.step();
  }
  tx.commit();
}

int Store::applyServerUsers(const std::vector<ServerUser>& server_users) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Transaction tx(*impl_, true);
  int changed = 0;
  std::vector<std::string> listed;
  const auto removeUser = [&](std::int64_t id) {
    // Deletion on request reaches every station: the user's sessions (items, groups, events by cascade) and course.
    for (const char* sql :
         {"DELETE FROM sessions WHERE user_id = ?1", "DELETE FROM course_assignments WHERE user_id = ?1",
          "UPDATE course_assignments SET assigned_by = NULL WHERE assigned_by = ?1",
          "DELETE FROM users WHERE id = ?1"}) {
      Impl::Statement stmt(*impl_, sql);
      stmt.integer(1, id);
      stmt.step();
    }
    ++changed;
  };
  for (const ServerUser& user : server_users) {
    if (user.name == kGuest) continue;
    listed.push_back(user.name);
    Impl::Statement find(*impl_, "SELECT id, role, origin FROM users WHERE name = ?1");
    find.text(1, user.name);
    const bool exists = find.step();
    const std::int64_t id = exists ? find.integerAt(0) : 0;
    if (user.deleted || user.role == "admin") {
      if (exists && (user.deleted || find.textAt(2) == "server")) removeUser(id);
      continue;
    }
    if (user.role != "trainee" && user.role != "instructor") continue;
    if (!exists) {
      Impl::Statement insert(*impl_,
                             "INSERT INTO users (name, role, iterations, created_at, origin) "
                             "VALUES (?1, ?2, 0, ?3, 'server')");
      insert.text(1, user.name).text(2, user.role).text(3, nowIso8601());
      insert.step();
      ++changed;
    } else if (find.textAt(1) != user.role || find.textAt(2) != "server") {
      Impl::Statement update(*impl_, "UPDATE users SET role = ?2, origin = 'server' WHERE id = ?1");
      update.integer(1, id).text(2, user.role);
      update.step();
      ++changed;
    }
  }
  // A server user that is not listed at all (a server restored from an old backup, or another server by mistake) is
  // not a deletion — only a tombstone is: the user becomes this station's own again, keeping their sessions, which
  // stay here until a server knows them.
  Impl::Statement server_users_here(*impl_, "SELECT id, name FROM users WHERE origin = 'server'");
  std::vector<std::int64_t> unlisted;
  while (server_users_here.step()) {
    if (std::find(listed.begin(), listed.end(), server_users_here.textAt(1)) == listed.end()) {
      unlisted.push_back(server_users_here.integerAt(0));
    }
  }
  Impl::Statement demote(*impl_, "UPDATE users SET origin = 'local' WHERE id = ?1");
  for (const std::int64_t id : unlisted) {
    demote.reset();
    demote.integer(1, id);
    demote.step();
    ++changed;
  }
  tx.commit();
  return changed;
}

int Store::attachTrajectories(const std::string& recorded_since, std::vector<std::string>* errors) {
  struct Candidate {
    std::int64_t id;
    std::vector<std::string> files;
  };
  std::vector<Candidate> candidates;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    Impl::Statement stmt(*impl_,
                         "SELECT s.id, s.bag_path, s.result_path FROM sessions s WHERE s.bag_path <> '' AND "
                         "(s.synced_at IS NULL OR s.recorded_at >= ?1) AND NOT EXISTS "
                         "(SELECT 1 FROM trajectory_samples t WHERE t.session_id = s.id)");
    stmt.text(1, recorded_since);
    while (stmt.step()) {
      Candidate c{stmt.integerAt(0), {}};
      const fs::path bag(stmt.textAt(1));
      c.files.push_back((bag.parent_path() / (bag.stem().string() + ".trajectory.json")).string());
      if (!stmt.textAt(2).empty()) c.files.push_back(trajectoryPathFor(stmt.textAt(2)));
      candidates.push_back(std::move(c));
    }
  }
  int attached = 0;
  for (const Candidate& c : candidates) {
    for (const std::string& file : c.files) {
      std::error_code ec;
      if (!fs::exists(file, ec)) continue;
      std::vector<TrajectorySample> trajectory;
      try {
        std::ifstream in(file, std::ios::binary);
        std::ostringstream text;
        text << in.rdbuf();
        trajectory = parseTrajectoryJson(text.str(), file);
      } catch (const StoreError& e) {
        if (errors != nullptr) errors->push_back(e.what());
        break;
      }
      std::lock_guard<std::mutex> lock(impl_->mutex);
      Impl::Transaction tx(*impl_, true);
      impl_->insertTrajectory(c.id, trajectory);
      Impl::Statement outbox(*impl_, "UPDATE sessions SET synced_at = NULL WHERE id = ?1");
      outbox.integer(1, c.id);
      outbox.step();
      tx.commit();
      ++attached;
      break;
    }
  }
  return attached;
}

void Store::applyServerAssignment(const CourseAssignment& assignment) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl::Transaction tx(*impl_, true);
  const std::optional<std::int64_t> trainee = impl_->userId(assignment.user);
  if (!trainee) throw StoreError(impl_->path + ": no user \"" + assignment.user + "\" for the server's course");
  const std::optional<std::int64_t> instructor = impl_->userId(assignment.assigned_by);
  Impl::Statement stmt(*impl_,
                       "INSERT OR REPLACE INTO course_assignments (user_id, course_name, course_file, course_text, "
                       "assigned_by, assigned_at) VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
  stmt.integer(1, *trainee)
      .text(2, assignment.course_name)
      .text(3, assignment.course_file)
      .text(4, assignment.course_text)
      .text(6, assignment.assigned_at.empty() ? nowIso8601() : assignment.assigned_at);
  if (instructor) {
    stmt.integer(5, *instructor);
  } else {
    stmt.null(5);
  }
  stmt.step();
  tx.commit();
}

void Store::exportCsv(std::ostream& out, const SessionFilter& filter) const {
  writeCsvRow(out, {"session_id", "user", "scene", "scenario", "difficulty", "seed", "state", "passed", "total",
                    "elapsed", "recorded_at", "bag", "item", "value", "unit", "weight", "points"});
  for (const SessionRecord& s : sessions(filter)) {
    const std::vector<std::string> session_fields{std::to_string(s.id),
                                                  s.user,
                                                  s.scene,
                                                  s.scenario,
                                                  s.difficulty,
                                                  std::to_string(s.seed),
                                                  s.state,
                                                  s.passed ? "1" : "0",
                                                  formatNumber(s.total),
                                                  formatNumber(s.elapsed),
                                                  s.recorded_at,
                                                  s.bag_path};
    if (s.items.empty()) {
      // A session without items (no scenario) still appears in the export.
      std::vector<std::string> row = session_fields;
      row.insert(row.end(), 5, "");
      writeCsvRow(out, row);
    }
    for (const ScoreItemRecord& item : s.items) {
      std::vector<std::string> row = session_fields;
      row.insert(row.end(), {item.name, formatNumber(item.value), item.unit, formatNumber(item.weight),
                             formatNumber(item.points)});
      writeCsvRow(out, row);
    }
  }
  if (!out) throw StoreError(impl_->path + ": writing the CSV export failed");
}

namespace {

const std::vector<std::string> kCsvSessionColumns{"session_id", "user",   "scene", "scenario", "difficulty",  "seed",
                                                  "state",      "passed", "total", "elapsed",  "recorded_at", "bag"};

std::vector<std::string> csvSessionFields(const SessionRecord& s) {
  return {std::to_string(s.id),
          s.user,
          s.scene,
          s.scenario,
          s.difficulty,
          std::to_string(s.seed),
          s.state,
          s.passed ? "1" : "0",
          formatNumber(s.total),
          formatNumber(s.elapsed),
          s.recorded_at,
          s.bag_path};
}

// The session columns, then `columns`; one line per row `rows_of` gives, or one line with those fields empty.
void writeSessionRowsCsv(std::ostream& out, const std::vector<SessionRecord>& sessions,
                         const std::vector<std::string>& columns,
                         const std::function<std::vector<std::vector<std::string>>(const SessionRecord&)>& rows_of) {
  std::vector<std::string> header = kCsvSessionColumns;
  header.insert(header.end(), columns.begin(), columns.end());
  writeCsvRow(out, header);
  for (const SessionRecord& s : sessions) {
    std::vector<std::vector<std::string>> rows = rows_of(s);
    if (rows.empty()) rows.emplace_back(columns.size(), "");
    for (const std::vector<std::string>& fields : rows) {
      std::vector<std::string> row = csvSessionFields(s);
      row.insert(row.end(), fields.begin(), fields.end());
      writeCsvRow(out, row);
    }
  }
}

std::string csvNumberOrEmpty(double value) { return std::isfinite(value) ? formatNumber(value) : ""; }

}  // namespace

void Store::exportGroupsCsv(std::ostream& out, const SessionFilter& filter) const {
  writeSessionRowsCsv(out, sessions(filter), {"group", "points", "weight"}, [](const SessionRecord& s) {
    std::vector<std::vector<std::string>> rows;
    for (const GroupRecord& g : s.groups) rows.push_back({g.name, formatNumber(g.points), formatNumber(g.weight)});
    return rows;
  });
  if (!out) throw StoreError(impl_->path + ": writing the CSV export failed");
}

void Store::exportEventsCsv(std::ostream& out, const SessionFilter& filter) const {
  writeSessionRowsCsv(
      out, sessions(filter), {"event_time", "kind", "item", "slot", "instrument", "x", "y", "z", "event_points"},
      [](const SessionRecord& s) {
        std::vector<std::vector<std::string>> rows;
        for (const PenaltyEventRecord& e : s.events) {
          rows.push_back({formatNumber(e.time), e.kind, e.item, e.slot, e.instrument, csvNumberOrEmpty(e.position[0]),
                          csvNumberOrEmpty(e.position[1]), csvNumberOrEmpty(e.position[2]), formatNumber(e.points)});
        }
        return rows;
      });
  if (!out) throw StoreError(impl_->path + ": writing the CSV export failed");
}

}  // namespace eyesi_gui::records
