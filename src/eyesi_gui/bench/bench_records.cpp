// The records benchmark (issue 41): a training centre's two hot paths on both back ends, at 10^4 and 10^5 stored
// sessions. `write_batch50`: 50 new sessions (8 score items each) reach the store — on SQLite through
// Store::recordSession (one transaction each, what a station or a central SQLite import does), on PostgreSQL through
// one `records sync` of a station holding 50 unsynced sessions (connect, users down, one server transaction up, the
// station's marks). `history_query`: the console's history of one trainee (every session with its score items), on
// SQLite through Store::sessions, on PostgreSQL as the trainee's instructor under row-level security. Reported per
// (backend, sessions, op): the median and 95th percentile over the repetitions, and sessions/s for the writes.
// The PostgreSQL server is a throw-away cluster (bench/records_cluster.sh) on this machine, over its Unix socket.
// Usage: bench_records [--quick] [--out FILE]   (quick: 10^3 sessions, fewer repetitions)
#include <libpq-fe.h>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "eyesi_gui/records/server.h"
#include "eyesi_gui/records/store.h"
#include "vrm_scene/cli/cli.h"

namespace records = eyesi_gui::records;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr int kTrainees = 50;
constexpr int kInstructors = 5;  // each supervising 10 trainees
constexpr int kItems = 8;
constexpr int kBatch = 50;
const char* const kScenes[] = {"navigation", "vitrectomy", "membrane_peeling"};

std::string trainee(int k) {
  char name[16];
  std::snprintf(name, sizeof(name), "t%03d", k % kTrainees);
  return name;
}

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

double percentile(std::vector<double> values, double p) {
  std::sort(values.begin(), values.end());
  const double rank = p * (values.size() - 1);
  const std::size_t low = static_cast<std::size_t>(rank);
  const std::size_t high = std::min(low + 1, values.size() - 1);
  return values[low] + (rank - low) * (values[high] - values[low]);
}

records::SessionRecord syntheticSession(int n, std::mt19937& random) {
  std::uniform_real_distribution<double> points(0.0, 100.0);
  records::SessionRecord s;
  s.user = trainee(n);
  s.scene = kScenes[n % 3];
  s.scenario = s.scene;
  s.difficulty = "medium";
  s.seed = static_cast<std::uint32_t>(n);
  s.state = "finished";
  s.passed = true;
  s.total = points(random);
  s.elapsed = 60.0;
  s.start_stamp = 1.8e9 + 100.0 * n;
  s.end_stamp = s.start_stamp + 60.0;
  s.final_state_hash = "0x" + std::to_string(n);
  s.frames = 3600;
  s.station = "bench";
  for (int i = 0; i < kItems; ++i) s.items.push_back({"item" + std::to_string(i), 1.0, "1", 1.0, points(random)});
  return s;
}

void sqliteExec(sqlite3* db, const std::string& sql) {
  char* error = nullptr;
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    const std::string message = error ? error : "?";
    sqlite3_free(error);
    throw std::runtime_error("sqlite: " + message + " in " + sql.substr(0, 80));
  }
}

// N sessions in one transaction, straight through SQL (filling is not what is measured).
void fillSqlite(const std::string& path, int sessions) {
  { records::Store create(path); }
  sqlite3* db = nullptr;
  sqlite3_open(path.c_str(), &db);
  sqliteExec(db, "BEGIN");
  for (int k = 0; k < kTrainees; ++k) {
    sqliteExec(db, "INSERT INTO users (name, role, iterations, created_at) VALUES ('" + trainee(k) +
                       "', 'trainee', 0, '2026-01-01T00:00:00Z')");
  }
  sqliteExec(db,
             "WITH RECURSIVE g(n) AS (SELECT 1 UNION ALL SELECT n + 1 FROM g WHERE n < " + std::to_string(sessions) +
                 ") INSERT INTO sessions (session_key, user_id, scene, scenario, difficulty, seed, state, total, "
                 "passed, elapsed, start_stamp, end_stamp, recorded_at, final_state_hash, frames, station, global_key) "
                 "SELECT 'k' || n, (SELECT id FROM users WHERE name = printf('t%03d', n % 50)), "
                 "CASE n % 3 WHEN 0 THEN 'navigation' WHEN 1 THEN 'vitrectomy' ELSE 'membrane_peeling' END, '', "
                 "'medium', n, 'finished', abs(random() % 10000) / 100.0, 1, 60, 1.7e9 + 100 * n, 1.7e9 + 100 * n + "
                 "60, '2026-01-01T00:00:00Z', '0x' || n, 3600, 'bench', 'g' || n FROM g");
  sqliteExec(db,
             "WITH RECURSIVE p(i) AS (SELECT 0 UNION ALL SELECT i + 1 FROM p WHERE i < 7) INSERT INTO score_items "
             "(session_id, position, name, value, unit, weight, points) SELECT s.id, p.i, 'item' || p.i, 1, '1', 1, "
             "abs(random() % 10000) / 100.0 FROM sessions s, p");
  sqliteExec(db, "UPDATE sessions SET synced_at = '2026-01-01T00:00:00Z'");
  sqliteExec(db, "COMMIT");
  sqliteExec(db, "ANALYZE");
  sqlite3_close(db);
}

class Pg {
 public:
  explicit Pg(const std::string& connection) : conn_(PQconnectdb(connection.c_str())) {
    if (PQstatus(conn_) != CONNECTION_OK) throw std::runtime_error("postgres: " + std::string(PQerrorMessage(conn_)));
  }
  ~Pg() { PQfinish(conn_); }
  int exec(const std::string& sql, const std::vector<std::string>& params = {}) {
    std::vector<const char*> values;
    for (const auto& p : params) values.push_back(p.c_str());
    PGresult* result = params.empty() ? PQexec(conn_, sql.c_str())
                                      : PQexecParams(conn_, sql.c_str(), static_cast<int>(values.size()), nullptr,
                                                     values.data(), nullptr, nullptr, 0);
    const ExecStatusType status = PQresultStatus(result);
    const int rows = PQntuples(result);
    const std::string error = PQresultErrorMessage(result);
    PQclear(result);
    if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK) {
      throw std::runtime_error("postgres: " + error + " in " + sql.substr(0, 80));
    }
    return rows;
  }

 private:
  PGconn* conn_;
};

void fillPostgres(const std::string& owner, int sessions) {
  if (!records::installServerSchema(owner)) throw std::runtime_error("schema already installed");
  Pg pg(owner);
  pg.exec("SELECT records_create_station('station_bench', 'bench-password-1')");
  for (int k = 0; k < kTrainees; ++k) {
    pg.exec("SELECT records_create_user('" + trainee(k) + "', 'trainee', 'bench-password-1')");
    pg.exec("INSERT INTO station_signins (station, user_name) VALUES ('station_bench', '" + trainee(k) + "')");
  }
  for (int i = 0; i < kInstructors; ++i) {
    pg.exec("SELECT records_create_user('i" + std::to_string(i) + "', 'instructor', 'bench-password-1')");
    for (int k = i * 10; k < i * 10 + 10; ++k) {
      pg.exec("SELECT records_supervise('i" + std::to_string(i) + "', '" + trainee(k) + "')");
    }
  }
  pg.exec(
      "INSERT INTO sessions (global_key, session_key, station_id, user_name, scene, scenario, difficulty, seed, "
      "state, total, passed, elapsed, start_stamp, end_stamp, recorded_at, final_state_hash, frames, station) "
      "SELECT gen_random_uuid()::text, md5(n::text), 'station_bench', 't' || lpad((n % 50)::text, 3, '0'), "
      "(ARRAY['navigation', 'vitrectomy', 'membrane_peeling'])[1 + n % 3], '', 'medium', n, 'finished', "
      "random() * 100, 1, 60, 1.7e9 + 100 * n, 1.7e9 + 100 * n + 60, '2026-01-01T00:00:00Z', '0x' || n, 3600, "
      "'bench' FROM generate_series(1, " +
      std::to_string(sessions) + ") n");
  pg.exec(
      "INSERT INTO score_items (session_id, position, name, value, unit, weight, points) SELECT s.id, p, "
      "'item' || p, 1, '1', 1, random() * 100 FROM sessions s, generate_series(0, 7) p");
  pg.exec("VACUUM ANALYZE");
}

json row(const std::string& backend, int sessions, const std::string& op, const std::vector<double>& ms,
         int per_rep_sessions = 0) {
  json r{{"suite", "records"},
         {"backend", backend},
         {"sessions", sessions},
         {"op", op},
         {"ms_p50", percentile(ms, 0.5)},
         {"ms_p95", percentile(ms, 0.95)},
         {"reps", ms.size()}};
  if (per_rep_sessions > 0) r["sessions_per_s_p50"] = per_rep_sessions * 1000.0 / percentile(ms, 0.5);
  std::printf(
      "%-10s %7d  %-14s p50 %9.2f ms  p95 %9.2f ms%s\n", backend.c_str(), sessions, op.c_str(), percentile(ms, 0.5),
      percentile(ms, 0.95),
      per_rep_sessions > 0
          ? ("  (" + std::to_string(static_cast<int>(r["sessions_per_s_p50"].get<double>())) + " sessions/s)").c_str()
          : "");
  std::fflush(stdout);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  namespace po = vrm_sim::cli::po;
  vrm_sim::cli::CommandLine cli("bench_records", "[--quick] [--out FILE]",
                                "Records back ends: writes and the instructor's history query, SQLite vs PostgreSQL.",
                                "");
  cli.add()("quick", "10^3 sessions, fewer repetitions")("out", po::value<std::string>()->value_name("FILE"),
                                                         "the JSON results");
  if (const auto status = cli.parse(argc, argv)) return *status;
  const bool quick = cli.values().count("quick") != 0;
  const std::vector<int> sizes = quick ? std::vector<int>{1000} : std::vector<int>{10000, 100000};
  const int reps = quick ? 5 : 20;

  char pattern[] = "/tmp/eyesi-bench-records-XXXXXX";
  if (mkdtemp(pattern) == nullptr) return 1;
  const fs::path tmp(pattern);
  // The cluster's unprivileged user must reach its folder inside (the stores in it are 0600 on their own).
  fs::permissions(tmp, fs::perms::others_exec | fs::perms::group_exec, fs::perm_options::add);
  const std::string helper = std::string(EYESI_GUI_SOURCE_DIR) + "/bench/records_cluster.sh";
  // A cluster per size: roles are the cluster's, not a database's, and each size starts from an empty server.
  const auto startCluster = [&](const std::string& cluster) {
    FILE* pipe = popen((helper + " start " + cluster).c_str(), "r");
    char line[512] = {0};
    const bool read = pipe != nullptr && std::fgets(line, sizeof(line), pipe) != nullptr;
    if (pipe == nullptr || pclose(pipe) != 0 || !read) {
      throw std::runtime_error("cannot start a PostgreSQL cluster (" + helper + ")");
    }
    std::string connection = line;
    connection.erase(connection.find_last_not_of('\n') + 1);
    return connection;
  };
  json rows = json::array();
  std::vector<std::string> clusters;
  int status = 0;
  try {
    std::mt19937 random(41);
    for (const int n : sizes) {
      // SQLite: one store of n sessions.
      const std::string central = (tmp / ("central_" + std::to_string(n) + ".sqlite")).string();
      fillSqlite(central, n);
      records::Store store(central);
      std::vector<double> history, writes;
      for (int r = 0; r < reps; ++r) {
        const auto start = std::chrono::steady_clock::now();
        const auto sessions = store.sessions({trainee(r * 7), ""});
        history.push_back(msSince(start));
        if (sessions.size() < static_cast<std::size_t>(n / kTrainees)) throw std::runtime_error("short history");
      }
      rows.push_back(row("sqlite", n, "history_query", history));
      int next = n + 1;
      for (int r = 0; r < reps; ++r) {
        std::vector<records::SessionRecord> batch;
        for (int i = 0; i < kBatch; ++i) batch.push_back(syntheticSession(next++, random));
        const auto start = std::chrono::steady_clock::now();
        for (const auto& s : batch) store.recordSession(s);
        writes.push_back(msSince(start));
      }
      rows.push_back(row("sqlite", n, "write_batch50", writes, kBatch));

      // PostgreSQL: a database of n sessions; a station syncing 50 at a time; the instructor's query under RLS.
      const std::string cluster = (tmp / ("pg_" + std::to_string(n))).string();
      clusters.push_back(cluster);
      const std::string owner = startCluster(cluster);
      fillPostgres(owner, n);
      std::string station_connection = owner;
      station_connection.replace(station_connection.find("user=postgres"), 13, "user=station_bench");
      records::Store station((tmp / ("station_" + std::to_string(n) + ".sqlite")).string());
      std::vector<double> syncs, queries;
      for (int r = 0; r < reps; ++r) {
        for (int i = 0; i < kBatch; ++i) station.recordSession(syntheticSession(next++, random));
        const auto start = std::chrono::steady_clock::now();
        const records::SyncReport report = records::syncWithServer(station, station_connection, {kBatch, 0});
        syncs.push_back(msSince(start));
        if (report.uploaded != kBatch) throw std::runtime_error("sync uploaded " + std::to_string(report.uploaded));
      }
      rows.push_back(row("postgresql", n, "write_batch50", syncs, kBatch));
      Pg instructor(owner);
      for (int r = 0; r < reps; ++r) {
        const int k = (r * 7) % kTrainees;
        instructor.exec("SET ROLE i" + std::to_string(k / 10));
        const auto start = std::chrono::steady_clock::now();
        const int got = instructor.exec(
            "SELECT s.id, s.global_key, s.scene, s.scenario, s.difficulty, s.state, s.total, s.start_stamp, "
            "s.recorded_at, s.station, i.position, i.name, i.value, i.unit, i.weight, i.points FROM sessions s "
            "LEFT JOIN score_items i ON i.session_id = s.id WHERE s.user_name = $1 "
            "ORDER BY s.start_stamp, s.id, i.position",
            {trainee(k)});
        queries.push_back(msSince(start));
        instructor.exec("RESET ROLE");
        if (got < n / kTrainees * kItems) throw std::runtime_error("short history on the server");
      }
      rows.push_back(row("postgresql", n, "history_query", queries));
      std::system((helper + " stop " + cluster + " >/dev/null").c_str());
      clusters.pop_back();
    }
  } catch (const std::exception& e) {
    std::cerr << "bench_records: " << e.what() << '\n';
    status = 1;
  }
  for (const std::string& cluster : clusters) std::system((helper + " stop " + cluster + " >/dev/null").c_str());
  fs::remove_all(tmp);
  if (status != 0) return status;
  const json result{{"command", std::string("./scripts/bench.sh ") + (quick ? "--quick " : "") + "records"},
                    {"cores", sysconf(_SC_NPROCESSORS_ONLN)},
                    {"rows", rows}};
  if (cli.values().count("out")) {
    std::ofstream out(cli.values()["out"].as<std::string>());
    out << result.dump(1) << '\n';
  }
  return 0;
}
