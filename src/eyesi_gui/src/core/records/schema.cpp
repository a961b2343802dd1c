#include "eyesi_gui/records/schema.h"

#include <openssl/evp.h>

#include <cstdio>

#include "eyesi_gui/records/csv.h"

namespace eyesi_gui::records {
namespace {

// Version 1: the first release. guest is created here (and re-created on open if ever missing) because every result
// without a user is filed under it.
constexpr const char* kVersion1 = R"sql(
CREATE TABLE users (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  role TEXT NOT NULL CHECK (role IN ('trainee', 'instructor')),
  pin_salt BLOB,
  pin_hash BLOB,
  iterations INTEGER NOT NULL DEFAULT 0,
  created_at TEXT NOT NULL
);
CREATE TABLE sessions (
  id INTEGER PRIMARY KEY,
  session_key TEXT NOT NULL UNIQUE,
  user_id INTEGER NOT NULL REFERENCES users (id),
  scene TEXT NOT NULL,
  scenario TEXT NOT NULL DEFAULT '',
  difficulty TEXT NOT NULL DEFAULT '',
  seed INTEGER NOT NULL DEFAULT 0,
  state TEXT NOT NULL DEFAULT '',
  message TEXT NOT NULL DEFAULT '',
  total REAL NOT NULL DEFAULT 0,
  passed INTEGER NOT NULL DEFAULT 0,
  elapsed REAL NOT NULL DEFAULT 0,
  start_stamp REAL NOT NULL DEFAULT 0,
  end_stamp REAL NOT NULL DEFAULT 0,
  recorded_at TEXT NOT NULL,
  bag_path TEXT NOT NULL DEFAULT '',
  result_path TEXT NOT NULL DEFAULT '',
  software_version TEXT NOT NULL DEFAULT '',
  final_state_hash TEXT NOT NULL DEFAULT '',
  frames INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE score_items (
  session_id INTEGER NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
  position INTEGER NOT NULL,
  name TEXT NOT NULL,
  value REAL NOT NULL DEFAULT 0,
  unit TEXT NOT NULL DEFAULT '',
  weight REAL NOT NULL DEFAULT 0,
  points REAL NOT NULL DEFAULT 0,
  PRIMARY KEY (session_id, position)
);
INSERT INTO users (name, role, iterations, created_at)
  VALUES ('guest', 'trainee', 0, strftime('%Y-%m-%dT%H:%M:%SZ', 'now'));
)sql";

// Version 2: instructor notes, the station a session ran on, and the index behind the scenario screen's per-user,
// per-scene queries. Additive only, so version-1 rows keep every value.
constexpr const char* kVersion2 = R"sql(
ALTER TABLE sessions ADD COLUMN annotation TEXT NOT NULL DEFAULT '';
ALTER TABLE sessions ADD COLUMN station TEXT NOT NULL DEFAULT '';
CREATE INDEX sessions_user_scene ON sessions (user_id, scene, start_stamp);
)sql";

// Version 3 (issue 35, courses): which course each trainee is assigned, by whom and when. The course's text is kept
// as assigned, so a trainee's progress (computed from their sessions) is shown against the same steps and pass marks
// after a restart, even if the course file is edited or gone. One course per trainee: assigning another replaces it.
constexpr const char* kVersion3 = R"sql(
CREATE TABLE course_assignments (
  user_id INTEGER PRIMARY KEY REFERENCES users (id),
  course_name TEXT NOT NULL,
  course_file TEXT NOT NULL DEFAULT '',
  course_text TEXT NOT NULL,
  assigned_by INTEGER REFERENCES users (id),
  assigned_at TEXT NOT NULL
);
)sql";

// Version 4 (issue 35, scoring): the factor groups and penalty events of each session, written with its score items.
// Additive only: sessions recorded before have none (their results predate the groups). A penalty event's position
// is NULL when the result did not know it.
constexpr const char* kVersion4 = R"sql(
ALTER TABLE sessions ADD COLUMN events_dropped INTEGER NOT NULL DEFAULT 0;
CREATE TABLE score_groups (
  session_id INTEGER NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
  position INTEGER NOT NULL,
  name TEXT NOT NULL,
  points REAL NOT NULL DEFAULT 0,
  weight REAL NOT NULL DEFAULT 0,
  PRIMARY KEY (session_id, position)
);
CREATE TABLE penalty_events (
  session_id INTEGER NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
  position INTEGER NOT NULL,
  time REAL NOT NULL DEFAULT 0,
  kind TEXT NOT NULL,
  item TEXT NOT NULL DEFAULT '',
  slot TEXT NOT NULL DEFAULT '',
  instrument TEXT NOT NULL DEFAULT '',
  x REAL,
  y REAL,
  z REAL,
  points REAL NOT NULL DEFAULT 0,
  PRIMARY KEY (session_id, position)
);
)sql";

}  // namespace

const char* migrationSql(int to_version) {
  switch (to_version) {
    case 1:
      return kVersion1;
    case 2:
      return kVersion2;
    case 3:
      return kVersion3;
    case 4:
      return kVersion4;
    default:
      return nullptr;
  }
}

std::string sessionKey(const SessionRecord& s) {
  // Unit separators keep ("a", "bc") and ("ab", "c") apart; numbers in their shortest round-trip form, so the same
  // JSON text always gives the same key.
  const std::string canonical = s.scene + '\x1f' + s.scenario + '\x1f' + s.difficulty + '\x1f' +
                                std::to_string(s.seed) + '\x1f' + formatNumber(s.start_stamp) + '\x1f' +
                                formatNumber(s.end_stamp) + '\x1f' + s.final_state_hash + '\x1f' +
                                std::to_string(s.frames);
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  if (EVP_Digest(canonical.data(), canonical.size(), digest, &length, EVP_sha256(), nullptr) != 1) {
    throw StoreError("SHA-256 failed (OpenSSL)");
  }
  std::string hex;
  char byte[3];
  for (unsigned int i = 0; i < length; ++i) {
    std::snprintf(byte, sizeof(byte), "%02x", digest[i]);
    hex += byte;
  }
  return hex;
}

}  // namespace eyesi_gui::records
