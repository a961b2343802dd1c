// Training records (thesis §2.4, §7.3: who trained what, how well, and the recorded inputs to replay it): a SQLite
// store of users, sessions and score items, shared by the console (eyesi_gui), its `records` command-line tool and
// the tests. ROS-free and Qt-free.
//
// CONTRACT (written before the implementation; the implementation may add, not change):
// - One database file (WAL journal, foreign keys on, schema version in PRAGMA user_version, forward migrations from
//   version 0 = empty file to kSchemaVersion).
// - Users: name (unique), role, PIN stored as a salted PBKDF2-HMAC-SHA256 hash (never plain). A built-in "guest"
//   trainee without PIN always exists.
// - Sessions: one row per session, written with its score items in one transaction; a session is identified by its
//   result (scene, seed, start/end stamp, final state hash, frames), so importing the same result twice gives one row.
//   Added (issue 35, schema version 4): the factor groups and penalty events are written in the same transaction.
// - A database that is not SQLite, cut off or has a bad page: StoreError with what() naming the file and the
//   integrity_check report; the file is never modified in that case.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "eyesi_gui/records/trajectory.h"

namespace eyesi_gui::records {

enum class Role { kTrainee, kInstructor };
const char* toString(Role role);  // "trainee" / "instructor"

struct User {
  std::int64_t id = 0;
  std::string name;
  Role role = Role::kTrainee;
  bool has_pin = false;
  // Added (issue 41): the user came down from the centre's records server (the console then asks for the server
  // password, not an empty PIN, until the person has set a PIN on this station).
  bool from_server = false;
};

struct ScoreItemRecord {
  std::string name;
  double value = 0.0;
  std::string unit;
  double weight = 0.0;
  double points = 0.0;  // 0..100: how much of the item was earned (the scenario runner's score; total = weighted mean)
};

// Added to the contract (issue 35, schema version 4): a factor group's score (doc/session_result.md: groups).
struct GroupRecord {
  std::string name;     // target_achievement, efficiency, tissue_treatment, instrument_handling, microscope_handling
  double points = 0.0;  // 0..100
  double weight = 0.0;  // the sum of its items' weights
};

// Added to the contract (issue 35, schema version 4): a penalty event, why points were lost (result key events).
struct PenaltyEventRecord {
  double time = 0.0;  // s of running time since the session started
  std::string kind;   // retina_touched, bleeding, ...
  std::string item;   // the score item it raised
  std::string slot;   // the instrument's slot ("" unknown)
  std::string instrument;
  double position[3] = {0.0, 0.0, 0.0};  // m, eye frame (NaN: unknown; stored as NULL)
  double points = 0.0;                   // the drop of the total it caused
};

struct SessionRecord {
  std::int64_t id = 0;  // 0 until stored
  std::string user;     // user name ("guest" for a result without one)
  std::string scene, scenario, difficulty;
  std::uint32_t seed = 0;
  std::string state;         // "finished" / "failed" / "stopped" / "running" (interrupted) / ...
  std::string message;       // the scenario's last message
  double total = 0.0;        // 0..100
  bool passed = false;       // state == finished
  double elapsed = 0.0;      // s of simulated time
  double start_stamp = 0.0;  // input time (s) of the session's start and end
  double end_stamp = 0.0;
  std::string recorded_at;  // wall time the row was written, ISO-8601 UTC ("2026-11-24T10:00:00Z")
  std::string bag_path;     // the session's input bag ("" = not recorded)
  std::string result_path;  // the result JSON it was imported from ("" = live)
  std::string software_version;
  std::string final_state_hash;
  std::uint64_t frames = 0;
  std::string station;     // host name of the simulator that ran it
  std::string annotation;  // instructor's note
  std::vector<ScoreItemRecord> items;
  std::vector<GroupRecord> groups;         // empty for sessions recorded before schema version 4
  std::vector<PenaltyEventRecord> events;  // at most 200 (the result's limit)
  std::uint64_t events_dropped = 0;        // penalty events the result did not keep
  // Added to the contract (issue 41, schema version 5): the session's identity across the centre, a random UUID made
  // when the station first stores it ("" in a record to store: one is made). Never derived from the content.
  std::string global_key;
  // Added (issue 41): the per-frame trajectories. Written by recordSession; read only by trajectory() and
  // unsyncedSessions() (the lists the console shows do not need them).
  std::vector<TrajectorySample> trajectory;
};

struct SessionFilter {
  std::string user;   // "" = every user
  std::string scene;  // "" = every scene
};

// A per-scene summary for the scenario screen.
struct SceneSummary {
  std::string scene;
  int sessions = 0;
  double best = 0.0;
  double last = 0.0;
  std::string last_recorded_at;
};

// Added to the contract (issue 35, schema version 3): the course an instructor assigned to a trainee, as it was
// assigned (course_text: the course file's YAML, read with records/course.h). Progress is not stored: it follows from
// the trainee's sessions.
struct CourseAssignment {
  std::string user;  // the trainee
  std::string course_name;
  std::string course_file;  // where the text came from (messages, and to tell courses apart)
  std::string course_text;
  std::string assigned_by;  // the instructor
  std::string assigned_at;  // ISO-8601 UTC
};

class StoreError : public std::runtime_error {
 public:
  StoreError(const std::string& what, std::string integrity_report = "")
      : std::runtime_error(what), integrity_report_(std::move(integrity_report)) {}
  const std::string& integrityReport() const { return integrity_report_; }

 private:
  std::string integrity_report_;
};

struct ImportResult {
  std::int64_t session_id = 0;
  bool inserted = false;  // false: the session was already stored
};

class Store {
 public:
  static constexpr int kSchemaVersion = 5;

  // Opens (creating parent folders and the file if missing) and migrates. Throws StoreError.
  explicit Store(const std::string& path);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  const std::string& path() const;
  int schemaVersion() const;

  // Users. addUser throws StoreError on a duplicate name or an empty name.
  User addUser(const std::string& name, Role role, const std::string& pin);
  std::vector<User> users() const;
  std::optional<User> findUser(const std::string& name) const;
  bool checkPin(const std::string& name, const std::string& pin) const;  // guest: always true
  // Added to the contract: sets or (empty pin) clears a user's PIN, e.g. for a trainee created by an import from
  // another station. A user without a PIN accepts only the empty PIN in checkPin. Throws for guest or an unknown user.
  void setPin(const std::string& name, const std::string& pin);

  // Sessions. recordSession is idempotent (see above); returns the row's id.
  ImportResult recordSession(const SessionRecord& session);
  // A scenario_manager result JSON (the file next to a bag, or the session_result topic's text). `user` and `bag`
  // override the JSON's "user" and "bag" fields when not empty (the station's graph serves many sessions, so the
  // live text does not name the session's trainee or bag). Throws StoreError on malformed JSON (naming the file).
  ImportResult importResultJson(const std::string& json_text, const std::string& origin, const std::string& user = "",
                                const std::string& bag = "");
  // Added (issue 41): the trajectories come from <stem>.trajectory.json next to the file, when there is one.
  ImportResult importResultFile(const std::string& path, const std::string& user = "");
  // Every *.result.json under `folder` (recursively); malformed ones are reported in `errors`, not thrown.
  std::vector<ImportResult> importFolder(const std::string& folder, std::vector<std::string>* errors = nullptr);
  // Added to the contract: the *.result.json files importFolder would import, sorted. Throws if `folder` is not one.
  static std::vector<std::string> findResultFiles(const std::string& folder);

  std::vector<SessionRecord> sessions(const SessionFilter& filter = {}) const;  // oldest first, with items
  std::optional<SessionRecord> session(std::int64_t id) const;
  std::vector<SceneSummary> summaries(const std::string& user) const;
  void annotate(std::int64_t session_id, const std::string& text);

  // Courses (issue 35). assignCourse gives `trainee` the course (replacing an earlier one); StoreError when the
  // trainee is unknown or not a trainee, the instructor unknown or not an instructor, or the course has no name or
  // text. courseAssignment: the trainee's course, if any.
  void assignCourse(const CourseAssignment& assignment);
  std::optional<CourseAssignment> courseAssignment(const std::string& trainee) const;

  // CSV (RFC 4180): one line per score item of every matching session, with a header line.
  void exportCsv(std::ostream& out, const SessionFilter& filter = {}) const;
  // The same session columns, then one line per factor group (group, points, weight) or per penalty event (time,
  // kind, item, slot, instrument, x, y, z, points; an unknown position is empty) of every matching session; a session
  // without any still has one line with those fields empty, so every session appears in every export.
  void exportGroupsCsv(std::ostream& out, const SessionFilter& filter = {}) const;
  void exportEventsCsv(std::ostream& out, const SessionFilter& filter = {}) const;

  // Added to the contract (issue 41): the station's side of the sync with the records server (server.h).
  // The sessions the server has not acknowledged yet with a row id above `after_id`, oldest first, at most `limit`,
  // with their items.
  std::vector<SessionRecord> unsyncedSessions(std::int64_t after_id, std::size_t limit) const;
  std::int64_t unsyncedCount() const;
  // The session's trajectory samples in frame order (empty: none recorded).
  std::vector<TrajectorySample> trajectory(std::int64_t session_id) const;
  // Marks sessions as on the server (after the server committed them). Unknown keys are ignored.
  void markSynced(const std::vector<std::string>& global_keys);
  // Users as the server lists them. The conflict rules (README "Training centre"): the server's user wins its name
  // and role (a station's own user of that name becomes the server's, keeping its PIN and sessions, which the server
  // accepts only once that person has signed in on this station); a server user deleted there (a tombstone) is removed
  // here with their sessions and course; one the server does not list at all (an old backup, another server) becomes
  // this station's own again, keeping everything; PINs never travel either way. Returns the number of users changed.
  struct ServerUser {
    std::string name;
    std::string role;  // trainee / instructor / admin (admins are not station users and are skipped)
    bool deleted = false;
  };
  int applyServerUsers(const std::vector<ServerUser>& users);
  // A live session is stored before its bag is closed, so its trajectory file (session_trajectory) comes later:
  // attaches <bag stem>.trajectory.json or <result stem>.trajectory.json to the recorded sessions that have none —
  // those not yet synced and those recorded since `recorded_since` (ISO-8601) — and puts a synced one back into the
  // outbox, so the next upload adds its trajectory on the server. Returns the sessions it attached; unreadable files
  // are listed in `errors`.
  int attachTrajectories(const std::string& recorded_since, std::vector<std::string>* errors = nullptr);
  // A course assignment from the server replaces this station's (the server's is the one instructors edit for the
  // whole centre). The trainee must be a user here (applyServerUsers first); the instructor may be unknown here.
  void applyServerAssignment(const CourseAssignment& assignment);

  // PRAGMA integrity_check of a database file, opened read-only ("ok" when sound). Throws StoreError if the file
  // cannot be opened at all.
  static std::string integrityCheck(const std::string& path);

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace eyesi_gui::records
