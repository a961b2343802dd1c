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

// Version 5 (issue 41, a training centre): a session's identity on the records server is its global key, a random
// UUID made when the station stores it (two stations running the same scripted session are two sessions);
// session_key stays this station's content hash, which only tells a re-imported file from a new session. synced_at
// is the station's outbox: NULL until the server has acknowledged the session (a commit there, then this mark here,
// so a crash between the two re-sends a session the server then recognises by its key). users.origin tells the
// station's own users from those that came down from the server (their role is the server's; a server deletion
// removes them and their sessions here too). trajectory_samples: the eye's and instruments' applied poses per frame
// (records/trajectory.h), one row per source and frame in frame order; a position of NULL is an unknown one.
constexpr const char* kVersion5 = R"sql(
ALTER TABLE sessions ADD COLUMN global_key TEXT;
UPDATE sessions SET global_key = lower(hex(randomblob(4)) || '-' || hex(randomblob(2)) || '-4' ||
  substr(hex(randomblob(2)), 2) || '-' || substr('89ab', 1 + (abs(random()) % 4), 1) ||
  substr(hex(randomblob(2)), 2) || '-' || hex(randomblob(6)));
CREATE UNIQUE INDEX sessions_global_key ON sessions (global_key);
ALTER TABLE sessions ADD COLUMN synced_at TEXT;
CREATE INDEX sessions_unsynced ON sessions (id) WHERE synced_at IS NULL;
ALTER TABLE users ADD COLUMN origin TEXT NOT NULL DEFAULT 'local' CHECK (origin IN ('local', 'server'));
CREATE TABLE trajectory_samples (
  session_id INTEGER NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
  position INTEGER NOT NULL,
  frame INTEGER NOT NULL,
  time REAL NOT NULL,
  source TEXT NOT NULL,
  frame_id TEXT NOT NULL DEFAULT '',
  x REAL, y REAL, z REAL,
  qx REAL, qy REAL, qz REAL, qw REAL,
  valid INTEGER NOT NULL DEFAULT 0,
  PRIMARY KEY (session_id, position)
);
)sql";

// The records server's schema (PostgreSQL 15), the same schema version as the station's: the session, score item,
// factor group and penalty event tables have the station's columns (a test compares them), keyed by the global key
// instead of the station's content hash, plus what only a centre needs: who supervises whom, which station a user
// signed in on, the schema version stations are checked against. Installed once by the database owner
// (`records server-init`); idempotent for the functions and policies, not for the tables (a second run is refused
// by the schema_info check in installServerSchema).
//
// Who may do what is enforced here, not by the clients (SECURITY.md, "Training centre"): every person signs in as a
// PostgreSQL login role of their own name, member of one of the group roles records_trainee, records_instructor or
// records_admin; each station has its own login role, member of records_station. Row-level security:
//   trainee    reads their own sessions (and their items, groups, events) and their course assignment;
//   instructor reads their own and their supervised trainees' sessions;
//   admin      creates and deletes users and stations and sets who supervises whom (records_* functions), reads no
//              sessions;
//   station    inserts sessions under its own name only, for users who signed in on it with their own password
//              (station_signins, written by records_sign_in as that user), after records_hello accepted its schema
//              version in the same transaction; reads back only its own sessions (to recognise a re-sent one).
constexpr const char* kServerSchema = R"sql(
CREATE TABLE schema_info (
  singleton boolean PRIMARY KEY DEFAULT true CHECK (singleton),
  version integer NOT NULL,
  min_station_version integer NOT NULL
);
CREATE TABLE users (
  name text PRIMARY KEY,
  role text NOT NULL CHECK (role IN ('trainee', 'instructor', 'admin')),
  created_at timestamptz NOT NULL DEFAULT now(),
  updated_at timestamptz NOT NULL DEFAULT now(),
  deleted_at timestamptz
);
CREATE TABLE stations (name text PRIMARY KEY, created_at timestamptz NOT NULL DEFAULT now());
CREATE TABLE supervision (
  instructor text NOT NULL REFERENCES users (name) ON DELETE CASCADE,
  trainee text NOT NULL REFERENCES users (name) ON DELETE CASCADE,
  PRIMARY KEY (instructor, trainee)
);
CREATE TABLE station_signins (
  station text NOT NULL REFERENCES stations (name) ON DELETE CASCADE,
  user_name text NOT NULL REFERENCES users (name) ON DELETE CASCADE,
  signed_in_at timestamptz NOT NULL DEFAULT now(),
  PRIMARY KEY (station, user_name)
);
CREATE TABLE sessions (
  id bigserial PRIMARY KEY,
  global_key text NOT NULL UNIQUE,
  session_key text NOT NULL,
  station_id text NOT NULL REFERENCES stations (name),
  user_name text NOT NULL REFERENCES users (name) ON DELETE CASCADE,
  scene text NOT NULL,
  scenario text NOT NULL DEFAULT '',
  difficulty text NOT NULL DEFAULT '',
  seed bigint NOT NULL DEFAULT 0,
  state text NOT NULL DEFAULT '',
  message text NOT NULL DEFAULT '',
  total double precision NOT NULL DEFAULT 0,
  passed integer NOT NULL DEFAULT 0,
  elapsed double precision NOT NULL DEFAULT 0,
  start_stamp double precision NOT NULL DEFAULT 0,
  end_stamp double precision NOT NULL DEFAULT 0,
  recorded_at text NOT NULL,
  bag_path text NOT NULL DEFAULT '',
  result_path text NOT NULL DEFAULT '',
  software_version text NOT NULL DEFAULT '',
  final_state_hash text NOT NULL DEFAULT '',
  frames bigint NOT NULL DEFAULT 0,
  annotation text NOT NULL DEFAULT '',
  station text NOT NULL DEFAULT '',
  events_dropped integer NOT NULL DEFAULT 0,
  uploaded_at timestamptz NOT NULL DEFAULT now()
);
-- The content hash finds the same result uploaded under two keys (a duplicate to look at), it identifies nothing.
CREATE INDEX sessions_session_key ON sessions (session_key);
CREATE INDEX sessions_user_scene ON sessions (user_name, scene, start_stamp);
CREATE INDEX sessions_station ON sessions (station_id);
CREATE TABLE score_items (
  session_id bigint NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
  position integer NOT NULL,
  name text NOT NULL,
  value double precision NOT NULL DEFAULT 0,
  unit text NOT NULL DEFAULT '',
  weight double precision NOT NULL DEFAULT 0,
  points double precision NOT NULL DEFAULT 0,
  PRIMARY KEY (session_id, position)
);
CREATE TABLE score_groups (
  session_id bigint NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
  position integer NOT NULL,
  name text NOT NULL,
  points double precision NOT NULL DEFAULT 0,
  weight double precision NOT NULL DEFAULT 0,
  PRIMARY KEY (session_id, position)
);
CREATE TABLE penalty_events (
  session_id bigint NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
  position integer NOT NULL,
  time double precision NOT NULL DEFAULT 0,
  kind text NOT NULL,
  item text NOT NULL DEFAULT '',
  slot text NOT NULL DEFAULT '',
  instrument text NOT NULL DEFAULT '',
  x double precision,
  y double precision,
  z double precision,
  points double precision NOT NULL DEFAULT 0,
  PRIMARY KEY (session_id, position)
);
CREATE TABLE trajectory_samples (
  session_id bigint NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
  position integer NOT NULL,
  frame bigint NOT NULL,
  time double precision NOT NULL,
  source text NOT NULL,
  frame_id text NOT NULL DEFAULT '',
  x double precision, y double precision, z double precision,
  qx double precision, qy double precision, qz double precision, qw double precision,
  valid integer NOT NULL DEFAULT 0,
  PRIMARY KEY (session_id, position)
);
CREATE TABLE course_assignments (
  user_name text PRIMARY KEY REFERENCES users (name) ON DELETE CASCADE,
  course_name text NOT NULL,
  course_file text NOT NULL DEFAULT '',
  course_text text NOT NULL,
  assigned_by text REFERENCES users (name) ON DELETE SET NULL,
  assigned_at text NOT NULL
);

DO $$ BEGIN
  CREATE ROLE records_trainee NOLOGIN;
EXCEPTION WHEN duplicate_object THEN NULL; END $$;
DO $$ BEGIN
  CREATE ROLE records_instructor NOLOGIN;
EXCEPTION WHEN duplicate_object THEN NULL; END $$;
DO $$ BEGIN
  CREATE ROLE records_admin NOLOGIN;
EXCEPTION WHEN duplicate_object THEN NULL; END $$;
DO $$ BEGIN
  CREATE ROLE records_station NOLOGIN;
EXCEPTION WHEN duplicate_object THEN NULL; END $$;

-- No JIT for this database: its queries are short lookups under row-level security, whose subplans inflate the cost
-- estimates past jit_above_cost, and compiling then takes longer than the query (15-20 ms of an 80 ms history
-- query at 10^5 sessions, bench_records).
DO $$ BEGIN
  EXECUTE format('ALTER DATABASE %I SET jit = off', current_database());
END $$;

REVOKE ALL ON ALL TABLES IN SCHEMA public FROM PUBLIC;
REVOKE CREATE ON SCHEMA public FROM PUBLIC;
GRANT USAGE ON SCHEMA public TO records_trainee, records_instructor, records_admin, records_station;
GRANT SELECT ON schema_info, users TO records_trainee, records_instructor, records_admin, records_station;
GRANT SELECT ON supervision TO records_instructor, records_admin;
GRANT SELECT ON stations, station_signins TO records_admin, records_station;
GRANT SELECT ON sessions, score_items, score_groups, penalty_events, trajectory_samples
  TO records_trainee, records_instructor, records_station;
GRANT INSERT ON sessions, score_items, score_groups, penalty_events, trajectory_samples TO records_station;
GRANT USAGE ON SEQUENCE sessions_id_seq TO records_station;
GRANT SELECT ON course_assignments TO records_trainee, records_instructor, records_admin, records_station;
GRANT INSERT, UPDATE, DELETE ON course_assignments TO records_instructor, records_admin;

ALTER TABLE sessions ENABLE ROW LEVEL SECURITY;
ALTER TABLE score_items ENABLE ROW LEVEL SECURITY;
ALTER TABLE score_groups ENABLE ROW LEVEL SECURITY;
ALTER TABLE penalty_events ENABLE ROW LEVEL SECURITY;
ALTER TABLE trajectory_samples ENABLE ROW LEVEL SECURITY;
ALTER TABLE station_signins ENABLE ROW LEVEL SECURITY;
ALTER TABLE supervision ENABLE ROW LEVEL SECURITY;
ALTER TABLE course_assignments ENABLE ROW LEVEL SECURITY;

CREATE POLICY trainee_reads_own ON sessions FOR SELECT TO records_trainee USING (user_name = current_user);
CREATE POLICY instructor_reads_supervised ON sessions FOR SELECT TO records_instructor
  USING (user_name = current_user OR user_name IN (SELECT trainee FROM supervision));
CREATE POLICY station_reads_own ON sessions FOR SELECT TO records_station USING (station_id = current_user);
CREATE POLICY station_inserts_signed_in ON sessions FOR INSERT TO records_station
  WITH CHECK (station_id = current_user
              AND coalesce(current_setting('records.station_schema_version', true), '') =
                  (SELECT min_station_version::text FROM schema_info)
              AND EXISTS (SELECT 1 FROM station_signins g
                          WHERE g.station = current_user AND g.user_name = sessions.user_name));
-- The items of a session follow the session: whoever sees the session (under the policies above) sees its items; a
-- station adds items only to a session it can see, i.e. its own.
-- A correlated EXISTS (one index probe per row), not "IN (SELECT id FROM sessions)", which builds the set of every
-- session the role may see for each statement: 3 s per 50 uploaded sessions at 10^5 stored (bench_records).
CREATE POLICY follow_session ON score_items USING (EXISTS (SELECT 1 FROM sessions s WHERE s.id = session_id));
CREATE POLICY follow_session ON score_groups USING (EXISTS (SELECT 1 FROM sessions s WHERE s.id = session_id));
CREATE POLICY follow_session ON penalty_events USING (EXISTS (SELECT 1 FROM sessions s WHERE s.id = session_id));
CREATE POLICY follow_session ON trajectory_samples
  USING (EXISTS (SELECT 1 FROM sessions s WHERE s.id = session_id));
CREATE POLICY station_sees_own ON station_signins FOR SELECT TO records_station USING (station = current_user);
CREATE POLICY admin_sees_all ON station_signins FOR SELECT TO records_admin USING (true);
CREATE POLICY instructor_sees_own ON supervision FOR SELECT TO records_instructor USING (instructor = current_user);
CREATE POLICY admin_sees_all ON supervision FOR SELECT TO records_admin USING (true);
CREATE POLICY trainee_sees_own ON course_assignments FOR SELECT TO records_trainee USING (user_name = current_user);
CREATE POLICY instructor_manages_supervised ON course_assignments TO records_instructor
  USING (user_name IN (SELECT trainee FROM supervision))
  WITH CHECK (user_name IN (SELECT trainee FROM supervision) AND assigned_by = current_user);
CREATE POLICY all_for_admin_and_stations ON course_assignments FOR SELECT TO records_admin, records_station
  USING (true);
CREATE POLICY admin_manages ON course_assignments TO records_admin USING (true) WITH CHECK (true);

-- The password policy (SECURITY.md): at least 12 characters and not only digits, so a server password is never a
-- PIN; PostgreSQL stores it as a SCRAM-SHA-256 verifier that never leaves the server (stations get no hash at all).
CREATE FUNCTION records_check_password(password text) RETURNS void LANGUAGE plpgsql AS $f$
BEGIN
  IF password IS NULL OR length(password) < 12 OR password ~ '^[0-9]*$' THEN
    RAISE EXCEPTION 'password policy: at least 12 characters and not only digits';
  END IF;
END $f$;

CREATE FUNCTION records_create_user(user_name text, user_role text, password text) RETURNS void
LANGUAGE plpgsql SECURITY DEFINER SET search_path = public, pg_temp AS $f$
BEGIN
  IF NOT pg_has_role(session_user, 'records_admin', 'MEMBER') THEN
    RAISE EXCEPTION 'only an admin creates users';
  END IF;
  IF user_role NOT IN ('trainee', 'instructor', 'admin') THEN
    RAISE EXCEPTION 'role must be trainee, instructor or admin, not %', user_role;
  END IF;
  IF user_name !~ '^[a-z][a-z0-9_.-]{0,62}$' OR user_name LIKE 'records\_%' OR user_name LIKE 'pg\_%' THEN
    RAISE EXCEPTION 'user name "%": lower-case letters, digits, _ . - (starting with a letter)', user_name;
  END IF;
  PERFORM records_check_password(password);
  IF EXISTS (SELECT 1 FROM users WHERE name = user_name AND deleted_at IS NULL) THEN
    RAISE EXCEPTION 'user "%" already exists', user_name;
  END IF;
  EXECUTE format('CREATE ROLE %I LOGIN PASSWORD %L IN ROLE %I', user_name, password, 'records_' || user_role);
  INSERT INTO users (name, role) VALUES (user_name, user_role)
    ON CONFLICT (name) DO UPDATE SET role = excluded.role, deleted_at = NULL, updated_at = now();
END $f$;

CREATE FUNCTION records_set_password(password text) RETURNS void
LANGUAGE plpgsql SECURITY DEFINER SET search_path = public, pg_temp AS $f$
BEGIN
  PERFORM records_check_password(password);
  EXECUTE format('ALTER ROLE %I PASSWORD %L', session_user, password);
END $f$;

-- Deletion on request: the person's sessions (with their items, groups, events, by cascade), sign-ins, supervision
-- and course go; the users row stays as a tombstone (name, deleted_at) so that every station deletes its copy too.
CREATE FUNCTION records_delete_user(user_name text) RETURNS void
LANGUAGE plpgsql SECURITY DEFINER SET search_path = public, pg_temp AS $f$
BEGIN
  IF NOT pg_has_role(session_user, 'records_admin', 'MEMBER') THEN
    RAISE EXCEPTION 'only an admin deletes users';
  END IF;
  DELETE FROM sessions WHERE sessions.user_name = records_delete_user.user_name;
  DELETE FROM station_signins WHERE station_signins.user_name = records_delete_user.user_name;
  DELETE FROM supervision WHERE trainee = records_delete_user.user_name OR instructor = records_delete_user.user_name;
  DELETE FROM course_assignments WHERE course_assignments.user_name = records_delete_user.user_name;
  UPDATE users SET deleted_at = now(), updated_at = now() WHERE name = records_delete_user.user_name;
  EXECUTE format('DROP ROLE IF EXISTS %I', user_name);
END $f$;

CREATE FUNCTION records_create_station(station_name text, password text) RETURNS void
LANGUAGE plpgsql SECURITY DEFINER SET search_path = public, pg_temp AS $f$
BEGIN
  IF NOT pg_has_role(session_user, 'records_admin', 'MEMBER') THEN
    RAISE EXCEPTION 'only an admin creates stations';
  END IF;
  IF station_name !~ '^station_[a-z0-9_]{1,40}$' THEN
    RAISE EXCEPTION 'station name "%": station_ then lower-case letters, digits, _', station_name;
  END IF;
  PERFORM records_check_password(password);
  EXECUTE format('CREATE ROLE %I LOGIN PASSWORD %L IN ROLE records_station', station_name, password);
  INSERT INTO stations (name) VALUES (station_name);
END $f$;

CREATE FUNCTION records_supervise(instructor_name text, trainee_name text) RETURNS void
LANGUAGE plpgsql SECURITY DEFINER SET search_path = public, pg_temp AS $f$
BEGIN
  IF NOT pg_has_role(session_user, 'records_admin', 'MEMBER') THEN
    RAISE EXCEPTION 'only an admin sets who supervises whom';
  END IF;
  INSERT INTO supervision VALUES (instructor_name, trainee_name) ON CONFLICT DO NOTHING;
END $f$;

-- A person signs in on a station as themselves (their own login, their own password, through the station): from
-- then on that station may upload their sessions, including those it records offline later.
CREATE FUNCTION records_sign_in(station_name text) RETURNS void
LANGUAGE plpgsql SECURITY DEFINER SET search_path = public, pg_temp AS $f$
BEGIN
  IF NOT EXISTS (SELECT 1 FROM users WHERE name = session_user AND deleted_at IS NULL) THEN
    RAISE EXCEPTION '"%" is not a user of this records server', session_user;
  END IF;
  IF NOT EXISTS (SELECT 1 FROM stations WHERE name = station_name) THEN
    RAISE EXCEPTION 'no station "%"', station_name;
  END IF;
  INSERT INTO station_signins (station, user_name) VALUES (station_name, session_user)
    ON CONFLICT (station, user_name) DO UPDATE SET signed_in_at = now();
END $f$;

-- A station states its schema version at the start of every sync transaction; an older station is refused here
-- with a message that says what to do, and without this call the insert policy refuses its sessions.
CREATE FUNCTION records_hello(station_schema_version integer) RETURNS integer
LANGUAGE plpgsql SET search_path = public, pg_temp AS $f$
DECLARE
  server_version integer;
  minimum integer;
BEGIN
  SELECT version, min_station_version INTO server_version, minimum FROM schema_info;
  IF station_schema_version < minimum THEN
    RAISE EXCEPTION 'station schema version % is older than this records server accepts (% to %): update the station software; its sessions stay on the station until then',
      station_schema_version, minimum, server_version;
  END IF;
  IF station_schema_version > server_version THEN
    RAISE EXCEPTION 'station schema version % is newer than this records server (%): update the server first',
      station_schema_version, server_version;
  END IF;
  PERFORM set_config('records.station_schema_version', minimum::text, true);
  RETURN server_version;
END $f$;

REVOKE ALL ON FUNCTION records_create_user, records_delete_user, records_create_station, records_supervise,
  records_sign_in, records_set_password, records_hello, records_check_password FROM PUBLIC;
GRANT EXECUTE ON FUNCTION records_create_user, records_delete_user, records_create_station, records_supervise
  TO records_admin;
GRANT EXECUTE ON FUNCTION records_sign_in, records_set_password
  TO records_trainee, records_instructor, records_admin;
GRANT EXECUTE ON FUNCTION records_hello TO records_station;
)sql";

}  // namespace

const char* serverSchemaSql() { return kServerSchema; }

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
    case 5:
      return kVersion5;
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
