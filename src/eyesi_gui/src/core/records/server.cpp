#include "eyesi_gui/records/server.h"

#include <libpq-fe.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <map>
#include <memory>
#include <optional>
#include <thread>

#include "eyesi_gui/records/centre.h"
#include "eyesi_gui/records/csv.h"
#include "eyesi_gui/records/schema.h"

namespace eyesi_gui::records {
namespace {

struct ClearResult {
  void operator()(PGresult* result) const { PQclear(result); }
};
using Result = std::unique_ptr<PGresult, ClearResult>;

// A parameter of a query: text, or SQL NULL.
using Param = std::optional<std::string>;

std::string trimmed(const char* text) {
  std::string message = text ? text : "";
  while (!message.empty() && (message.back() == '\n' || message.back() == ' ')) message.pop_back();
  return message;
}

bool succeeded(const PGresult* result) {
  const ExecStatusType status = PQresultStatus(result);
  return status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK;
}

// One libpq connection; every failure is a ServerError naming what was being done.
class Connection {
 public:
  explicit Connection(const std::string& connection) {
    // In the key=value form earlier keywords are defaults that later ones override: the caller's wins. An
    // unreachable server is an error after 5 s, and a server that vanishes mid-sync without closing the connection (a
    // cable pulled, a partition) after about 30 s of unacknowledged data or 25 s of silent keepalives, not the
    // kernel's two hours; the transaction then rolls back on the server. A URI (postgresql://...) is taken as it is.
    const bool uri = connection.rfind("postgres://", 0) == 0 || connection.rfind("postgresql://", 0) == 0;
    const std::string defaults =
        "connect_timeout=5 keepalives=1 keepalives_idle=10 keepalives_interval=5 keepalives_count=3 "
        "tcp_user_timeout=30000 ";
    conn_ = PQconnectdb((uri ? connection : defaults + connection).c_str());
    if (conn_ == nullptr || PQstatus(conn_) != CONNECTION_OK) {
      const std::string message = conn_ ? trimmed(PQerrorMessage(conn_)) : "out of memory";
      PQfinish(conn_);
      conn_ = nullptr;
      throw ServerError("cannot connect to the records server: " + message);
    }
  }
  ~Connection() { PQfinish(conn_); }
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  // Runs `sql` with $1.. bound to `params`; throws ServerError (with the server's message) unless it succeeded.
  Result run(const std::string& sql, const std::vector<Param>& params = {}, const char* what = "query") {
    Result result = tryRun(sql, params);
    const ExecStatusType status = PQresultStatus(result.get());
    if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK) {
      throw ServerError(std::string(what) + " failed on the records server: " + errorOf(result.get()));
    }
    return result;
  }

  // Several statements in one string (PQexec: no parameters), e.g. the schema.
  void script(const char* sql, const char* what) {
    Result result(PQexec(conn_, sql));
    if (!result || !succeeded(result.get())) {
      throw ServerError(std::string(what) + " failed on the records server: " + errorOf(result.get()));
    }
  }

  // As run, but returns a failed result instead of throwing (the caller rolls back to a savepoint).
  Result tryRun(const std::string& sql, const std::vector<Param>& params = {}) {
    std::vector<const char*> values;
    values.reserve(params.size());
    for (const Param& param : params) values.push_back(param ? param->c_str() : nullptr);
    Result result(
        PQexecParams(conn_, sql.c_str(), static_cast<int>(values.size()), nullptr, values.data(), nullptr, nullptr, 0));
    if (!result) throw ServerError("the records server connection failed: " + trimmed(PQerrorMessage(conn_)));
    return result;
  }

  std::string errorOf(const PGresult* result) const {
    const char* primary = result ? PQresultErrorField(result, PG_DIAG_MESSAGE_PRIMARY) : nullptr;
    return primary ? primary : trimmed(PQerrorMessage(conn_));
  }

 private:
  PGconn* conn_ = nullptr;
};

std::string value(const PGresult* result, int row, int column) { return PQgetvalue(result, row, column); }

constexpr const char* kInsertSession =
    "INSERT INTO sessions (global_key, session_key, station_id, user_name, scene, scenario, difficulty, seed, state, "
    "message, total, passed, elapsed, start_stamp, end_stamp, recorded_at, bag_path, result_path, software_version, "
    "final_state_hash, frames, annotation, station, events_dropped) VALUES ($1, $2, current_user, $3, $4, $5, $6, $7, "
    "$8, $9, $10, $11, $12, $13, $14, $15, $16, $17, $18, $19, $20, $21, $22, $23) "
    "ON CONFLICT (global_key) DO NOTHING RETURNING id";

// A PostgreSQL array literal of `count` elements ("{1,2,NULL}"); text elements quoted with " and \ escaped.
template <typename Element>
std::string arrayLiteral(std::size_t count, Element&& element) {
  std::string text = "{";
  for (std::size_t i = 0; i < count; ++i) {
    if (i > 0) text += ',';
    text += element(i);
  }
  return text + "}";
}

std::string quotedElement(const std::string& value) {
  std::string text = "\"";
  for (const char c : value) {
    if (c == '"' || c == '\\') text += '\\';
    text += c;
  }
  return text + "\"";
}

std::string numberElement(double x) { return std::isfinite(x) ? formatNumber(x) : "NULL"; }

// All samples in one statement (unnest of one array per column): a session's thousands of rows in one round trip.
void uploadTrajectory(Connection& server, const std::string& session_id, const std::vector<TrajectorySample>& t) {
  const std::size_t n = t.size();
  std::vector<Param> params{session_id};
  params.push_back(arrayLiteral(n, [](std::size_t i) { return std::to_string(i); }));
  params.push_back(arrayLiteral(n, [&](std::size_t i) { return std::to_string(t[i].frame); }));
  params.push_back(arrayLiteral(n, [&](std::size_t i) { return numberElement(t[i].time); }));
  params.push_back(arrayLiteral(n, [&](std::size_t i) { return quotedElement(t[i].source); }));
  params.push_back(arrayLiteral(n, [&](std::size_t i) { return quotedElement(t[i].frame_id); }));
  for (int k = 0; k < 3; ++k) {
    params.push_back(arrayLiteral(n, [&](std::size_t i) { return numberElement(t[i].position[k]); }));
  }
  for (int k = 0; k < 4; ++k) {
    params.push_back(arrayLiteral(n, [&](std::size_t i) { return numberElement(t[i].orientation[k]); }));
  }
  params.push_back(arrayLiteral(n, [&](std::size_t i) { return std::string(t[i].valid ? "1" : "0"); }));
  server.run(
      "INSERT INTO trajectory_samples (session_id, position, frame, time, source, frame_id, x, y, z, qx, qy, qz, qw, "
      "valid) SELECT $1::bigint, * FROM unnest($2::integer[], $3::bigint[], $4::float8[], $5::text[], $6::text[], "
      "$7::float8[], $8::float8[], $9::float8[], $10::float8[], $11::float8[], $12::float8[], $13::float8[], "
      "$14::integer[])",
      params, "uploading a trajectory");
}

// The session's rows on the server; false (with the server's reason) when the server refused it.
enum class Upload { kInserted, kAlreadyThere, kRefused };

Upload uploadSession(Connection& server, const SessionRecord& s, std::string* reason) {
  server.run("SAVEPOINT one_session", {}, "a savepoint");
  Result inserted = server.tryRun(kInsertSession, {s.global_key,
                                                   sessionKey(s),
                                                   s.user.empty() ? "guest" : s.user,
                                                   s.scene,
                                                   s.scenario,
                                                   s.difficulty,
                                                   std::to_string(s.seed),
                                                   s.state,
                                                   s.message,
                                                   formatNumber(s.total),
                                                   s.passed ? "1" : "0",
                                                   formatNumber(s.elapsed),
                                                   formatNumber(s.start_stamp),
                                                   formatNumber(s.end_stamp),
                                                   s.recorded_at,
                                                   s.bag_path,
                                                   s.result_path,
                                                   s.software_version,
                                                   s.final_state_hash,
                                                   std::to_string(s.frames),
                                                   s.annotation,
                                                   s.station,
                                                   std::to_string(s.events_dropped)});
  if (!succeeded(inserted.get())) {
    *reason = server.errorOf(inserted.get());
    server.run("ROLLBACK TO SAVEPOINT one_session", {}, "a rollback to a savepoint");
    return Upload::kRefused;
  }
  if (PQntuples(inserted.get()) == 0) {
    // Its key is there: sent before (and acknowledged now). Its trajectory may have been attached here since
    // (Store::attachTrajectories): then the server gets it now, once.
    if (!s.trajectory.empty()) {
      Result existing = server.run(
          "SELECT s.id, EXISTS (SELECT 1 FROM trajectory_samples t WHERE t.session_id = s.id) FROM sessions s "
          "WHERE s.global_key = $1",
          {s.global_key}, "checking a re-sent session's trajectory");
      if (PQntuples(existing.get()) == 1 && value(existing.get(), 0, 1) == "f") {
        uploadTrajectory(server, value(existing.get(), 0, 0), s.trajectory);
      }
    }
    return Upload::kAlreadyThere;
  }
  const std::string id = value(inserted.get(), 0, 0);
  // Each table's rows in one statement (unnest of one array per column): a few round trips per session, not one per
  // row.
  const auto positions = [](std::size_t n) { return arrayLiteral(n, [](std::size_t i) { return std::to_string(i); }); };
  if (!s.items.empty()) {
    const auto& v = s.items;
    server.run(
        "INSERT INTO score_items (session_id, position, name, value, unit, weight, points) SELECT $1::bigint, * FROM "
        "unnest($2::integer[], $3::text[], $4::float8[], $5::text[], $6::float8[], $7::float8[])",
        {id, positions(v.size()), arrayLiteral(v.size(), [&](std::size_t i) { return quotedElement(v[i].name); }),
         arrayLiteral(v.size(), [&](std::size_t i) { return numberElement(v[i].value); }),
         arrayLiteral(v.size(), [&](std::size_t i) { return quotedElement(v[i].unit); }),
         arrayLiteral(v.size(), [&](std::size_t i) { return numberElement(v[i].weight); }),
         arrayLiteral(v.size(), [&](std::size_t i) { return numberElement(v[i].points); })},
        "uploading the score items");
  }
  if (!s.groups.empty()) {
    const auto& v = s.groups;
    server.run(
        "INSERT INTO score_groups (session_id, position, name, points, weight) SELECT $1::bigint, * FROM "
        "unnest($2::integer[], $3::text[], $4::float8[], $5::float8[])",
        {id, positions(v.size()), arrayLiteral(v.size(), [&](std::size_t i) { return quotedElement(v[i].name); }),
         arrayLiteral(v.size(), [&](std::size_t i) { return numberElement(v[i].points); }),
         arrayLiteral(v.size(), [&](std::size_t i) { return numberElement(v[i].weight); })},
        "uploading the factor groups");
  }
  if (!s.events.empty()) {
    const auto& v = s.events;
    std::vector<Param> params{id,
                              positions(v.size()),
                              arrayLiteral(v.size(), [&](std::size_t i) { return numberElement(v[i].time); }),
                              arrayLiteral(v.size(), [&](std::size_t i) { return quotedElement(v[i].kind); }),
                              arrayLiteral(v.size(), [&](std::size_t i) { return quotedElement(v[i].item); }),
                              arrayLiteral(v.size(), [&](std::size_t i) { return quotedElement(v[i].slot); }),
                              arrayLiteral(v.size(), [&](std::size_t i) { return quotedElement(v[i].instrument); })};
    for (int axis = 0; axis < 3; ++axis) {
      params.push_back(arrayLiteral(v.size(), [&](std::size_t i) { return numberElement(v[i].position[axis]); }));
    }
    params.push_back(arrayLiteral(v.size(), [&](std::size_t i) { return numberElement(v[i].points); }));
    server.run(
        "INSERT INTO penalty_events (session_id, position, time, kind, item, slot, instrument, x, y, z, points) "
        "SELECT $1::bigint, * FROM unnest($2::integer[], $3::float8[], $4::text[], $5::text[], $6::text[], "
        "$7::text[], $8::float8[], $9::float8[], $10::float8[], $11::float8[])",
        params, "uploading the penalty events");
  }
  if (!s.trajectory.empty()) uploadTrajectory(server, id, s.trajectory);
  return Upload::kInserted;
}

void hello(Connection& server) {
  server.run("SELECT records_hello($1)", {std::to_string(Store::kSchemaVersion)}, "the station's schema check");
}

}  // namespace

bool installServerSchema(const std::string& owner_connection) {
  Connection server(owner_connection);
  server.run("BEGIN", {}, "BEGIN");
  Result installed = server.run("SELECT to_regclass('public.schema_info') IS NOT NULL", {}, "reading the schema");
  if (value(installed.get(), 0, 0) == "t") {
    Result version = server.run("SELECT version FROM schema_info", {}, "reading the schema version");
    const std::string found = PQntuples(version.get()) ? value(version.get(), 0, 0) : "none";
    server.run("ROLLBACK", {}, "ROLLBACK");
    if (found == std::to_string(Store::kSchemaVersion)) return false;
    throw ServerError("the records server has schema version " + found + ", this software " +
                      std::to_string(Store::kSchemaVersion) + "; no migration between them exists yet");
  }
  server.script(serverSchemaSql(), "installing the records schema");
  server.run("INSERT INTO schema_info (version, min_station_version) VALUES ($1, $2)",
             {std::to_string(Store::kSchemaVersion), std::to_string(kMinStationSchemaVersion)},
             "recording the schema version");
  server.run("COMMIT", {}, "COMMIT");
  return true;
}

void signInOnServer(const std::string& user_connection, const std::string& station) {
  Connection server(user_connection);
  server.run("SELECT records_sign_in($1)", {station}, "signing in");
}

SyncReport syncWithServer(Store& store, const std::string& station_connection, const SyncOptions& options) {
  if (options.batch == 0) throw ServerError("sync: the batch size must be at least 1");
  SyncReport report;
  Connection server(station_connection);

  // Down: users, then the courses assigned to them, from one snapshot.
  std::vector<Store::ServerUser> users;
  std::vector<CourseAssignment> assignments;
  server.run("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY", {}, "BEGIN");
  hello(server);
  {
    Result rows = server.run("SELECT name, role, deleted_at IS NOT NULL FROM users ORDER BY name", {}, "reading users");
    for (int row = 0; row < PQntuples(rows.get()); ++row) {
      users.push_back({value(rows.get(), row, 0), value(rows.get(), row, 1), value(rows.get(), row, 2) == "t"});
    }
    Result courses = server.run(
        "SELECT user_name, course_name, course_file, course_text, coalesce(assigned_by, ''), assigned_at "
        "FROM course_assignments ORDER BY user_name",
        {}, "reading course assignments");
    for (int row = 0; row < PQntuples(courses.get()); ++row) {
      assignments.push_back({value(courses.get(), row, 0), value(courses.get(), row, 1), value(courses.get(), row, 2),
                             value(courses.get(), row, 3), value(courses.get(), row, 4), value(courses.get(), row, 5)});
    }
  }
  server.run("COMMIT", {}, "COMMIT");
  report.users_changed = store.applyServerUsers(users);
  for (const CourseAssignment& assignment : assignments) {
    const std::optional<User> trainee = store.findUser(assignment.user);
    if (!trainee || trainee->role != Role::kTrainee) continue;
    store.applyServerAssignment(assignment);
    ++report.assignments;
  }

  // Trajectories written since the sessions were stored (the last day's; see Store::attachTrajectories).
  const auto day_ago = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now() - std::chrono::hours(24));
  std::tm utc{};
  gmtime_r(&day_ago, &utc);
  char since[32];
  std::strftime(since, sizeof(since), "%Y-%m-%dT%H:%M:%SZ", &utc);
  report.trajectories_attached = store.attachTrajectories(since, &report.trajectory_errors);

  // Up: the outbox in batches, one server transaction each, marked here only after the server's COMMIT.
  std::int64_t after_id = 0;
  for (;;) {
    const std::vector<SessionRecord> batch = store.unsyncedSessions(after_id, options.batch);
    if (batch.empty()) break;
    after_id = batch.back().id;
    std::vector<std::string> acknowledged;
    SyncReport counts;
    server.run("BEGIN", {}, "BEGIN");
    hello(server);
    for (const SessionRecord& session : batch) {
      std::string reason;
      switch (uploadSession(server, session, &reason)) {
        case Upload::kInserted:
          ++counts.uploaded;
          acknowledged.push_back(session.global_key);
          break;
        case Upload::kAlreadyThere:
          ++counts.already_on_server;
          acknowledged.push_back(session.global_key);
          break;
        case Upload::kRefused:
          ++counts.held;
          counts.held_reasons.push_back(session.global_key + " " + session.user + ": " + reason);
          break;
      }
    }
    server.run("COMMIT", {}, "COMMIT");
    store.markSynced(acknowledged);
    report.uploaded += counts.uploaded;
    report.already_on_server += counts.already_on_server;
    report.held += counts.held;
    report.held_reasons.insert(report.held_reasons.end(), counts.held_reasons.begin(), counts.held_reasons.end());
    if (options.pause_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(options.pause_ms));
  }
  return report;
}

namespace {

// The sessions the connection's role may read (row-level security decides), with their score items, and with their
// factor groups and penalty events when `everything`; in the order they were trained.
std::vector<SessionRecord> readSessions(Connection& server, const CentreFilter& filter, bool everything) {
  std::vector<SessionRecord> sessions;
  Result rows = server.run(
      "SELECT id, user_name, scene, scenario, difficulty, seed, state, message, total, passed, elapsed, start_stamp, "
      "end_stamp, recorded_at, software_version, final_state_hash, frames, station_id, annotation, global_key, "
      "events_dropped FROM sessions WHERE ($1 = '' OR station_id = $1) AND ($2 = '' OR user_name = $2) AND ($3 = '' OR "
      "scene = $3) "
      "AND ($4 = '' OR left(recorded_at, 10) >= $4) AND ($5 = '' OR left(recorded_at, 10) <= $5) "
      "ORDER BY start_stamp, id",
      {filter.station, filter.trainee, filter.scene, filter.from_date, filter.to_date},
      "reading the centre's sessions");
  std::map<std::int64_t, std::size_t> index;
  for (int row = 0; row < PQntuples(rows.get()); ++row) {
    const auto text = [&](int column) { return value(rows.get(), row, column); };
    SessionRecord s;
    s.id = std::stoll(text(0));
    s.user = text(1);
    s.scene = text(2);
    s.scenario = text(3);
    s.difficulty = text(4);
    s.seed = static_cast<std::uint32_t>(std::stoul(text(5)));
    s.state = text(6);
    s.message = text(7);
    s.total = std::stod(text(8));
    s.passed = text(9) == "1";
    s.elapsed = std::stod(text(10));
    s.start_stamp = std::stod(text(11));
    s.end_stamp = std::stod(text(12));
    s.recorded_at = text(13);
    s.software_version = text(14);
    s.final_state_hash = text(15);
    s.frames = std::stoull(text(16));
    s.station = text(17);
    s.annotation = text(18);
    s.global_key = text(19);
    s.events_dropped = std::stoull(text(20));
    index[s.id] = sessions.size();
    sessions.push_back(std::move(s));
  }
  if (!sessions.empty()) {
    const std::string ids =
        arrayLiteral(sessions.size(), [&](std::size_t i) { return std::to_string(sessions[i].id); });
    Result items = server.run(
        "SELECT session_id, name, value, unit, weight, points FROM score_items WHERE session_id = ANY($1::bigint[]) "
        "ORDER BY session_id, position",
        {ids}, "reading score items");
    for (int row = 0; row < PQntuples(items.get()); ++row) {
      const auto text = [&](int column) { return value(items.get(), row, column); };
      sessions[index.at(std::stoll(text(0)))].items.push_back(
          {text(1), std::stod(text(2)), text(3), std::stod(text(4)), std::stod(text(5))});
    }
  }
  if (everything && !sessions.empty()) {
    const std::string ids =
        arrayLiteral(sessions.size(), [&](std::size_t i) { return std::to_string(sessions[i].id); });
    Result groups = server.run(
        "SELECT session_id, name, points, weight FROM score_groups WHERE session_id = ANY($1::bigint[]) "
        "ORDER BY session_id, position",
        {ids}, "reading factor groups");
    for (int row = 0; row < PQntuples(groups.get()); ++row) {
      const auto text = [&](int column) { return value(groups.get(), row, column); };
      sessions[index.at(std::stoll(text(0)))].groups.push_back({text(1), std::stod(text(2)), std::stod(text(3))});
    }
    Result events = server.run(
        "SELECT session_id, time, kind, item, slot, instrument, x, y, z, points FROM penalty_events "
        "WHERE session_id = ANY($1::bigint[]) ORDER BY session_id, position",
        {ids}, "reading penalty events");
    for (int row = 0; row < PQntuples(events.get()); ++row) {
      const auto text = [&](int column) { return value(events.get(), row, column); };
      const auto coordinate = [&](int column) {
        return PQgetisnull(events.get(), row, column) ? std::nan("") : std::stod(text(column));
      };
      PenaltyEventRecord e;
      e.time = std::stod(text(1));
      e.kind = text(2);
      e.item = text(3);
      e.slot = text(4);
      e.instrument = text(5);
      for (int axis = 0; axis < 3; ++axis) e.position[axis] = coordinate(6 + axis);
      e.points = std::stod(text(9));
      sessions[index.at(std::stoll(text(0)))].events.push_back(std::move(e));
    }
  }
  return sessions;
}

}  // namespace

CentreData fetchCentre(const std::string& instructor_connection, const CentreFilter& filter) {
  matches(SessionRecord{}, filter);  // a malformed date is refused before anything is asked
  Connection server(instructor_connection);
  CentreData data;
  server.run("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY", {}, "BEGIN");
  // Row-level security answers for the instructor: their own and their supervised trainees' sessions only.
  data.sessions = readSessions(server, filter, false);
  Result courses = server.run(
      "SELECT user_name, course_name, course_file, course_text, coalesce(assigned_by, ''), assigned_at "
      "FROM course_assignments ORDER BY user_name",
      {}, "reading course assignments");
  for (int row = 0; row < PQntuples(courses.get()); ++row) {
    data.assignments.push_back({value(courses.get(), row, 0), value(courses.get(), row, 1),
                                value(courses.get(), row, 2), value(courses.get(), row, 3),
                                value(courses.get(), row, 4), value(courses.get(), row, 5)});
  }
  Result group = server.run("SELECT trainee FROM supervision ORDER BY trainee", {}, "reading the group");
  for (int row = 0; row < PQntuples(group.get()); ++row) data.trainees.push_back(value(group.get(), row, 0));
  server.run("COMMIT", {}, "COMMIT");
  return data;
}

struct ServerReader::Impl {
  explicit Impl(const std::string& connection) : server(connection) {}
  Connection server;
};

ServerReader::ServerReader(const std::string& connection) : impl_(std::make_unique<Impl>(connection)) {
  // One snapshot for the whole export: sessions and their trajectories agree even while stations sync.
  impl_->server.run("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY", {}, "BEGIN");
}

ServerReader::~ServerReader() = default;

std::vector<SessionRecord> ServerReader::sessions(const SessionFilter& filter) {
  return readSessions(impl_->server, {"", filter.user, filter.scene, "", ""}, true);
}

std::vector<TrajectorySample> ServerReader::trajectory(std::int64_t session_id) {
  Result rows = impl_->server.run(
      "SELECT frame, time, source, frame_id, x, y, z, qx, qy, qz, qw, valid FROM trajectory_samples "
      "WHERE session_id = $1 ORDER BY position",
      {std::to_string(session_id)}, "reading a trajectory");
  std::vector<TrajectorySample> samples;
  samples.reserve(static_cast<std::size_t>(PQntuples(rows.get())));
  for (int row = 0; row < PQntuples(rows.get()); ++row) {
    TrajectorySample t;
    t.frame = std::stoull(value(rows.get(), row, 0));
    t.time = std::stod(value(rows.get(), row, 1));
    t.source = value(rows.get(), row, 2);
    t.frame_id = value(rows.get(), row, 3);
    double* values[] = {&t.position[0],    &t.position[1],    &t.position[2],   &t.orientation[0],
                        &t.orientation[1], &t.orientation[2], &t.orientation[3]};
    for (int k = 0; k < 7; ++k) {
      *values[k] = PQgetisnull(rows.get(), row, 4 + k) ? std::nan("") : std::stod(value(rows.get(), row, 4 + k));
    }
    t.valid = value(rows.get(), row, 11) == "1";
    samples.push_back(std::move(t));
  }
  return samples;
}

}  // namespace eyesi_gui::records
