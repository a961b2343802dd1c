// The training-records store without ROS: users and PINs, migrations, sessions, imports of real scenario results,
// concurrency, damaged files, the CSV export and the command-line tool.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>
#include <thread>

#include "eyesi_gui/records/centre.h"
#include "eyesi_gui/records/csv.h"
#include "eyesi_gui/records/schema.h"
#include "eyesi_gui/records/store.h"

namespace eyesi_gui::records {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    std::string pattern = testing::TempDir() + "eyesi_records_XXXXXX";
    if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string readBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

// Compares without printing two whole database files when they differ.
::testing::AssertionResult sameBytes(const std::string& actual, const std::string& expected) {
  if (actual == expected) return ::testing::AssertionSuccess();
  std::size_t first = 0;
  while (first < actual.size() && first < expected.size() && actual[first] == expected[first]) ++first;
  return ::testing::AssertionFailure() << "sizes " << actual.size() << " vs " << expected.size()
                                       << ", first difference at byte " << first;
}

void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
}

// A plain sqlite3 connection, to look at what the store wrote (or to write what an older release wrote).
class RawDb {
 public:
  explicit RawDb(const std::string& path) {
    if (sqlite3_open(path.c_str(), &db_) != SQLITE_OK) throw std::runtime_error(sqlite3_errmsg(db_));
    sqlite3_busy_timeout(db_, 5000);
  }
  ~RawDb() { sqlite3_close(db_); }
  void exec(const std::string& sql) {
    char* error = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
      const std::string message = error ? error : "?";
      sqlite3_free(error);
      throw std::runtime_error(message + " in: " + sql);
    }
  }
  // Every column of every row as text (blobs as their raw bytes).
  std::vector<std::vector<std::string>> rows(const std::string& sql) {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK) {
      throw std::runtime_error(sqlite3_errmsg(db_));
    }
    std::vector<std::vector<std::string>> result;
    int rc;
    while ((rc = sqlite3_step(stmt)) == SQLITE_ROW) {
      std::vector<std::string> row;
      for (int c = 0; c < sqlite3_column_count(stmt); ++c) {
        const auto* data = static_cast<const char*>(sqlite3_column_blob(stmt, c));
        row.emplace_back(data ? std::string(data, sqlite3_column_bytes(stmt, c)) : "");
      }
      result.push_back(row);
    }
    sqlite3_finalize(stmt);
    if (rc != SQLITE_DONE) throw std::runtime_error(sqlite3_errmsg(db_));
    return result;
  }
  std::string value(const std::string& sql) {
    const auto result = rows(sql);
    return result.empty() || result[0].empty() ? "" : result[0][0];
  }

 private:
  sqlite3* db_ = nullptr;
};

// Fails unless `action` throws a StoreError whose what() contains every one of `parts`.
void expectStoreError(const std::function<void()>& action, const std::vector<std::string>& parts,
                      StoreError* caught = nullptr) {
  try {
    action();
    ADD_FAILURE() << "no StoreError";
  } catch (const StoreError& e) {
    for (const auto& part : parts) EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    if (caught) *caught = e;
  }
}

SessionRecord makeSession(const std::string& user, const std::string& scene, double start, double total) {
  SessionRecord s;
  s.user = user;
  s.scene = scene;
  s.scenario = scene;
  s.difficulty = "medium";
  s.seed = 7;
  s.state = total >= 50 ? "finished" : "failed";
  s.passed = s.state == "finished";
  s.message = "done";
  s.total = total;
  s.elapsed = 12.5;
  s.start_stamp = start;
  s.end_stamp = start + 12.5;
  s.final_state_hash = "0x" + std::to_string(static_cast<long long>(start * 1000));
  s.frames = 700;
  s.items = {{"completed", 1, "", 3, 100}, {"time", 12.5, "s", 1, 80}};
  return s;
}

// A database of several pages (long messages), closed so the WAL is checkpointed into the file.
void fillDatabase(const std::string& path, int sessions) {
  Store store(path);
  for (int i = 0; i < sessions; ++i) {
    SessionRecord s = makeSession("anna", "navigation", 1000 + i, 50 + i % 50);
    s.message = std::string(400, static_cast<char>('a' + i % 26));
    store.recordSession(s);
  }
}

std::vector<std::vector<std::string>> parseCsv(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> row;
  std::string field;
  bool quoted = false, in_row = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c != '"') {
        field += c;
      } else if (i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        ++i;
      } else {
        quoted = false;
      }
      continue;
    }
    in_row = true;
    if (c == '"' && field.empty()) {
      quoted = true;
    } else if (c == ',') {
      row.push_back(field);
      field.clear();
    } else if (c == '\r' || c == '\n') {
      if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
      row.push_back(field);
      rows.push_back(row);
      row.clear();
      field.clear();
      in_row = false;
    } else {
      field += c;
    }
  }
  if (in_row) {
    row.push_back(field);
    rows.push_back(row);
  }
  return rows;
}

std::vector<std::string> referenceResults() {
  std::vector<std::string> files = Store::findResultFiles(EYESI_TEST_BAGS);
  return files;
}

TEST(RecordsUsers, PinsAreSaltedHashesAndGuestAlwaysExists) {
  TempDir dir;
  const std::string path = dir.file("records.sqlite");
  {
    Store store(path);
    ASSERT_EQ(store.users().size(), 1u);
    EXPECT_EQ(store.users()[0].name, "guest");
    EXPECT_EQ(store.users()[0].role, Role::kTrainee);
    EXPECT_FALSE(store.users()[0].has_pin);
    EXPECT_TRUE(store.checkPin("guest", "anything"));
    EXPECT_TRUE(store.checkPin("guest", ""));

    const User anna = store.addUser("anna", Role::kTrainee, "482915");
    EXPECT_GT(anna.id, 0);
    EXPECT_TRUE(anna.has_pin);
    const User doc = store.addUser("dr. who", Role::kInstructor, "482915");
    EXPECT_EQ(doc.role, Role::kInstructor);
    EXPECT_TRUE(store.checkPin("anna", "482915"));
    EXPECT_FALSE(store.checkPin("anna", "482916"));
    EXPECT_FALSE(store.checkPin("anna", ""));
    EXPECT_FALSE(store.checkPin("nobody", "482915"));
    EXPECT_TRUE(store.checkPin("dr. who", "482915"));

    expectStoreError([&] { store.addUser("anna", Role::kInstructor, "1"); }, {"anna", "already exists"});
    expectStoreError([&] { store.addUser("guest", Role::kTrainee, ""); }, {"guest", "already exists"});
    expectStoreError([&] { store.addUser("", Role::kTrainee, "1"); }, {"name"});

    const auto found = store.findUser("dr. who");
    ASSERT_TRUE(found.has_value());
    EXPECT_EQ(found->id, doc.id);
    EXPECT_EQ(found->role, Role::kInstructor);
    EXPECT_FALSE(store.findUser("nobody").has_value());
    EXPECT_EQ(store.users().size(), 3u);

    // A PIN-less user (as an import creates them) accepts only the empty PIN, until one is set.
    store.addUser("ben", Role::kTrainee, "");
    EXPECT_TRUE(store.checkPin("ben", ""));
    EXPECT_FALSE(store.checkPin("ben", "0000"));
    store.setPin("ben", "2468");
    EXPECT_TRUE(store.checkPin("ben", "2468"));
    EXPECT_FALSE(store.checkPin("ben", ""));
    expectStoreError([&] { store.setPin("guest", "1"); }, {"guest"});
    expectStoreError([&] { store.setPin("nobody", "1"); }, {"nobody"});

    // Neither the file nor its WAL holds the PIN in plain text, in any encoding a column could use.
    for (const std::string& file : {path, path + "-wal"}) {
      EXPECT_EQ(readBytes(file).find("482915"), std::string::npos) << file;
    }
  }
  RawDb raw(path);
  const auto rows = raw.rows(
      "SELECT name, pin_salt, pin_hash, iterations, hex(pin_hash), created_at FROM users "
      "WHERE name IN ('anna', 'dr. who') ORDER BY name");
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& row : rows) {
    EXPECT_EQ(row[1].size(), 16u);
    EXPECT_EQ(row[2].size(), 32u);
    EXPECT_EQ(row[3], "100000");
    for (const auto& column : row) EXPECT_EQ(column.find("482915"), std::string::npos) << row[0];
  }
  // Same PIN, different salts: different hashes.
  EXPECT_NE(rows[0][1], rows[1][1]);
  EXPECT_NE(rows[0][2], rows[1][2]);
  EXPECT_EQ(raw.value("SELECT pin_hash IS NULL FROM users WHERE name = 'guest'"), "1");
}

TEST(RecordsSchema, MigratesAnEmptyFileToTheCurrentVersion) {
  TempDir dir;
  const std::string path = dir.file("empty.sqlite");
  writeBytes(path, "");
  {
    Store store(path);
    EXPECT_EQ(store.schemaVersion(), Store::kSchemaVersion);
    EXPECT_EQ(store.path(), path);
  }
  RawDb raw(path);
  EXPECT_EQ(raw.value("PRAGMA user_version"), std::to_string(Store::kSchemaVersion));
  EXPECT_EQ(raw.value("PRAGMA journal_mode"), "wal");
  EXPECT_EQ(raw.value("SELECT count(*) FROM pragma_table_info('sessions') WHERE name IN ('annotation', 'station')"),
            "2");
  EXPECT_EQ(raw.value("SELECT count(*) FROM sqlite_master WHERE name = 'sessions_user_scene'"), "1");
  EXPECT_EQ(raw.value("SELECT role FROM users WHERE name = 'guest'"), "trainee");
}

TEST(RecordsSchema, CreatesMissingFoldersAndFile) {
  TempDir dir;
  const std::string path = dir.file("a/b/records.sqlite");
  Store store(path);
  EXPECT_TRUE(fs::exists(path));
  EXPECT_EQ(store.schemaVersion(), Store::kSchemaVersion);
}

// Permission bits of a file or folder (0777 part).
unsigned modeOf(const std::string& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) return 01000;  // "missing": never equal to a permission set
  return info.st_mode & 0777;
}

// SECURITY.md: the records (names, scores, PIN hashes) are readable by their owner only, whatever the umask.
TEST(RecordsPermissions, NewDatabaseItsWalAndShmAndNewFoldersAreOwnerOnly) {
  TempDir dir;
  struct Umask {  // the usual umask: SQLite alone would create 0644 files
    mode_t previous = ::umask(022);
    ~Umask() { ::umask(previous); }
  } umask_022;
  const std::string path = dir.file("eyesi/sessions/records.sqlite");
  {
    Store store(path);
    store.addUser("anna", Role::kTrainee, "482915");
    // Open connection after a write: the WAL and the shared-memory index exist now.
    ASSERT_TRUE(fs::exists(path + "-wal"));
    ASSERT_TRUE(fs::exists(path + "-shm"));
    EXPECT_EQ(modeOf(path), 0600u) << std::oct << modeOf(path);
    EXPECT_EQ(modeOf(path + "-wal"), 0600u) << std::oct << modeOf(path + "-wal");
    EXPECT_EQ(modeOf(path + "-shm"), 0600u) << std::oct << modeOf(path + "-shm");
  }
  EXPECT_EQ(modeOf(path), 0600u);
  EXPECT_EQ(modeOf(dir.file("eyesi")), 0700u) << std::oct << modeOf(dir.file("eyesi"));
  EXPECT_EQ(modeOf(dir.file("eyesi/sessions")), 0700u);
}

TEST(RecordsPermissions, AnOlderWorldReadableDatabaseIsTightenedAndAnExistingFolderKept) {
  TempDir dir;
  const std::string path = dir.file("records.sqlite");
  { Store store(path); }
  ASSERT_EQ(::chmod(path.c_str(), 0644), 0);
  ASSERT_EQ(::chmod(dir.path().c_str(), 0755), 0);
  {
    Store store(path);
    store.addUser("ben", Role::kTrainee, "2468");
    EXPECT_EQ(modeOf(path), 0600u) << std::oct << modeOf(path);
    EXPECT_EQ(modeOf(path + "-wal"), 0600u);
    EXPECT_EQ(modeOf(path + "-shm"), 0600u);
  }
  EXPECT_EQ(modeOf(dir.path().string()), 0755u);  // a folder the store did not create is not its to change
}

TEST(RecordsSchema, MigratesVersion1KeepingTheRows) {
  TempDir dir;
  const std::string path = dir.file("v1.sqlite");
  SessionRecord old = makeSession("bob", "vitrectomy", 500.25, 66.5);
  {
    // Exactly what the version-1 release left on disk (rollback journal, no annotation/station columns).
    RawDb raw(path);
    raw.exec(std::string("BEGIN;") + migrationSql(1) + "PRAGMA user_version = 1; COMMIT;");
    raw.exec(
        "INSERT INTO users (name, role, iterations, created_at) VALUES ('bob', 'trainee', 0, '2025-01-01T00:00:00Z')");
    raw.exec(
        "INSERT INTO sessions (session_key, user_id, scene, scenario, difficulty, seed, state, message, total, "
        "passed, elapsed, start_stamp, end_stamp, recorded_at, bag_path, result_path, software_version, "
        "final_state_hash, frames) SELECT '" +
        sessionKey(old) +
        "', id, 'vitrectomy', 'vitrectomy', 'medium', 7, 'finished', 'done', 66.5, 1, 12.5, 500.25, 512.75, "
        "'2025-01-02T03:04:05Z', '/b.bag', '/b.result.json', 'vrm_sim 0.0.9', '" +
        old.final_state_hash + "', 700 FROM users WHERE name = 'bob'");
    raw.exec("INSERT INTO score_items SELECT id, 0, 'completed', 1, '', 3, 100 FROM sessions");
    raw.exec("INSERT INTO score_items SELECT id, 1, 'time', 12.5, 's', 1, 80 FROM sessions");
    ASSERT_EQ(raw.value("PRAGMA user_version"), "1");
  }
  Store store(path);
  EXPECT_EQ(store.schemaVersion(), Store::kSchemaVersion);
  const auto sessions = store.sessions();
  ASSERT_EQ(sessions.size(), 1u);
  const SessionRecord& s = sessions[0];
  EXPECT_EQ(s.user, "bob");
  EXPECT_EQ(s.scene, "vitrectomy");
  EXPECT_DOUBLE_EQ(s.total, 66.5);
  EXPECT_TRUE(s.passed);
  EXPECT_EQ(s.recorded_at, "2025-01-02T03:04:05Z");
  EXPECT_EQ(s.bag_path, "/b.bag");
  EXPECT_EQ(s.software_version, "vrm_sim 0.0.9");
  EXPECT_EQ(s.frames, 700u);
  EXPECT_EQ(s.annotation, "");
  EXPECT_EQ(s.station, "");
  ASSERT_EQ(s.items.size(), 2u);
  EXPECT_EQ(s.items[0].name, "completed");
  EXPECT_EQ(s.items[1].name, "time");
  EXPECT_DOUBLE_EQ(s.items[1].points, 80);

  // The migrated row keeps its identity: recording the same session again finds it.
  const ImportResult again = store.recordSession(old);
  EXPECT_FALSE(again.inserted);
  EXPECT_EQ(again.session_id, s.id);
  store.annotate(s.id, "steady hands");
  EXPECT_EQ(store.session(s.id)->annotation, "steady hands");
  expectStoreError([&] { store.annotate(s.id + 100, "x"); }, {"no session"});

  RawDb raw(path);
  EXPECT_EQ(raw.value("PRAGMA user_version"), std::to_string(Store::kSchemaVersion));
  EXPECT_EQ(raw.value("SELECT count(*) FROM sqlite_master WHERE name = 'sessions_user_scene'"), "1");
}

TEST(RecordsSchema, RefusesANewerSchemaAndForeignDatabases) {
  TempDir dir;
  const std::string newer = dir.file("newer.sqlite");
  { Store store(newer); }
  RawDb(newer).exec("PRAGMA user_version = " + std::to_string(Store::kSchemaVersion + 1));
  expectStoreError([&] { Store store(newer); }, {newer, "newer"});

  const std::string foreign = dir.file("foreign.sqlite");
  RawDb(foreign).exec("CREATE TABLE notes (x TEXT); INSERT INTO notes VALUES ('keep me')");
  const std::string before = readBytes(foreign);
  expectStoreError([&] { Store store(foreign); }, {foreign});
  EXPECT_TRUE(sameBytes(readBytes(foreign), before));
}

TEST(RecordsSessions, RecordsAndReadsBackEveryFieldAndTheItemsInOrder) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  SessionRecord s = makeSession("carla", "membrane_peeling", 1700000000.5, 81.5);
  s.items = {{"zeta", 3, "1", 2, 50}, {"alpha", 0.25, "m", 1, 100}, {"mid", -1, "", 0, 0}};
  s.bag_path = "/root/s.bag";
  s.software_version = "vrm_sim 0.1.0";
  s.station = "sim1";
  s.recorded_at = "2026-01-02T03:04:05Z";
  const ImportResult first = store.recordSession(s);
  EXPECT_TRUE(first.inserted);
  EXPECT_GT(first.session_id, 0);

  // The unknown user was created as a PIN-less trainee rather than the session dropped.
  const auto carla = store.findUser("carla");
  ASSERT_TRUE(carla.has_value());
  EXPECT_EQ(carla->role, Role::kTrainee);
  EXPECT_FALSE(carla->has_pin);

  const auto back = store.session(first.session_id);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->id, first.session_id);
  EXPECT_EQ(back->user, "carla");
  EXPECT_EQ(back->scene, "membrane_peeling");
  EXPECT_EQ(back->seed, 7u);
  EXPECT_EQ(back->state, "finished");
  EXPECT_TRUE(back->passed);
  EXPECT_EQ(back->message, "done");
  EXPECT_DOUBLE_EQ(back->total, 81.5);
  EXPECT_DOUBLE_EQ(back->start_stamp, 1700000000.5);
  EXPECT_DOUBLE_EQ(back->end_stamp, 1700000013.0);
  EXPECT_EQ(back->recorded_at, "2026-01-02T03:04:05Z");
  EXPECT_EQ(back->bag_path, "/root/s.bag");
  EXPECT_EQ(back->station, "sim1");
  EXPECT_EQ(back->final_state_hash, s.final_state_hash);
  ASSERT_EQ(back->items.size(), 3u);
  EXPECT_EQ(back->items[0].name, "zeta");
  EXPECT_EQ(back->items[1].name, "alpha");
  EXPECT_EQ(back->items[2].name, "mid");
  EXPECT_DOUBLE_EQ(back->items[1].value, 0.25);
  EXPECT_EQ(back->items[1].unit, "m");
  EXPECT_DOUBLE_EQ(back->items[0].weight, 2);
  EXPECT_DOUBLE_EQ(back->items[0].points, 50);
  EXPECT_DOUBLE_EQ(back->items[2].value, -1);
  EXPECT_FALSE(store.session(first.session_id + 1).has_value());

  // A second, older session: sessions() lists by start stamp, not by insertion.
  SessionRecord earlier = makeSession("", "navigation", 1600000000, 40);
  const ImportResult second = store.recordSession(earlier);
  ASSERT_TRUE(second.inserted);
  const auto all = store.sessions();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].id, second.session_id);
  EXPECT_EQ(all[0].user, "guest");
  EXPECT_EQ(all[0].recorded_at.size(), 20u);  // written now, ISO-8601 UTC
  EXPECT_EQ(all[0].recorded_at.back(), 'Z');
  EXPECT_EQ(all[1].id, first.session_id);
  EXPECT_EQ(all[1].items.size(), 3u);
  EXPECT_EQ(store.sessions({"carla", ""}).size(), 1u);
  EXPECT_EQ(store.sessions({"", "navigation"}).size(), 1u);
  EXPECT_EQ(store.sessions({"carla", "navigation"}).size(), 0u);
}

TEST(RecordsImport, SameResultFileTwiceGivesOneRow) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  const std::string result = dir.file("anna.result.json");
  writeBytes(result,
             R"({"scene": "membrane_peeling", "scene_file": "/x/membrane_peeling.yaml", "scenario": "membrane_peeling",
  "difficulty": "medium", "seed": 1, "state": "finished", "session_ended": true, "timed_out": false,
  "message": "membrane peeled", "start_stamp": 1700000000.5, "end_stamp": 1700000020.1, "elapsed": 19.6,
  "total": 81.5, "items": [{"name": "completed", "value": 1, "unit": "", "weight": 3, "points": 1},
  {"name": "time", "value": 19.6, "unit": "s", "weight": 1, "points": 0.93}], "final_state_hash": "9f86d081884c7d65",
  "frames": 1000, "simulated_frames": 980, "late_inputs": 0, "last_frame_stamp": 1700000020.1,
  "software_version": "vrm_sim 0.1.0", "bag": "/root/s.bag", "user": "anna", "station": "sim1"})");
  const ImportResult first = store.importResultFile(result);
  const ImportResult second = store.importResultFile(result);
  EXPECT_TRUE(first.inserted);
  EXPECT_FALSE(second.inserted);
  EXPECT_EQ(second.session_id, first.session_id);
  // The same result arriving live (session_result topic) is the same session too.
  const ImportResult live = store.importResultJson(readBytes(result), "session_result");
  EXPECT_FALSE(live.inserted);
  EXPECT_EQ(live.session_id, first.session_id);

  const auto sessions = store.sessions();
  ASSERT_EQ(sessions.size(), 1u);
  EXPECT_EQ(sessions[0].user, "anna");
  EXPECT_EQ(sessions[0].station, "sim1");
  EXPECT_TRUE(sessions[0].passed);
  EXPECT_EQ(sessions[0].message, "membrane peeled");
  EXPECT_EQ(sessions[0].result_path, result);
  EXPECT_EQ(sessions[0].frames, 1000u);
  ASSERT_EQ(sessions[0].items.size(), 2u);
  EXPECT_DOUBLE_EQ(sessions[0].items[1].points, 0.93);
  RawDb raw(dir.file("r.sqlite"));
  EXPECT_EQ(raw.value("SELECT count(*) FROM sessions"), "1");
  EXPECT_EQ(raw.value("SELECT count(*) FROM score_items"), "2");
}

// The station's graph serves many sessions, so the live text names neither the session's trainee nor its bag: the
// console passes both, and the same session imported later from the station's result file stays one row.
TEST(RecordsImport, LiveResultTakesTheSessionsUserAndBag) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  const std::string live_text =
      R"({"scene": "navigation", "scenario": "navigation", "difficulty": "easy", "seed": 7, "state": "finished",
  "start_stamp": 1700000000.5, "end_stamp": 1700000010.25, "total": 50, "final_state_hash": "ab12", "frames": 500,
  "bag": null, "user": null, "station": "sim1"})";
  const ImportResult live = store.importResultJson(live_text, "session_result", "anna", "/records/s2.bag");
  ASSERT_TRUE(live.inserted);
  const std::string file = dir.file("s2.result.json");
  writeBytes(file, R"({"scene": "navigation", "scenario": "navigation", "difficulty": "easy", "seed": 7,
  "state": "finished", "start_stamp": 1700000000.5, "end_stamp": 1700000010.25, "total": 50,
  "final_state_hash": "ab12", "frames": 500, "bag": "/records/s2.bag", "user": "anna", "station": "sim1"})");
  const ImportResult from_file = store.importResultFile(file);
  EXPECT_FALSE(from_file.inserted);
  EXPECT_EQ(from_file.session_id, live.session_id);
  const auto sessions = store.sessions();
  ASSERT_EQ(sessions.size(), 1u);
  EXPECT_EQ(sessions[0].user, "anna");
  EXPECT_EQ(sessions[0].bag_path, "/records/s2.bag");
}

TEST(RecordsImport, ShippedReferenceResults) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  const std::vector<std::string> files = referenceResults();
  ASSERT_GE(files.size(), 3u) << EYESI_TEST_BAGS;
  for (const std::string& file : files) {
    SCOPED_TRACE(file);
    const auto expected = nlohmann::json::parse(readBytes(file));
    const ImportResult result = store.importResultFile(file, "tester");
    ASSERT_TRUE(result.inserted);
    const auto s = store.session(result.session_id);
    ASSERT_TRUE(s.has_value());
    EXPECT_EQ(s->user, "tester");
    EXPECT_EQ(s->scene, expected["scene"].get<std::string>());
    EXPECT_EQ(s->scenario, expected["scenario"].get<std::string>());
    EXPECT_EQ(s->state, expected["state"].get<std::string>());
    EXPECT_EQ(s->passed, expected["state"] == "finished");
    EXPECT_DOUBLE_EQ(s->total, expected["total"].get<double>());
    EXPECT_DOUBLE_EQ(s->start_stamp, expected["start_stamp"].get<double>());
    EXPECT_EQ(s->final_state_hash, expected["final_state_hash"].get<std::string>());
    EXPECT_EQ(s->frames, expected["frames"].get<std::uint64_t>());
    EXPECT_EQ(s->bag_path, expected["bag"].get<std::string>());
    EXPECT_EQ(s->result_path, fs::absolute(file).lexically_normal().string());
    ASSERT_EQ(s->items.size(), expected["items"].size());
    for (std::size_t i = 0; i < s->items.size(); ++i) {
      EXPECT_EQ(s->items[i].name, expected["items"][i]["name"].get<std::string>());
      EXPECT_DOUBLE_EQ(s->items[i].value, expected["items"][i]["value"].get<double>());
      EXPECT_DOUBLE_EQ(s->items[i].points, expected["items"][i]["points"].get<double>());
    }
  }
  EXPECT_EQ(store.sessions().size(), files.size());
}

TEST(RecordsImport, FolderReportsTheMalformedFileAndImportsTheOthers) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  const fs::path results = dir.path() / "usb";
  fs::create_directories(results / "day2");
  const auto references = referenceResults();
  ASSERT_GE(references.size(), 2u);
  fs::copy_file(references[0], results / "a.result.json");
  fs::copy_file(references[1], results / "day2" / "b.result.json");
  writeBytes((results / "day2" / "broken.result.json").string(), "{\"scene\": \"navigation\", \"total\": ");
  writeBytes((results / "notes.json").string(), "not a result, not looked at");
  std::vector<std::string> errors;
  const auto imported = store.importFolder(results.string(), &errors);
  EXPECT_EQ(imported.size(), 2u);
  for (const auto& r : imported) EXPECT_TRUE(r.inserted);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("broken.result.json"), std::string::npos) << errors[0];
  EXPECT_EQ(store.sessions().size(), 2u);
  EXPECT_EQ(Store::findResultFiles(results.string()).size(), 3u);
  expectStoreError([&] { store.importFolder(dir.file("missing")); }, {"missing"});
}

TEST(RecordsImport, MalformedResultsNameTheOriginAndTheField) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  const std::string file = dir.file("bad.result.json");
  writeBytes(file, "{\"scene\": \"navigation\",");
  expectStoreError([&] { store.importResultFile(file); }, {file, "malformed"});
  expectStoreError([&] { store.importResultFile(dir.file("absent.result.json")); }, {"absent.result.json"});
  expectStoreError([&] { store.importResultJson("[1, 2]", "station2"); }, {"station2", "not an object"});
  expectStoreError([&] { store.importResultJson(R"({"total": 3})", "station2"); }, {"station2", "scene"});
  expectStoreError([&] { store.importResultJson(R"({"scene": 4})", "o"); }, {"scene", "not a string"});
  // The simulator's required keys besides the scene (every writer version wrote them).
  expectStoreError([&] { store.importResultJson(R"({"scene": "n", "frames": 1})", "o"); },
                   {"final_state_hash", "missing"});
  expectStoreError([&] { store.importResultJson(R"({"scene": "n", "final_state_hash": "0x1"})", "o"); },
                   {"frames", "missing"});
  const auto with = [](const std::string& fields) {
    return R"({"scene": "n", "final_state_hash": "0x1", "frames": 1, )" + fields + "}";
  };
  expectStoreError([&] { store.importResultJson(with(R"("total": "high")"), "o"); }, {"total"});
  expectStoreError([&] { store.importResultJson(with(R"("seed": -1)"), "o"); }, {"seed"});
  expectStoreError([&] { store.importResultJson(with(R"("items": {})"), "o"); }, {"items"});
  expectStoreError([&] { store.importResultJson(with(R"("items": [{"name": "t", "value": "x"}])"), "o"); },
                   {"items[0].", "value"});
  EXPECT_TRUE(store.sessions().empty());

  // Nulls are "unknown", not errors; no scenario → no items; no user → guest.
  const ImportResult ok = store.importResultJson(
      R"({"scene": "free", "final_state_hash": "0x1", "frames": 1, "scenario": null, "seed": null, "state": "stopped",
          "total": null, "bag": null, "items": null, "user": ""})",
      "o");
  const auto s = store.session(ok.session_id);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->user, "guest");
  EXPECT_EQ(s->scenario, "");
  EXPECT_EQ(s->bag_path, "");
  EXPECT_EQ(s->total, 0.0);  // null: unknown, stored as 0 (the column is NOT NULL)
  EXPECT_FALSE(s->passed);
  EXPECT_TRUE(s->items.empty());
  EXPECT_EQ(s->result_path, "");
}

TEST(RecordsConcurrency, AReaderSeesConsistentSnapshotsWhileAWriterWrites) {
  TempDir dir;
  const std::string path = dir.file("r.sqlite");
  Store writer(path);
  Store reader(path);
  constexpr int kSessions = 200;
  std::atomic<bool> done{false};
  std::string writer_error, reader_error;
  std::thread write_thread([&] {
    try {
      for (int i = 0; i < kSessions; ++i) writer.recordSession(makeSession("anna", "navigation", 1000 + i, i % 100));
    } catch (const std::exception& e) {
      writer_error = e.what();
    }
    done = true;
  });
  std::size_t last_count = 0;
  int reads = 0;
  try {
    RawDb raw(path);
    while (!done || last_count < kSessions) {
      const auto sessions = reader.sessions();
      if (sessions.size() < last_count) reader_error = "count went down";
      for (const auto& s : sessions) {
        // Session and items are one transaction: a reader never sees one without the other.
        if (s.items.size() != 2u) reader_error = "session " + std::to_string(s.id) + " without its items";
      }
      last_count = sessions.size();
      // A plain connection too, in one statement: sessions and items counts agree in every snapshot.
      const auto counts = raw.rows("SELECT (SELECT count(*) FROM sessions), (SELECT count(*) FROM score_items)");
      if (std::stoi(counts[0][1]) != 2 * std::stoi(counts[0][0])) reader_error = "raw counts disagree";
      ++reads;
      if (done && last_count < kSessions && !writer_error.empty()) break;
    }
  } catch (const std::exception& e) {
    reader_error = e.what();
  }
  write_thread.join();
  EXPECT_EQ(writer_error, "");
  EXPECT_EQ(reader_error, "");
  EXPECT_EQ(last_count, static_cast<std::size_t>(kSessions));
  EXPECT_GT(reads, 1);
}

TEST(RecordsDamage, TruncatedDatabaseIsReportedAndLeftUntouched) {
  TempDir dir;
  const std::string path = dir.file("cut.sqlite");
  fillDatabase(path, 120);
  ASSERT_EQ(Store::integrityCheck(path), "ok");
  const std::string whole = readBytes(path);
  ASSERT_GT(whole.size(), 16u * 4096u);
  // Cut off mid-write: half the file, not on a page boundary.
  writeBytes(path, whole.substr(0, whole.size() / 2 + 1234));
  const std::string before = readBytes(path);

  StoreError error("");
  expectStoreError([&] { Store store(path); }, {path, "damaged"}, &error);
  EXPECT_FALSE(error.integrityReport().empty());
  EXPECT_NE(error.integrityReport(), "ok");
  EXPECT_NE(Store::integrityCheck(path), "ok");
  EXPECT_TRUE(sameBytes(readBytes(path), before));
}

TEST(RecordsDamage, GarbagePageIsReportedAndLeftUntouched) {
  for (const bool random : {false, true}) {
    SCOPED_TRACE(random ? "random bytes in a middle page" : "0xFF over page 2");
    TempDir dir;
    const std::string path = dir.file("bad_page.sqlite");
    fillDatabase(path, 120);
    const int page_size = std::stoi(RawDb(path).value("PRAGMA page_size"));
    std::string bytes = readBytes(path);
    const std::size_t pages = bytes.size() / page_size;
    ASSERT_GE(pages, 8u);
    const std::size_t page = random ? pages / 2 : 2;  // 1-based page numbers
    std::mt19937 rng(42);
    for (int i = 0; i < page_size; ++i) {
      bytes[(page - 1) * page_size + i] = random ? static_cast<char>(rng()) : static_cast<char>(0xFF);
    }
    writeBytes(path, bytes);

    StoreError error("");
    expectStoreError([&] { Store store(path); }, {path, "damaged"}, &error);
    EXPECT_NE(error.integrityReport(), "ok");
    EXPECT_FALSE(error.integrityReport().empty());
    EXPECT_NE(Store::integrityCheck(path), "ok");
    EXPECT_TRUE(sameBytes(readBytes(path), bytes));
  }
}

TEST(RecordsDamage, NotADatabaseIsRefusedAndLeftUntouched) {
  TempDir dir;
  const std::string path = dir.file("notes.sqlite");
  std::string text;
  for (int i = 0; i < 100; ++i) text += "line " + std::to_string(i) + " of a text file, not a database\n";
  writeBytes(path, text);
  StoreError error("");
  expectStoreError([&] { Store store(path); }, {path, "damaged"}, &error);
  EXPECT_NE(error.integrityReport().find("not a database"), std::string::npos) << error.integrityReport();
  EXPECT_NE(Store::integrityCheck(path), "ok");
  EXPECT_TRUE(sameBytes(readBytes(path), text));
  expectStoreError([&] { Store::integrityCheck(dir.file("missing.sqlite")); }, {"missing.sqlite"});
  EXPECT_FALSE(fs::exists(dir.file("missing.sqlite")));
}

TEST(RecordsExport, CsvQuotesFieldsAndParsesBack) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  const std::string awkward_user = "O'Neil, \"Doc\"";
  SessionRecord s = makeSession(awkward_user, "navigation", 100, 75.25);
  s.items = {{"wrong, \"touches\"", 2, "1", 2, 50}, {"path\nlength", 0.0206, "m", 1, 100}};
  s.bag_path = "/bags/a,b.bag";
  const auto id = store.recordSession(s).session_id;
  SessionRecord bare = makeSession("guest", "free", 200, 0);
  bare.items.clear();
  const auto bare_id = store.recordSession(bare).session_id;

  std::ostringstream out;
  store.exportCsv(out);
  const std::string csv = out.str();
  EXPECT_NE(csv.find("\"O'Neil, \"\"Doc\"\"\""), std::string::npos) << csv;
  const auto rows = parseCsv(csv);
  ASSERT_EQ(rows.size(), 4u) << csv;
  EXPECT_EQ(rows[0], (std::vector<std::string>{"session_id", "user", "scene", "scenario", "difficulty", "seed", "state",
                                               "passed", "total", "elapsed", "recorded_at", "bag", "item", "value",
                                               "unit", "weight", "points"}));
  for (const auto& row : rows) ASSERT_EQ(row.size(), 17u);
  EXPECT_EQ(rows[1][0], std::to_string(id));
  EXPECT_EQ(rows[1][1], awkward_user);
  EXPECT_EQ(rows[1][7], "1");
  EXPECT_EQ(rows[1][8], "75.25");
  EXPECT_EQ(rows[1][11], "/bags/a,b.bag");
  EXPECT_EQ(rows[1][12], "wrong, \"touches\"");
  EXPECT_EQ(rows[1][15], "2");
  EXPECT_EQ(rows[2][12], "path\nlength");
  EXPECT_EQ(rows[2][13], "0.0206");
  EXPECT_EQ(rows[3][0], std::to_string(bare_id));
  EXPECT_EQ(rows[3][7], "0");
  for (int c = 12; c < 17; ++c) EXPECT_EQ(rows[3][c], "");

  std::ostringstream filtered;
  store.exportCsv(filtered, {awkward_user, ""});
  EXPECT_EQ(parseCsv(filtered.str()).size(), 3u);
  EXPECT_EQ(csvField("plain"), "plain");
  EXPECT_EQ(csvField("a\"b"), "\"a\"\"b\"");
}

TEST(RecordsSummaries, BestAndLastPerScene) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  auto record = [&](const std::string& user, const std::string& scene, double start, double total,
                    const std::string& at) {
    SessionRecord s = makeSession(user, scene, start, total);
    s.recorded_at = at;
    store.recordSession(s);
  };
  // Inserted out of order: "last" follows the session's start stamp, not the insertion.
  record("anna", "navigation", 300, 60, "2026-01-03T00:00:00Z");
  record("anna", "navigation", 100, 50, "2026-01-01T00:00:00Z");
  record("anna", "navigation", 200, 80, "2026-01-02T00:00:00Z");
  record("anna", "vitrectomy", 150, 42, "2026-01-04T00:00:00Z");
  record("bob", "navigation", 400, 99, "2026-01-05T00:00:00Z");

  const auto anna = store.summaries("anna");
  ASSERT_EQ(anna.size(), 2u);
  EXPECT_EQ(anna[0].scene, "navigation");
  EXPECT_EQ(anna[0].sessions, 3);
  EXPECT_DOUBLE_EQ(anna[0].best, 80);
  EXPECT_DOUBLE_EQ(anna[0].last, 60);
  EXPECT_EQ(anna[0].last_recorded_at, "2026-01-03T00:00:00Z");
  EXPECT_EQ(anna[1].scene, "vitrectomy");
  EXPECT_EQ(anna[1].sessions, 1);
  EXPECT_DOUBLE_EQ(anna[1].best, 42);
  EXPECT_DOUBLE_EQ(anna[1].last, 42);

  const auto bob = store.summaries("bob");
  ASSERT_EQ(bob.size(), 1u);
  EXPECT_DOUBLE_EQ(bob[0].best, 99);
  EXPECT_TRUE(store.summaries("nobody").empty());
}

int run(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(RecordsTool, ImportCheckExportAndExitCodes) {
  TempDir dir;
  const std::string tool = EYESI_RECORDS_TOOL;
  const std::string db = dir.file("tool.sqlite");
  const std::string quiet = " >/dev/null 2>&1";
  EXPECT_EQ(run(tool + " --db " + db + " import " + EYESI_TEST_BAGS + " --user anna" + quiet), 0);
  EXPECT_EQ(run(tool + " --db " + db + " add-user dr --role instructor --pin 1357" + quiet), 0);
  EXPECT_EQ(run(tool + " --db " + db + " add-user dr --role instructor --pin 1357" + quiet), 1);
  EXPECT_EQ(run(tool + " --db " + db + " add-user x --role boss" + quiet), 2);
  EXPECT_EQ(run(tool + " --db " + db + " frobnicate" + quiet), 2);
  // The shared command line (vrm_scene/cli/cli.h): --help, unknown and abbreviated options, a command's foreign option.
  EXPECT_EQ(run(tool + " --help" + quiet), 0);
  EXPECT_EQ(run(tool + " --db " + db + " list --no-such-flag" + quiet), 2);
  EXPECT_EQ(run(tool + " --db " + db + " list --us anna" + quiet), 2);
  EXPECT_EQ(run(tool + " --db " + db + " users --role trainee" + quiet), 2);
  EXPECT_EQ(run(tool + " --db=" + db + " set-pin dr --pin=1357" + quiet), 0);  // --name=value spelling
  EXPECT_EQ(run(tool + " --db " + db + " list --user anna" + quiet), 0);
  EXPECT_EQ(run(tool + " --db " + db + " check" + quiet), 0);
  const std::string csv = dir.file("out.csv");
  EXPECT_EQ(run(tool + " --db " + db + " export-csv --user anna --out " + csv + quiet), 0);
  std::size_t items = 0;
  for (const auto& file : referenceResults()) items += nlohmann::json::parse(readBytes(file))["items"].size();
  EXPECT_EQ(parseCsv(readBytes(csv)).size(), 1u + items);  // the header and one line per item
  {
    Store store(db);
    EXPECT_TRUE(store.checkPin("dr", "1357"));
    EXPECT_EQ(store.sessions({"anna", ""}).size(), 3u);
  }
  const std::string junk = dir.file("junk.sqlite");
  writeBytes(junk, std::string(5000, 'x'));
  EXPECT_EQ(run(tool + " --db " + junk + " check" + quiet), 1);
  EXPECT_EQ(run(tool + " --db " + junk + " list" + quiet), 1);
  EXPECT_TRUE(sameBytes(readBytes(junk), std::string(5000, 'x')));
}

// ---- issue 35: factor groups and penalty events ----

SessionRecord sessionWithPenalties(const std::string& user, double start) {
  SessionRecord s = makeSession(user, "membrane_peeling", start, 61.25);
  s.groups = {{"target_achievement", 100, 3}, {"tissue_treatment", 40.5, 4}};
  PenaltyEventRecord touch;
  touch.time = 4.25;
  touch.kind = "retina_touched";
  touch.item = "retina_contacts";
  touch.slot = "right";
  touch.instrument = "forceps";
  touch.position[0] = 0.0012;
  touch.position[1] = -0.0003;
  touch.position[2] = -0.0118;
  touch.points = 6.25;
  PenaltyEventRecord unlocated;  // no tracked instrument: no slot, no position
  unlocated.time = 9.5;
  unlocated.kind = "bleeding";
  unlocated.item = "bleeding_area";
  unlocated.position[0] = unlocated.position[1] = unlocated.position[2] = std::nan("");
  unlocated.points = 1.5;
  s.events = {touch, unlocated};
  s.events_dropped = 3;
  return s;
}

TEST(RecordsSessions, GroupsAndEventsRoundTripInOrderWithAnUnknownPosition) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  const SessionRecord s = sessionWithPenalties("carla", 1700000000.5);
  const auto stored = store.session(store.recordSession(s).session_id);
  ASSERT_TRUE(stored.has_value());
  ASSERT_EQ(stored->groups.size(), 2u);
  EXPECT_EQ(stored->groups[1].name, "tissue_treatment");
  EXPECT_DOUBLE_EQ(stored->groups[1].points, 40.5);
  EXPECT_DOUBLE_EQ(stored->groups[1].weight, 4);
  ASSERT_EQ(stored->events.size(), 2u);
  const PenaltyEventRecord& touch = stored->events[0];
  EXPECT_EQ(touch.kind, "retina_touched");
  EXPECT_EQ(touch.item, "retina_contacts");
  EXPECT_EQ(touch.slot, "right");
  EXPECT_EQ(touch.instrument, "forceps");
  EXPECT_DOUBLE_EQ(touch.time, 4.25);
  EXPECT_DOUBLE_EQ(touch.position[0], 0.0012);
  EXPECT_DOUBLE_EQ(touch.position[2], -0.0118);
  EXPECT_DOUBLE_EQ(touch.points, 6.25);
  EXPECT_EQ(stored->events[1].slot, "");
  EXPECT_TRUE(std::isnan(stored->events[1].position[0])) << "an unknown position must not read back as 0";
  EXPECT_EQ(stored->events_dropped, 3u);
  // A session without any: none read back (and the list query sees the same).
  const auto bare_id = store.recordSession(makeSession("carla", "navigation", 5, 70)).session_id;
  EXPECT_TRUE(store.session(bare_id)->groups.empty());
  EXPECT_TRUE(store.session(bare_id)->events.empty());
  EXPECT_EQ(store.sessions({"carla", "membrane_peeling"}).at(0).events.size(), 2u);
}

TEST(RecordsImport, ResultGroupsAndEventsAreStoredWithTheSession) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  const std::string json =
      R"({"scene": "navigation", "scenario": "navigation", "state": "failed", "total": 60, "items": [], )"
      R"("groups": [{"name": "tissue_treatment", "points": 50, "weight": 2}], "events": [{"time": 1.5, )"
      R"("kind": "wrong_target", "item": "wrong_touches", "slot": "right", "instrument": "needle", )"
      R"("position": [0.001, null, -0.01], "points": 12.5}], "events_dropped": 0, "final_state_hash": "0x2", )"
      R"("frames": 10})";
  const auto id = store.importResultJson(json, "t.result.json", "anna").session_id;
  const auto stored = store.session(id);
  ASSERT_TRUE(stored.has_value());
  ASSERT_EQ(stored->groups.size(), 1u);
  EXPECT_EQ(stored->groups[0].name, "tissue_treatment");
  ASSERT_EQ(stored->events.size(), 1u);
  EXPECT_EQ(stored->events[0].kind, "wrong_target");
  EXPECT_DOUBLE_EQ(stored->events[0].position[0], 0.001);
  EXPECT_TRUE(std::isnan(stored->events[0].position[1]));
  EXPECT_DOUBLE_EQ(stored->events[0].points, 12.5);
}

TEST(RecordsSchema, MigratesVersion3AddingGroupsAndEventsAndKeepingTheRows) {
  TempDir dir;
  const std::string path = dir.file("v3.sqlite");
  const SessionRecord old = makeSession("bob", "vitrectomy", 500.25, 66.5);
  {
    RawDb raw(path);
    std::string sql = "BEGIN;";
    for (int version = 1; version <= 3; ++version) sql += migrationSql(version);
    raw.exec(sql + "PRAGMA user_version = 3; COMMIT;");
    raw.exec(
        "INSERT INTO users (name, role, iterations, created_at) VALUES ('bob', 'trainee', 0, '2025-01-01T00:00:00Z')");
    raw.exec(
        "INSERT INTO sessions (session_key, user_id, scene, state, total, recorded_at, final_state_hash, frames) "
        "SELECT '" +
        sessionKey(old) + "', id, 'vitrectomy', 'finished', 66.5, '2025-01-02T03:04:05Z', '" + old.final_state_hash +
        "', 700 FROM users WHERE name = 'bob'");
    raw.exec("INSERT INTO score_items SELECT id, 0, 'completed', 1, '', 3, 100 FROM sessions");
  }
  Store store(path);
  EXPECT_EQ(store.schemaVersion(), Store::kSchemaVersion);
  const auto sessions = store.sessions();
  ASSERT_EQ(sessions.size(), 1u);
  EXPECT_DOUBLE_EQ(sessions[0].total, 66.5);
  EXPECT_EQ(sessions[0].items.size(), 1u);
  EXPECT_TRUE(sessions[0].groups.empty());  // recorded before groups existed
  EXPECT_TRUE(sessions[0].events.empty());
  EXPECT_EQ(sessions[0].events_dropped, 0u);
  const auto id = store.recordSession(sessionWithPenalties("bob", 900)).session_id;
  EXPECT_EQ(store.session(id)->events.size(), 2u);
  RawDb raw(path);
  EXPECT_EQ(raw.value("SELECT count(*) FROM sqlite_master WHERE name IN ('score_groups', 'penalty_events')"), "2");
  EXPECT_EQ(raw.value("SELECT count(*) FROM penalty_events WHERE x IS NULL"), "1");
}

// Issue 41: the station's side of the centre's sync (the server side runs in test/centre/centre_sync.py).
TEST(RecordsSync, EverySessionGetsItsOwnGlobalKeyAndTheContentHashIsNotIt) {
  TempDir dir;
  Store a(dir.file("a.sqlite")), b(dir.file("b.sqlite"));
  const SessionRecord scripted = makeSession("anna", "navigation", 1000, 80);
  const auto in_a = a.recordSession(scripted), in_b = b.recordSession(scripted);
  const std::string key_a = a.session(in_a.session_id)->global_key, key_b = b.session(in_b.session_id)->global_key;
  EXPECT_EQ(key_a.size(), 36u);
  EXPECT_EQ(key_a[14], '4');  // a version 4 (random) UUID
  EXPECT_NE(key_a, key_b);    // the same scripted session on two stations: two sessions
  SessionRecord given = makeSession("anna", "navigation", 2000, 70);
  given.global_key = "6f1c2d3e-0000-4000-8000-000000000001";
  EXPECT_EQ(a.session(a.recordSession(given).session_id)->global_key, given.global_key);
}

TEST(RecordsSync, TheOutboxListsUnsyncedSessionsInOrderUntilMarked) {
  TempDir dir;
  Store store(dir.file("s.sqlite"));
  for (int i = 0; i < 5; ++i) store.recordSession(makeSession("anna", "navigation", 1000 + i, 60));
  EXPECT_EQ(store.unsyncedCount(), 5);
  const auto first = store.unsyncedSessions(0, 2);
  ASSERT_EQ(first.size(), 2u);
  EXPECT_LT(first[0].id, first[1].id);
  EXPECT_EQ(first[0].items.size(), 2u);
  EXPECT_EQ(store.unsyncedSessions(first.back().id, 10).size(), 3u);
  store.markSynced({first[0].global_key, first[1].global_key, "not-a-key"});
  EXPECT_EQ(store.unsyncedCount(), 3);
  const auto rest = store.unsyncedSessions(0, 10);
  ASSERT_EQ(rest.size(), 3u);
  EXPECT_GT(rest[0].id, first[1].id);
}

TEST(RecordsSync, ServerUsersWinNamesAndRolesAndDeletionsReachTheStation) {
  TempDir dir;
  Store store(dir.file("s.sqlite"));
  store.addUser("anna", Role::kTrainee, "1234");  // made on this station while offline
  store.addUser("otto", Role::kTrainee, "");      // only on this station
  store.recordSession(makeSession("anna", "navigation", 1000, 60));
  store.recordSession(makeSession("carl", "navigation", 1001, 60));  // carl is created by the import
  EXPECT_EQ(store.applyServerUsers({{"anna", "trainee", false},
                                    {"bea", "instructor", false},
                                    {"carl", "instructor", false},
                                    {"root", "admin", false},
                                    {"guest", "admin", true}}),
            3);
  EXPECT_TRUE(store.checkPin("anna", "1234"));  // the station's PIN stays; it never travels
  EXPECT_EQ(store.findUser("bea")->role, Role::kInstructor);
  EXPECT_FALSE(store.findUser("bea")->has_pin);
  EXPECT_EQ(store.findUser("carl")->role, Role::kInstructor);  // the server's role wins
  EXPECT_FALSE(store.findUser("root"));                        // admins are not station users
  EXPECT_TRUE(store.findUser("guest"));
  EXPECT_TRUE(store.findUser("otto"));  // a station's own user the server does not know stays
  // A server that does not list carl at all (restored from an old backup): not a deletion, carl and his session stay.
  EXPECT_EQ(store.applyServerUsers({{"anna", "trainee", false}, {"bea", "instructor", false}}), 1);
  ASSERT_TRUE(store.findUser("carl"));
  EXPECT_FALSE(store.findUser("carl")->from_server);
  EXPECT_EQ(store.sessions({"carl", ""}).size(), 1u);
  // Deletion on request: the user, their sessions and their course go.
  store.applyServerAssignment({"anna", "Basics", "", "name: Basics", "bea", "2026-11-30T10:00:00Z"});
  EXPECT_EQ(store.courseAssignment("anna")->assigned_by, "bea");
  store.applyServerUsers({{"anna", "trainee", true}, {"bea", "instructor", false}});
  EXPECT_FALSE(store.findUser("anna"));
  EXPECT_EQ(store.sessions({"anna", ""}).size(), 0u);
  EXPECT_EQ(store.sessions().size(), 1u);  // carl's
  EXPECT_FALSE(store.courseAssignment("anna"));
  EXPECT_TRUE(store.findUser("otto"));
}

TEST(RecordsTrajectory, SamplesRoundTripThroughTheFileAndTheStoreAndBadFilesAreNamed) {
  TempDir dir;
  TrajectorySample eye;
  eye.frame = 1;
  eye.source = "eye";
  eye.frame_id = "world";
  eye.orientation[3] = 1.0;
  eye.valid = true;
  TrajectorySample tip = eye;
  tip.source = "instrument:left";
  tip.frame_id = "eye";
  tip.time = 0.016;
  tip.position[0] = -0.0035;
  tip.valid = false;
  const auto parsed = parseTrajectoryJson(trajectoryJson({eye, tip}, "a.bag"), "t.json");
  ASSERT_EQ(parsed.size(), 2u);
  EXPECT_EQ(parsed[1].source, "instrument:left");
  EXPECT_DOUBLE_EQ(parsed[1].position[0], -0.0035);
  EXPECT_FALSE(parsed[1].valid);
  Store store(dir.file("s.sqlite"));
  SessionRecord s = makeSession("anna", "navigation", 1000, 60);
  s.trajectory = parsed;
  const auto id = store.recordSession(s).session_id;
  const auto back = store.trajectory(id);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1].frame_id, "eye");
  EXPECT_DOUBLE_EQ(back[1].time, 0.016);
  EXPECT_TRUE(store.session(id)->trajectory.empty());  // the lists do not carry them
  EXPECT_EQ(store.unsyncedSessions(0, 1)[0].trajectory.size(), 2u);
  EXPECT_EQ(trajectoryPathFor("/x/a.result.json"), "/x/a.trajectory.json");
  expectStoreError([] { parseTrajectoryJson("{\"format\": \"other\"}", "bad.json"); }, {"bad.json", "format"});
  expectStoreError([] { parseTrajectoryJson(R"({"format": "eyesi_trajectory/1", "samples": [[1, 0]]})", "b.json"); },
                   {"b.json", "sample 0"});
}

TEST(RecordsCentre, FiltersCurvesAndTheGroupsProgress) {
  std::vector<SessionRecord> sessions;
  for (int i = 0; i < 6; ++i) {
    SessionRecord s = makeSession(i % 2 ? "ben" : "anna", i < 4 ? "membrane_peeling" : "navigation", 100 - i, 50 + i);
    s.station = i % 3 ? "station_a" : "station_b";
    s.recorded_at = "2026-11-2" + std::to_string(i) + "T09:00:00Z";
    sessions.push_back(s);
  }
  EXPECT_EQ(filterSessions(sessions, {"station_b", "", "", "", ""}).size(), 2u);
  EXPECT_EQ(filterSessions(sessions, {"", "anna", "membrane_peeling", "", ""}).size(), 2u);
  EXPECT_EQ(filterSessions(sessions, {"", "", "", "2026-11-21", "2026-11-23"}).size(), 3u);  // both ends inclusive
  expectStoreError([&] { filterSessions(sessions, {"", "", "", "21.11.2026", ""}); }, {"21.11.2026", "YYYY-MM-DD"});
  const auto curves = learningCurves(sessions);
  ASSERT_EQ(curves.size(), 4u);  // (anna, ben) x (membrane_peeling, navigation)
  EXPECT_EQ(curves[0].trainee, "anna");
  EXPECT_EQ(curves[0].scene, "membrane_peeling");
  // In the order trained (start stamps fall as i rises): session 2 (total 52) before session 0 (total 50).
  EXPECT_EQ(curves[0].totals, (std::vector<double>{52, 50}));
  EXPECT_DOUBLE_EQ(curves[0].best, 52);
  const std::string course = "name: Peel\nsteps:\n  - module: membrane_peeling\n    level: medium\n    pass_mark: 51\n";
  const auto rows =
      groupProgress({"anna", "ben", "cleo"},
                    {{"anna", "Peel", "", course, "weber", ""}, {"ben", "Broken", "", "steps: [", "", ""}}, sessions);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].steps_passed, 1u);
  EXPECT_EQ(rows[0].steps, 1u);
  EXPECT_FALSE(rows[1].problem.empty());  // an unreadable course is reported in its row
  EXPECT_TRUE(rows[2].course.empty());
  EXPECT_EQ(connectionValue("it's a \\ test"), "'it\\'s a \\\\ test'");
}

TEST(RecordsTrajectory, ALiveSessionsTrajectoryIsAttachedLaterAndGoesBackIntoTheOutbox) {
  TempDir dir;
  Store store(dir.file("s.sqlite"));
  SessionRecord live = makeSession("anna", "navigation", 1000, 60);
  live.bag_path = dir.file("live.bag");
  live.recorded_at = "2026-11-30T10:00:00Z";
  const auto id = store.recordSession(live).session_id;
  store.markSynced({store.session(id)->global_key});
  EXPECT_EQ(store.attachTrajectories("2026-11-30T00:00:00Z"), 0);  // no file yet
  TrajectorySample eye;
  eye.frame = 1;
  eye.source = "eye";
  writeBytes(dir.file("live.trajectory.json"), trajectoryJson({eye, eye}, live.bag_path));
  EXPECT_EQ(store.attachTrajectories("2026-12-01T00:00:00Z"), 0);  // synced and older than asked for
  EXPECT_EQ(store.attachTrajectories("2026-11-30T00:00:00Z"), 1);
  EXPECT_EQ(store.trajectory(id).size(), 2u);
  EXPECT_EQ(store.unsyncedCount(), 1);                             // back in the outbox, for the server's copy
  EXPECT_EQ(store.attachTrajectories("2026-11-30T00:00:00Z"), 0);  // once
  writeBytes(dir.file("broken.trajectory.json"), "{");
  SessionRecord other = makeSession("anna", "navigation", 2000, 60);
  other.bag_path = dir.file("broken.bag");
  store.recordSession(other);
  std::vector<std::string> errors;
  EXPECT_EQ(store.attachTrajectories("", &errors), 0);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("broken.trajectory.json"), std::string::npos);
}

TEST(RecordsSchema, MigratesVersion4GivingEverySessionAGlobalKeyAndAnEmptyOutbox) {
  TempDir dir;
  const std::string path = dir.file("v4.sqlite");
  {
    RawDb raw(path);
    std::string sql = "BEGIN;";
    for (int version = 1; version <= 4; ++version) sql += migrationSql(version);
    raw.exec(sql + "PRAGMA user_version = 4; COMMIT;");
    raw.exec(
        "INSERT INTO users (name, role, iterations, created_at) VALUES ('bob', 'trainee', 0, '2025-01-01T00:00:00Z')");
    for (int i = 0; i < 3; ++i) {
      raw.exec("INSERT INTO sessions (session_key, user_id, scene, recorded_at) SELECT 'k" + std::to_string(i) +
               "', id, 'navigation', '2025-01-02T03:04:05Z' FROM users WHERE name = 'bob'");
    }
  }
  Store store(path);
  EXPECT_EQ(store.schemaVersion(), 5);
  const auto sessions = store.unsyncedSessions(0, 10);
  ASSERT_EQ(sessions.size(), 3u);  // everything recorded before a server existed waits to go up
  std::set<std::string> keys;
  for (const auto& s : sessions) {
    EXPECT_EQ(s.global_key.size(), 36u) << s.global_key;
    EXPECT_EQ(s.global_key[14], '4') << s.global_key;
    keys.insert(s.global_key);
  }
  EXPECT_EQ(keys.size(), 3u);
}

TEST(RecordsExport, GroupsAndEventsCsvListEverySession) {
  TempDir dir;
  Store store(dir.file("r.sqlite"));
  const auto id = store.recordSession(sessionWithPenalties("anna", 100)).session_id;
  const auto bare_id = store.recordSession(makeSession("anna", "navigation", 200, 70)).session_id;

  std::ostringstream groups_out;
  store.exportGroupsCsv(groups_out);
  const auto groups = parseCsv(groups_out.str());
  ASSERT_EQ(groups.size(), 4u) << groups_out.str();  // header, two groups, the session without any
  EXPECT_EQ(groups[0], (std::vector<std::string>{"session_id", "user", "scene", "scenario", "difficulty", "seed",
                                                 "state", "passed", "total", "elapsed", "recorded_at", "bag", "group",
                                                 "points", "weight"}));
  EXPECT_EQ(groups[1][0], std::to_string(id));
  EXPECT_EQ(groups[2][12], "tissue_treatment");
  EXPECT_EQ(groups[2][13], "40.5");
  EXPECT_EQ(groups[2][14], "4");
  EXPECT_EQ(groups[3][0], std::to_string(bare_id));
  EXPECT_EQ(groups[3][12], "");

  std::ostringstream events_out;
  store.exportEventsCsv(events_out, {"anna", "membrane_peeling"});
  const auto events = parseCsv(events_out.str());
  ASSERT_EQ(events.size(), 3u) << events_out.str();
  EXPECT_EQ(events[0].size(), 21u);
  EXPECT_EQ(events[0][12], "event_time");
  EXPECT_EQ(events[0][20], "event_points");
  EXPECT_EQ(events[1], (std::vector<std::string>{std::to_string(id),
                                                 "anna",
                                                 "membrane_peeling",
                                                 "membrane_peeling",
                                                 "medium",
                                                 "7",
                                                 "finished",
                                                 "1",
                                                 "61.25",
                                                 "12.5",
                                                 events[1][10],
                                                 "",
                                                 "4.25",
                                                 "retina_touched",
                                                 "retina_contacts",
                                                 "right",
                                                 "forceps",
                                                 "0.0012",
                                                 "-3e-04",
                                                 "-0.0118",
                                                 "6.25"}));
  EXPECT_EQ(events[2][13], "bleeding");
  EXPECT_EQ(events[2][17], "");  // unknown position: empty, not 0
  EXPECT_EQ(events[2][20], "1.5");
}

TEST(RecordsTool, ExportsTheGroupsAndEventsTables) {
  TempDir dir;
  const std::string tool = EYESI_RECORDS_TOOL;
  const std::string db = dir.file("tool.sqlite");
  const std::string quiet = " >/dev/null 2>&1";
  ASSERT_EQ(run(tool + " --db " + db + " import " + EYESI_TEST_BAGS + " --user anna" + quiet), 0);
  for (const std::string table : {"groups", "events"}) {
    const std::string csv = dir.file(table + ".csv");
    EXPECT_EQ(run(tool + " --db " + db + " export-csv --table " + table + " --out " + csv + quiet), 0) << table;
    // One line per group / event of a session; a session without any (results before issue 35) gets one line with
    // those fields empty.
    std::size_t lines = 0;
    for (const std::string& file : referenceResults()) {
      const nlohmann::json result = nlohmann::json::parse(readBytes(file));
      lines += std::max<std::size_t>(1, result.value(table, nlohmann::json::array()).size());
    }
    const auto rows = parseCsv(readBytes(csv));
    ASSERT_EQ(rows.size(), 1u + lines) << table;
    EXPECT_EQ(rows[0][12], table == "groups" ? "group" : "event_time");
  }
  EXPECT_EQ(run(tool + " --db " + db + " export-csv --table scores" + quiet), 2);
}

}  // namespace
}  // namespace eyesi_gui::records
