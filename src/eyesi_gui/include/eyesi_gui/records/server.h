// The records server of a training centre (issue 41): PostgreSQL, reached through libpq, with the schema of
// schema.h's serverSchemaSql. A station keeps writing its own SQLite store first (store.h) and syncs when the server is
// reachable; nothing here is needed for a single station. ROS-free and Qt-free.
//
// Sync protocol (README "Training centre"):
// - Down, in one read transaction: users (names and roles only, never a password or PIN hash) and course
//   assignments; applied with Store::applyServerUsers / applyServerAssignment (the server wins).
// - Up, in batches: one server transaction per batch that starts with records_hello(station schema version) (an older
//   station is refused with the server's message), then per session a savepoint and
//   INSERT ... ON CONFLICT (global_key) DO NOTHING with its items, groups and events. After the COMMIT the station
//   marks the batch's sessions synced. A crash of either side before the COMMIT leaves nothing on the server; a crash
//   between the COMMIT and the mark re-sends sessions the server recognises by their global key: nothing is lost and
//   nothing is doubled. A session the server refuses (its user has not signed in on this station, guest, a user
//   the server does not know) stays on the station, unsynced, and is reported as held.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "eyesi_gui/records/store.h"

namespace eyesi_gui::records {

class ServerError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Connection strings are libpq's key=value form ("host=records.centre port=5432 dbname=records user=station_a
// sslmode=verify-full"); passwords come from PGPASSWORD or ~/.pgpass, not the command line. connect_timeout defaults
// to 5 s so an unreachable server is an error soon, not a hang.

// Installs the server schema (as the database's owner, a superuser or the owner of an empty database): tables,
// group roles, policies, functions, and schema_info at Store::kSchemaVersion. Returns false (and changes nothing)
// when that version is installed already; throws ServerError for another version or any failure.
bool installServerSchema(const std::string& owner_connection);

// Signs the connection's user in on `station` (records_sign_in): from then on that station may upload their sessions.
void signInOnServer(const std::string& user_connection, const std::string& station);

struct SyncOptions {
  std::size_t batch = 50;  // sessions per server transaction
  int pause_ms = 0;        // between batches (lets a busy server breathe; the tests use it to kill mid-sync)
};

struct SyncReport {
  int users_changed = 0;
  int assignments = 0;
  int uploaded = 0;                       // new on the server
  int already_on_server = 0;              // re-sent after a crash between the server's commit and the station's mark
  int held = 0;                           // refused by the server, kept on the station
  std::vector<std::string> held_reasons;  // one line per held session: global key, user, the server's reason
  int trajectories_attached = 0;          // trajectory files found since their sessions were stored
  std::vector<std::string> trajectory_errors;  // unreadable trajectory files (their sessions go up without)
};

// One sync of `store` as the station the connection's user is (its own login role). Throws ServerError when the
// server cannot be reached, refuses the station's schema version, or fails mid-way (what was committed stays
// committed and marked; the rest goes next time).
SyncReport syncWithServer(Store& store, const std::string& station_connection, const SyncOptions& options = {});

// Reads sessions for `records export --server` (export.h), in one read-only snapshot: what the connection's role may
// read under row-level security (an instructor: their group; the database owner on the server host: everything).
class ServerReader {
 public:
  explicit ServerReader(const std::string& connection);  // throws ServerError
  ~ServerReader();
  ServerReader(const ServerReader&) = delete;
  ServerReader& operator=(const ServerReader&) = delete;
  // With items, groups and events; SessionRecord::station is the station's server login.
  std::vector<SessionRecord> sessions(const SessionFilter& filter);
  std::vector<TrajectorySample> trajectory(std::int64_t session_id);  // one session's, so an export streams them

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace eyesi_gui::records
