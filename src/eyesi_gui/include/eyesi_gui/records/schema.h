// The records database schema as forward migrations: step N turns a version N-1 database into version N. Exposed so
// the tests can build a database exactly as an older release left it.
#pragma once

#include <string>

#include "eyesi_gui/records/store.h"

namespace eyesi_gui::records {

// SQL of the step that migrates `to_version - 1` → `to_version` (1..Store::kSchemaVersion), without the
// PRAGMA user_version update and without the transaction (the store wraps both around it).
const char* migrationSql(int to_version);

// The records server's schema (PostgreSQL; issue 41) at Store::kSchemaVersion, with its roles, row-level security
// policies and functions; installServerSchema (server.h) runs it once and records the version in schema_info.
const char* serverSchemaSql();
// The oldest station schema version the server accepts sessions from (records_hello): the first with global keys.
constexpr int kMinStationSchemaVersion = 5;

// The value of sessions.session_key: the session's identity (scene, scenario, difficulty, seed, start/end stamp,
// final state hash, frames). Not the user or the wall time, so a result imported twice, or once live and once from
// its file, maps to one row.
std::string sessionKey(const SessionRecord& session);

}  // namespace eyesi_gui::records
