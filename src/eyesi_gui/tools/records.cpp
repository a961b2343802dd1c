// records: the training-records database from the command line (import results from another station or a USB
// stick, export for a spreadsheet, check a database after a crash, add users). ROS-free; `rosrun eyesi_gui records`.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "eyesi_gui/records/centre.h"
#include "eyesi_gui/records/export.h"
#include "eyesi_gui/records/server.h"
#include "eyesi_gui/records/store.h"
#include "vrm_scene/cli/cli.h"

namespace {

namespace records = eyesi_gui::records;

constexpr const char* kCommandHelp =
    "Commands:\n"
    "  import FILE_OR_FOLDER... [--user NAME]   import scenario result JSON files (folders: every *.result.json)\n"
    "  export-csv [--user U] [--scene S] [--table items|groups|events] [--out FILE]\n"
    "                                           score items (default), factor groups or penalty events as CSV\n"
    "                                           (RFC 4180; stdout by default)\n"
    "  export --out-dir DIR [--user U] [--scene S] [--pseudonym-key FILE] [--server CONNINFO]\n"
    "                                           tidy CSV tables for research: sessions, score_items, score_groups,\n"
    "                                           penalty_events, trajectories (README: data dictionary); with a key\n"
    "                                           file (created if missing) users and stations are pseudonymised;\n"
    "                                           --server: from the records server (what your role may read)\n"
    "  check                                    integrity report of the database (exit 0 ok, 1 damaged)\n"
    "  add-user NAME --role trainee|instructor [--pin PIN]   (--pin - reads the PIN from stdin)\n"
    "  set-pin NAME --pin PIN                   set (or with an empty PIN clear) a user's PIN\n"
    "  list [--user U]                          sessions, oldest first\n"
    "  users                                    users and roles\n"
    "Training centre (a records server on PostgreSQL; CONNINFO is libpq's key=value form, the password from\n"
    "PGPASSWORD or ~/.pgpass):\n"
    "  server-init --server CONNINFO            install the server schema (as the database owner)\n"
    "  sign-in --server CONNINFO --station S    sign the connection's user in on station S (as that user)\n"
    "  centre --server CONNINFO [--station S] [--user U] [--scene S] [--from YYYY-MM-DD] [--to YYYY-MM-DD]\n"
    "                                           as an instructor: the sessions of your trainees on every station,\n"
    "                                           learning curves per trainee and module, the group's course progress\n"
    "  sync --server CONNINFO [--batch N] [--pause-ms MS] [--every S]\n"
    "                                           users and courses down, this station's sessions up (as the\n"
    "                                           station's own login); exit 0 all synced, 3 some held;\n"
    "                                           --every S: again every S seconds, until stopped\n"
    "--db defaults to $HOME/.ros/eyesi/records.sqlite\n";

struct UsageError {
  std::string message;
};

struct Arguments {
  std::string command;
  std::vector<std::string> positional;
  std::map<std::string, std::string> options;  // "--user" → value

  std::string option(const std::string& name) const {
    const auto it = options.find(name);
    return it == options.end() ? "" : it->second;
  }
  bool has(const std::string& name) const { return options.count(name) != 0; }
};

void allowOnly(const Arguments& args, const std::vector<std::string>& allowed) {
  for (const auto& [name, value] : args.options) {
    if (name != "--db" && std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
      throw UsageError{args.command + " does not take " + name};
    }
  }
}

std::string defaultDatabase() {
  const char* home = std::getenv("HOME");
  if (home == nullptr || *home == '\0') throw records::StoreError("HOME is not set; pass --db PATH");
  return std::string(home) + "/.ros/eyesi/records.sqlite";
}

// "-" reads the PIN from stdin, so it need not appear in the shell history or the process list.
std::string pinArgument(const Arguments& args) {
  std::string pin = args.option("--pin");
  if (pin == "-") {
    if (!std::getline(std::cin, pin)) pin.clear();
  }
  return pin;
}

int runImport(records::Store& store, const Arguments& args) {
  if (args.positional.empty()) throw UsageError{"import needs at least one file or folder"};
  const std::string user = args.option("--user");
  int inserted = 0, existing = 0, failed = 0;
  for (const std::string& target : args.positional) {
    std::vector<std::string> files{target};
    std::error_code ec;
    if (std::filesystem::is_directory(target, ec)) {
      files = records::Store::findResultFiles(target);
      if (files.empty()) std::cerr << "records: " << target << ": no *.result.json files\n";
    }
    for (const std::string& file : files) {
      try {
        const records::ImportResult result = store.importResultFile(file, user);
        std::cout << (result.inserted ? "inserted " : "already stored ") << result.session_id << ' ' << file << '\n';
        ++(result.inserted ? inserted : existing);
      } catch (const records::StoreError& e) {
        std::cerr << "records: " << e.what() << '\n';
        ++failed;
      }
    }
  }
  std::cout << inserted << " inserted, " << existing << " already stored, " << failed << " failed\n";
  return failed == 0 ? 0 : 1;
}

int runExport(const records::Store& store, const Arguments& args) {
  if (!args.positional.empty()) throw UsageError{"export-csv takes no positional arguments"};
  const records::SessionFilter filter{args.option("--user"), args.option("--scene")};
  const std::string table = args.has("--table") ? args.option("--table") : "items";
  if (table != "items" && table != "groups" && table != "events") {
    throw UsageError{"--table must be items, groups or events, not '" + table + "'"};
  }
  const auto writeTable = [&](std::ostream& out) {
    if (table == "groups") {
      store.exportGroupsCsv(out, filter);
    } else if (table == "events") {
      store.exportEventsCsv(out, filter);
    } else {
      store.exportCsv(out, filter);
    }
  };
  if (!args.has("--out") || args.option("--out") == "-") {
    writeTable(std::cout);
    return 0;
  }
  const std::string out_path = args.option("--out");
  std::ofstream out(out_path, std::ios::binary);
  if (!out) throw records::StoreError(out_path + ": cannot write the CSV file");
  writeTable(out);
  out.close();
  if (!out) throw records::StoreError(out_path + ": writing the CSV file failed");
  return 0;
}

int runCheck(const std::string& db, const Arguments& args) {
  if (!args.positional.empty()) throw UsageError{"check takes no arguments"};
  // Not through Store: opening a Store would create a missing file and migrate an old one.
  std::error_code ec;
  if (!std::filesystem::exists(db, ec)) throw records::StoreError(db + ": no such database file");
  const std::string report = records::Store::integrityCheck(db);
  std::cout << report << '\n';
  if (report == "ok") return 0;
  std::cerr << "records: " << db << ": the database is damaged (see the report above)\n";
  return 1;
}

int runAddUser(records::Store& store, const Arguments& args) {
  if (args.positional.size() != 1) throw UsageError{"add-user needs exactly one NAME"};
  const std::string role_text = args.option("--role");
  if (role_text != "trainee" && role_text != "instructor") throw UsageError{"--role must be trainee or instructor"};
  const records::Role role = role_text == "instructor" ? records::Role::kInstructor : records::Role::kTrainee;
  const records::User user = store.addUser(args.positional[0], role, pinArgument(args));
  std::cout << "added " << records::toString(user.role) << ' ' << user.name << " (id " << user.id << ", "
            << (user.has_pin ? "with PIN" : "no PIN") << ")\n";
  return 0;
}

int runSetPin(records::Store& store, const Arguments& args) {
  if (args.positional.size() != 1) throw UsageError{"set-pin needs exactly one NAME"};
  if (!args.has("--pin")) throw UsageError{"set-pin needs --pin"};
  store.setPin(args.positional[0], pinArgument(args));
  std::cout << "PIN of " << args.positional[0] << " updated\n";
  return 0;
}

int runList(const records::Store& store, const Arguments& args) {
  if (!args.positional.empty()) throw UsageError{"list takes no positional arguments"};
  const auto sessions = store.sessions({args.option("--user"), ""});
  std::printf("%6s  %-20s  %-12s  %-18s  %-8s  %-9s  %6s  %5s\n", "id", "recorded_at", "user", "scene", "level",
              "state", "total", "items");
  for (const auto& s : sessions) {
    std::printf("%6lld  %-20s  %-12s  %-18s  %-8s  %-9s  %6.1f  %5zu\n", static_cast<long long>(s.id),
                s.recorded_at.c_str(), s.user.c_str(), s.scene.c_str(), s.difficulty.c_str(), s.state.c_str(), s.total,
                s.items.size());
  }
  std::printf("%zu sessions\n", sessions.size());
  return 0;
}

int runUsers(const records::Store& store, const Arguments& args) {
  if (!args.positional.empty()) throw UsageError{"users takes no arguments"};
  for (const auto& user : store.users()) {
    std::printf("%6lld  %-20s  %-10s  %s\n", static_cast<long long>(user.id), user.name.c_str(),
                records::toString(user.role), user.has_pin ? "PIN" : "no PIN");
  }
  return 0;
}

int positiveOption(const Arguments& args, const std::string& name, int fallback) {
  if (!args.has(name)) return fallback;
  try {
    std::size_t used = 0;
    const int value = std::stoi(args.option(name), &used);
    if (used == args.option(name).size() && value >= 0) return value;
  } catch (const std::exception&) {
  }
  throw UsageError{name + " must be a whole number >= 0, not '" + args.option(name) + "'"};
}

// From the station's store, or with --server from the records server (what the connection's role may read).
int runExportTables(const records::Store* store, const Arguments& args) {
  if (!args.positional.empty()) throw UsageError{"export takes no positional arguments"};
  if (!args.has("--out-dir")) throw UsageError{"export needs --out-dir DIR"};
  records::ExportOptions options;
  options.filter = {args.option("--user"), args.option("--scene")};
  options.pseudonym_key_file = args.option("--pseudonym-key");
  const records::ExportCounts counts =
      store != nullptr ? records::exportTables(*store, args.option("--out-dir"), options)
                       : records::exportServerTables(args.option("--server"), args.option("--out-dir"), options);
  std::cout << counts.sessions << " sessions, " << counts.items << " score items, " << counts.groups
            << " factor groups, " << counts.events << " penalty events, " << counts.samples << " trajectory samples"
            << (options.pseudonym_key_file.empty() ? "" : " (pseudonymised)") << " -> " << args.option("--out-dir")
            << '\n';
  return 0;
}

int runCentre(const Arguments& args) {
  if (!args.positional.empty() || !args.has("--server")) throw UsageError{"centre needs --server CONNINFO"};
  const records::CentreFilter filter{args.option("--station"), args.option("--user"), args.option("--scene"),
                                     args.option("--from"), args.option("--to")};
  const records::CentreData data = records::fetchCentre(args.option("--server"), filter);
  std::cout << data.sessions.size() << " sessions\n";
  for (const records::LearningCurve& curve : records::learningCurves(data.sessions)) {
    std::cout << "curve " << curve.trainee << ' ' << curve.scene << ':';
    for (const double total : curve.totals) std::printf(" %.1f", total);
    std::printf(" (best %.1f)\n", curve.best);
  }
  for (const records::GroupProgressRow& row : records::groupProgress(data.trainees, data.assignments, data.sessions)) {
    std::cout << "progress " << row.trainee << ' ' << (row.course.empty() ? "(no course)" : row.course) << ' '
              << row.steps_passed << '/' << row.steps << (row.problem.empty() ? "" : " unreadable: " + row.problem)
              << '\n';
  }
  return 0;
}

int runSync(records::Store& store, const Arguments& args) {
  if (!args.positional.empty()) throw UsageError{"sync takes no positional arguments"};
  if (!args.has("--server")) throw UsageError{"sync needs --server CONNINFO"};
  records::SyncOptions options;
  options.batch = static_cast<std::size_t>(positiveOption(args, "--batch", 50));
  options.pause_ms = positiveOption(args, "--pause-ms", 0);
  const int every = positiveOption(args, "--every", 0);
  // --every: the station's background sync (a launch file or a systemd service runs it): a round that cannot reach
  // the server is reported and tried again; only a refusal of this station's schema version ends it.
  while (every > 0) {
    try {
      const records::SyncReport report = records::syncWithServer(store, args.option("--server"), options);
      if (report.uploaded + report.already_on_server + report.held + report.users_changed > 0) {
        std::cout << report.uploaded << " uploaded, " << report.already_on_server << " already on the server, "
                  << report.held << " held; " << report.users_changed << " users changed" << std::endl;
      }
    } catch (const records::ServerError& e) {
      std::cerr << "records: " << e.what() << std::endl;
      if (std::string(e.what()).find("station schema version") != std::string::npos) return 1;
    }
    std::this_thread::sleep_for(std::chrono::seconds(every));
  }
  const records::SyncReport report = records::syncWithServer(store, args.option("--server"), options);
  for (const std::string& line : report.held_reasons) std::cout << "held " << line << '\n';
  for (const std::string& line : report.trajectory_errors) std::cerr << "records: " << line << '\n';
  if (report.trajectories_attached > 0) {
    std::cout << report.trajectories_attached << " trajectories attached since their sessions were stored\n";
  }
  std::cout << report.uploaded << " uploaded, " << report.already_on_server << " already on the server, " << report.held
            << " held; " << report.users_changed << " users changed, " << report.assignments << " course assignments\n";
  return report.held == 0 ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  namespace po = vrm_sim::cli::po;
  vrm_sim::cli::CommandLine cli("records", "[--db PATH] COMMAND [ARGS]",
                                "The training-records database: import, export, check, users.", kCommandHelp);
  static const std::vector<std::string> kValued{
      "db",      "user",  "scene",    "out",     "role",          "pin",  "table", "server",
      "station", "batch", "pause-ms", "out-dir", "pseudonym-key", "from", "to",    "every"};
  cli.add()("db", po::value<std::string>()->value_name("PATH"), "the database")(
      "user", po::value<std::string>()->value_name("NAME"), "import: the trainee; export-csv, list: only this user")(
      "scene", po::value<std::string>()->value_name("S"), "export-csv: only this scene")(
      "out", po::value<std::string>()->value_name("FILE"), "export-csv: the CSV file (- or none: stdout)")(
      "table", po::value<std::string>()->value_name("T"), "export-csv: items (default), groups or events")(
      "role", po::value<std::string>()->value_name("ROLE"), "add-user: trainee or instructor")(
      "pin", po::value<std::string>()->value_name("PIN"), "add-user, set-pin: the PIN (- reads it from stdin)")(
      "server", po::value<std::string>()->value_name("CONNINFO"), "server-init, sign-in, sync: the records server")(
      "station", po::value<std::string>()->value_name("S"), "sign-in: the station's server login; centre: only it")(
      "batch", po::value<std::string>()->value_name("N"), "sync: sessions per server transaction (50)")(
      "pause-ms", po::value<std::string>()->value_name("MS"), "sync: pause between batches (0)")(
      "out-dir", po::value<std::string>()->value_name("DIR"), "export: the folder of the CSV tables")(
      "pseudonym-key", po::value<std::string>()->value_name("FILE"), "export: pseudonymise with this key file")(
      "every", po::value<std::string>()->value_name("S"), "sync: again every S seconds until stopped")(
      "from", po::value<std::string>()->value_name("DATE"), "centre: from this day (YYYY-MM-DD)")(
      "to", po::value<std::string>()->value_name("DATE"), "centre: to this day (YYYY-MM-DD)");
  cli.hidden()("command", po::value<std::string>())("args", po::value<std::vector<std::string>>());
  cli.positional("command", 1).positional("args", -1);
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "help") {  // `records help`, as --help
      std::cout << cli.help();
      return 0;
    }
  }
  if (const auto status = cli.parse(argc, argv)) return *status;
  Arguments args;
  const po::variables_map& values = cli.values();
  if (values.count("command") == 0) return cli.fail("no command");
  args.command = values["command"].as<std::string>();
  if (values.count("args")) args.positional = values["args"].as<std::vector<std::string>>();
  for (const std::string& name : kValued) {
    if (values.count(name)) args.options["--" + name] = values[name].as<std::string>();
  }
  try {
    const std::string db = args.has("--db") ? args.option("--db") : defaultDatabase();
    const std::string& command = args.command;
    if (command == "check") {
      allowOnly(args, {});
      return runCheck(db, args);
    }
    // The server commands that need no station database.
    if (command == "server-init") {
      allowOnly(args, {"--server"});
      if (!args.has("--server") || !args.positional.empty()) throw UsageError{"server-init needs --server CONNINFO"};
      const bool installed = records::installServerSchema(args.option("--server"));
      std::cout << (installed ? "installed" : "already installed") << " records server schema version "
                << records::Store::kSchemaVersion << '\n';
      return 0;
    }
    if (command == "export" && args.has("--server")) {
      allowOnly(args, {"--server", "--out-dir", "--user", "--scene", "--pseudonym-key"});
      return runExportTables(nullptr, args);
    }
    if (command == "centre") {
      allowOnly(args, {"--server", "--station", "--user", "--scene", "--from", "--to"});
      return runCentre(args);
    }
    if (command == "sign-in") {
      allowOnly(args, {"--server", "--station"});
      if (!args.has("--server") || !args.has("--station") || !args.positional.empty()) {
        throw UsageError{"sign-in needs --server CONNINFO and --station S"};
      }
      records::signInOnServer(args.option("--server"), args.option("--station"));
      std::cout << "signed in on " << args.option("--station") << '\n';
      return 0;
    }
    static const std::vector<std::string> kCommands{"import", "export-csv", "add-user", "set-pin",
                                                    "list",   "users",      "sync",     "export"};
    if (std::find(kCommands.begin(), kCommands.end(), command) == kCommands.end()) {
      throw UsageError{"unknown command " + command};
    }
    if (command == "import") allowOnly(args, {"--user"});
    if (command == "export-csv") allowOnly(args, {"--user", "--scene", "--out", "--table"});
    if (command == "add-user") allowOnly(args, {"--role", "--pin"});
    if (command == "set-pin") allowOnly(args, {"--pin"});
    if (command == "list") allowOnly(args, {"--user"});
    if (command == "users") allowOnly(args, {});
    if (command == "sync") allowOnly(args, {"--server", "--batch", "--pause-ms", "--every"});
    if (command == "export") allowOnly(args, {"--out-dir", "--user", "--scene", "--pseudonym-key"});

    records::Store store(db);
    if (command == "import") return runImport(store, args);
    if (command == "export-csv") return runExport(store, args);
    if (command == "add-user") return runAddUser(store, args);
    if (command == "set-pin") return runSetPin(store, args);
    if (command == "list") return runList(store, args);
    if (command == "sync") return runSync(store, args);
    if (command == "export") return runExportTables(&store, args);
    return runUsers(store, args);
  } catch (const UsageError& e) {
    return cli.fail(e.message);
  } catch (const std::exception& e) {
    std::cerr << "records: " << e.what() << '\n';
    return 1;
  }
}
