// `records export` (issue 41, "data a researcher can use"): a records database as tidy CSV tables, one observation
// per row and one table per kind of observation, joined by session_key (the session's global key). The data
// dictionary is in README.md ("Records export: data dictionary"). Identities can be pseudonymised: user and station
// names become keyed hashes (HMAC-SHA256 with a centre-held key, so the same person has the same pseudonym in every
// export made with that key, and nobody without the key can test a guessed name), free text and paths are left out,
// and wall-clock times are cut to the date.
#pragma once

#include <cstdint>
#include <string>

#include "eyesi_gui/records/store.h"

namespace eyesi_gui::records {

struct ExportOptions {
  SessionFilter filter;
  std::string pseudonym_key_file;  // "" = real names; else the key file (created, 32 random bytes, 0600, if missing)
};

struct ExportCounts {
  std::size_t sessions = 0, items = 0, groups = 0, events = 0, samples = 0;
};

// The file names, in `folder` (created if missing): sessions.csv, score_items.csv, score_groups.csv,
// penalty_events.csv, trajectories.csv. Throws StoreError naming the file that could not be written.
ExportCounts exportTables(const Store& store, const std::string& folder, const ExportOptions& options = {});
// The same tables from the records server (server.h's ServerReader): what the connection's role may read — the whole
// centre for the database owner on the server host (the centre's data steward, who keeps the pseudonym key), an
// instructor's group for an instructor. Throws ServerError / StoreError.
ExportCounts exportServerTables(const std::string& connection, const std::string& folder,
                                const ExportOptions& options = {});

// "p-" and 16 hex digits of HMAC-SHA256(key, kind + ":" + name); kind "user" or "station".
std::string pseudonym(const std::string& key, const std::string& kind, const std::string& name);

}  // namespace eyesi_gui::records
