#!/usr/bin/env python3
"""A training centre end to end (issue 41): a throw-away PostgreSQL cluster and three sync clients, each in its own
network namespace, fed with the committed reference results.

  server namespace  eyesi-ctr-srv   10.215.K.1 (one veth per station; postgres listens on the three and on a Unix
                                    socket in the temporary folder, which the host reaches through the file system)
  station K         eyesi-ctr-sK    10.215.K.2, a SQLite store of its own, `records import` + `records sync`

What happens: users, stations, sign-ins and supervision are set up by an admin; every station imports its sessions in
two waves, concurrently, syncing as it goes; station 3 is offline for the first wave; the server is killed (-9, the
postmaster and its backends) in the middle of station 1's sync and restarted; station 2's sync process is killed (-9)
mid-sync. At the end every session is on the server exactly once with all its items, groups and events, the sessions
the server must refuse (a user not signed in on that station, guest) are still on their station, unsynced, and every
local store passes its integrity check. Then the role checks run against the server directly, a deletion on request
reaches the station, a course comes down, and an older station is refused.

Needs root (namespaces; the cluster runs as the unprivileged user `postgres`, or `nobody`), Debian's postgresql and
the built `records` tool (EYESI_RECORDS_TOOL, default build/devel/lib/eyesi_gui/records).
Usage: centre_sync.py [--keep]  (--keep leaves the temporary folder for a look at the logs)
"""
import csv
import glob
import io
import json
import os
import pwd
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "../../../.."))
RECORDS = os.environ.get("EYESI_RECORDS_TOOL", os.path.join(ROOT, "build/devel/lib/eyesi_gui/records"))
TRAJECTORY = os.environ.get("EYESI_TRAJECTORY_TOOL", os.path.join(ROOT, "build/devel/lib/eyesi_gui/session_trajectory"))
REFERENCE = sorted(glob.glob(os.path.join(ROOT, "src/vrm_sim/test/bags/*.result.json")))
STATIONS = (1, 2, 3)
SERVER_NS = "eyesi-ctr-srv"
PASSWORD = {  # test-only secrets of a throw-away cluster; the policy asks for >= 12 characters, not only digits
    "admin1": "admin-secret-01", "station_s1": "station-secret-1", "station_s2": "station-secret-2",
    "station_s3": "station-secret-3", "i1": "instructor-one-1", "i2": "instructor-two-2",
}
TRAINEES = {1: ["t1", "t2"], 2: ["t3", "t4"], 3: ["t5", "t6"]}  # who signs in on which station
for _t in [t for ts in TRAINEES.values() for t in ts] + ["t7"]:
    PASSWORD[_t] = "trainee-secret-" + _t
SESSIONS_PER_WAVE = 12  # per station and wave, plus the held ones of station 1

failures = []


def check(condition, what):
    print(("PASS " if condition else "FAIL ") + what, flush=True)
    if not condition:
        failures.append(what)


def run(cmd, check_rc=True, **kw):
    result = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)
    if check_rc and result.returncode != 0:
        raise RuntimeError("%s failed (%d): %s" % (" ".join(cmd), result.returncode, result.stdout))
    return result


def children_of(pid):
    """The processes whose parent is `pid` (from /proc: procps may not be installed)."""
    children = []
    for stat in glob.glob("/proc/[0-9]*/stat"):
        try:
            with open(stat) as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            children.append(stat.split("/")[2])
    return children


def station_ns(k):
    return "eyesi-ctr-s%d" % k


class Centre:
    def __init__(self, tmp):
        self.tmp = tmp
        self.bin = sorted(glob.glob("/usr/lib/postgresql/*/bin"))[-1]
        self.user = "postgres" if self._has_user("postgres") else "nobody"
        self.port = 5432  # alone in its namespace: the default port cannot collide with anything on the host
        self.data = os.path.join(tmp, "pgdata")
        self.socket = os.path.join(tmp, "sock")

    @staticmethod
    def _has_user(name):
        try:
            pwd.getpwnam(name)
            return True
        except KeyError:
            return False

    # --- network namespaces ---
    def netns_up(self):
        self.netns_down()
        run(["ip", "netns", "add", SERVER_NS])
        run(["ip", "-n", SERVER_NS, "link", "set", "lo", "up"])
        for k in STATIONS:
            ns = station_ns(k)
            run(["ip", "netns", "add", ns])
            run(["ip", "-n", ns, "link", "set", "lo", "up"])
            run(["ip", "link", "add", "ectrS%d" % k, "netns", ns, "type", "veth", "peer", "name", "ectrP%d" % k,
                 "netns", SERVER_NS])
            run(["ip", "-n", ns, "addr", "add", "10.215.%d.2/24" % k, "dev", "ectrS%d" % k])
            run(["ip", "-n", SERVER_NS, "addr", "add", "10.215.%d.1/24" % k, "dev", "ectrP%d" % k])
            run(["ip", "-n", ns, "link", "set", "ectrS%d" % k, "up"])
            run(["ip", "-n", SERVER_NS, "link", "set", "ectrP%d" % k, "up"])

    def netns_down(self):
        for ns in [SERVER_NS] + [station_ns(k) for k in STATIONS]:
            pids = run(["ip", "netns", "pids", ns], check_rc=False).stdout.split()
            for pid in pids:
                try:
                    os.kill(int(pid), signal.SIGKILL)
                except (ProcessLookupError, ValueError):
                    pass
            run(["ip", "netns", "del", ns], check_rc=False)

    def set_online(self, k, online):
        run(["ip", "-n", station_ns(k), "link", "set", "ectrS%d" % k, "up" if online else "down"])

    # --- the cluster ---
    def initdb(self):
        os.makedirs(self.socket)
        shutil.chown(self.tmp, self.user)
        shutil.chown(self.socket, self.user)
        os.chmod(self.tmp, 0o755)
        run(["runuser", "-u", self.user, "--", os.path.join(self.bin, "initdb"), "-D", self.data, "-U", "postgres",
             "-E", "UTF8", "--auth-local=trust", "--auth-host=scram-sha-256"])
        # The owner (superuser) connects over the Unix socket only, without a password; everyone else with their own
        # password (SCRAM-SHA-256), over the socket or from the stations' subnets. Stations 1 and 2 share the
        # server's segment; station 3 stands for one off it: TLS only (hostssl), its certificate checked by the
        # station (sslmode=verify-full against the centre's CA).
        with open(os.path.join(self.data, "pg_hba.conf"), "w") as hba:
            hba.write("local all postgres trust\n"
                      "local all all scram-sha-256\n"
                      "host all all 10.215.1.0/24 scram-sha-256\n"
                      "host all all 10.215.2.0/24 scram-sha-256\n"
                      "hostssl all all 10.215.3.0/24 scram-sha-256\n")
        self.make_certificates()
        listen = ",".join("10.215.%d.1" % k for k in STATIONS)
        with open(os.path.join(self.data, "postgresql.auto.conf"), "a") as conf:
            conf.write("listen_addresses = '%s'\nport = %d\nunix_socket_directories = '%s'\n"
                       "password_encryption = 'scram-sha-256'\n"
                       "ssl = on\nssl_cert_file = '%s'\nssl_key_file = '%s'\n"
                       % (listen, self.port, self.socket, self.server_cert, self.server_key))

    def make_certificates(self):
        """A throw-away CA and the server's certificate for its three addresses (openssl, which postgresql-common's
        ssl-cert brings along)."""
        tls = os.path.join(self.tmp, "tls")
        os.makedirs(tls)
        self.ca = os.path.join(tls, "ca.crt")
        self.server_cert, self.server_key = os.path.join(tls, "server.crt"), os.path.join(tls, "server.key")
        ca_key, csr = os.path.join(tls, "ca.key"), os.path.join(tls, "server.csr")
        run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj",
             "/CN=eyesi centre test CA", "-keyout", ca_key, "-out", self.ca])
        run(["openssl", "req", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=records.centre", "-keyout",
             self.server_key, "-out", csr])
        ext = os.path.join(tls, "san.ext")
        with open(ext, "w") as f:
            f.write("subjectAltName = " + ",".join("IP:10.215.%d.1" % k for k in STATIONS) + "\n")
        run(["openssl", "x509", "-req", "-in", csr, "-CA", self.ca, "-CAkey", ca_key, "-CAcreateserial", "-days", "1",
             "-extfile", ext, "-out", self.server_cert])
        for path in (self.server_key, self.server_cert):
            shutil.chown(path, self.user)
        os.chmod(self.server_key, 0o600)
        os.chmod(tls, 0o755)

    def start(self):
        run(["ip", "netns", "exec", SERVER_NS, "runuser", "-u", self.user, "--", os.path.join(self.bin, "pg_ctl"),
             "-D", self.data, "-l", os.path.join(self.tmp, "postgres.log"), "-w", "-t", "30", "start"])

    def postmaster_pid(self):
        with open(os.path.join(self.data, "postmaster.pid")) as f:
            return int(f.readline())

    def kill9(self):
        """kill -9 of the server: the postmaster and every backend (the backends of a killed postmaster would keep
        its shared memory and stop a restart)."""
        pid = self.postmaster_pid()
        children = children_of(pid)
        os.kill(pid, signal.SIGKILL)
        for child in children:
            try:
                os.kill(int(child), signal.SIGKILL)
            except ProcessLookupError:
                pass
        for _ in range(100):
            if not any(os.path.exists("/proc/%s" % p) for p in [pid] + children):
                break
            time.sleep(0.05)

    def stop(self):
        run(["runuser", "-u", self.user, "--", os.path.join(self.bin, "pg_ctl"), "-D", self.data, "-m", "immediate",
             "stop"], check_rc=False)

    def psql(self, sql, user="postgres", db="records", ok=True):
        """SQL over the Unix socket; as `user` with their password (the owner without). Returns (rc, output)."""
        env = dict(os.environ, PGPASSWORD=PASSWORD.get(user, ""))
        result = subprocess.run(["psql", "-X", "-q", "-A", "-t", "-v", "ON_ERROR_STOP=1", "-h", self.socket, "-p",
                                 str(self.port), "-U", user, "-d", db, "-c", sql], stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, env=env)
        if ok and result.returncode != 0:
            raise RuntimeError("psql as %s: %s: %s" % (user, sql, result.stdout))
        return result.returncode, result.stdout.strip()

    def value(self, sql, user="postgres"):
        return self.psql(sql, user)[1]

    # --- stations ---
    def conninfo(self, k, user, sslmode=None):
        info = "host=10.215.%d.1 port=%d dbname=records user=%s connect_timeout=2" % (k, self.port, user)
        if k == 3 or sslmode:  # off the server's segment: TLS, and the server's certificate checked
            info += " sslmode=%s sslrootcert=%s" % (sslmode or "verify-full", self.ca)
        return info

    def station_db(self, k):
        return os.path.join(self.tmp, "s%d" % k, "records.sqlite")

    def records(self, k, args, user=None, background=False, log=None, db=None):
        """The records tool in station k's namespace, as the station's login (or `user`, e.g. to sign in)."""
        login = user or "station_s%d" % k
        env = dict(os.environ, PGPASSWORD=PASSWORD[login])
        cmd = ["ip", "netns", "exec", station_ns(k), RECORDS, "--db", db or self.station_db(k)] + args
        if "--server" in args:
            cmd[cmd.index("--server") + 1] = self.conninfo(k, login)
        if background:
            return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)

    def sync(self, k, *extra):
        return self.records(k, ["sync", "--server", "-"] + list(extra))


def make_trajectories(tmp):
    """The trajectories of the reference bags (session_trajectory), once: every copy of a result carries its own."""
    folder = os.path.join(tmp, "trajectories")
    os.makedirs(folder)
    for result in REFERENCE:
        bag = result[: -len(".result.json")] + ".bag"
        run([TRAJECTORY, bag, "--out", os.path.join(folder, os.path.basename(bag)[:-4] + ".trajectory.json")])
    return folder


TRAJECTORIES = None


def write_results(folder, count, users, first, shift_stamps=True, trajectory=True, bag=None):
    """`count` copies of the reference results for `users` (round robin). Each copy is the same scripted session run
    later (its stamps shifted by a whole number of hours), so its content hash differs; with shift_stamps False the
    copies are the reference results unchanged (what another station running the same script records)."""
    os.makedirs(folder, exist_ok=True)
    paths = []
    for i in range(count):
        with open(REFERENCE[i % len(REFERENCE)]) as f:
            result = json.load(f)
        n = first + i
        if shift_stamps:
            for key in ("start_stamp", "end_stamp", "last_frame_stamp"):
                if key in result:
                    result[key] += 3600.0 * n
        result["user"] = users[i % len(users)] if users else None
        if result["user"] is None:
            del result["user"]
        path = os.path.join(folder, "%04d.result.json" % n)
        with open(path, "w") as f:
            json.dump(result, f)
        if bag:
            result["bag"] = bag
            with open(path, "w") as f:
                json.dump(result, f)
        stem = os.path.basename(REFERENCE[i % len(REFERENCE)])[: -len(".result.json")]
        if trajectory:
            shutil.copy(os.path.join(TRAJECTORIES, stem + ".trajectory.json"),
                        os.path.join(folder, "%04d.trajectory.json" % n))
        paths.append(path)
    return paths


def wait_for_count(centre, station, count, timeout=20.0):
    """Polls the server until `station` has at least `count` sessions there (a sync under way); returns the count."""
    deadline = time.monotonic() + timeout
    while True:
        n = int(centre.value("SELECT count(*) FROM sessions WHERE station_id = '%s'" % station))
        if n >= count or time.monotonic() > deadline:
            return n
        time.sleep(0.03)


def local_sessions(db):
    """{global_key: (user, synced, items, groups, events, total, samples)} of a station's store, read without the
    tool."""
    con = sqlite3.connect("file:%s?mode=ro" % db, uri=True)
    rows = con.execute(
        "SELECT s.global_key, u.name, s.synced_at IS NOT NULL, "
        "(SELECT count(*) FROM score_items WHERE session_id = s.id), "
        "(SELECT count(*) FROM score_groups WHERE session_id = s.id), "
        "(SELECT count(*) FROM penalty_events WHERE session_id = s.id), s.total, "
        "(SELECT count(*) FROM trajectory_samples WHERE session_id = s.id) "
        "FROM sessions s JOIN users u ON u.id = s.user_id").fetchall()
    integrity = con.execute("PRAGMA integrity_check").fetchone()[0]
    con.close()
    return {r[0]: r[1:] for r in rows}, integrity


def server_sessions(centre):
    out = centre.value("COPY (SELECT global_key, user_name, station_id, session_key, "
                       "(SELECT count(*) FROM score_items WHERE session_id = s.id), "
                       "(SELECT count(*) FROM score_groups WHERE session_id = s.id), "
                       "(SELECT count(*) FROM penalty_events WHERE session_id = s.id), total, "
                       "(SELECT count(*) FROM trajectory_samples WHERE session_id = s.id) "
                       "FROM sessions s) TO STDOUT WITH CSV")
    return list(csv.reader(io.StringIO(out)))


def main():
    keep = "--keep" in sys.argv
    if os.geteuid() != 0:
        print("SKIP centre_sync needs root (network namespaces, the cluster as an unprivileged user)")
        return 0
    if not os.path.exists(RECORDS):
        print("FAIL no records tool at %s (build the records target)" % RECORDS)
        return 1
    started = time.monotonic()
    probe = "eyesi-ctr-probe"
    if run(["ip", "netns", "add", probe], check_rc=False).returncode != 0:
        print("SKIP centre_sync: no network namespaces here (needs CAP_SYS_ADMIN), as security_firewall.sh")
        return 0
    run(["ip", "netns", "del", probe], check_rc=False)
    tmp = tempfile.mkdtemp(prefix="eyesi-centre-")
    centre = Centre(tmp)
    global TRAJECTORIES
    try:
        TRAJECTORIES = make_trajectories(tmp)
        centre.netns_up()
        centre.initdb()
        centre.start()
        centre.psql("CREATE DATABASE records", db="postgres")
        run([RECORDS, "server-init", "--server",
             "host=%s port=%d dbname=records user=postgres" % (centre.socket, centre.port)])
        again = run([RECORDS, "server-init", "--server",
                     "host=%s port=%d dbname=records user=postgres" % (centre.socket, centre.port)])
        check("already installed" in again.stdout, "server-init twice installs once")
        print("cluster up, schema installed: %.1f s" % (time.monotonic() - started), flush=True)

        # The admin, created by the owner; everything else by the admin as themselves.
        centre.psql("SELECT records_create_user('admin1', 'admin', '%s')" % PASSWORD["admin1"])
        admin_sql = ["SELECT records_create_station('station_s%d', '%s')" % (k, PASSWORD["station_s%d" % k])
                     for k in STATIONS]
        admin_sql += ["SELECT records_create_user('%s', 'instructor', '%s')" % (i, PASSWORD[i]) for i in ("i1", "i2")]
        admin_sql += ["SELECT records_create_user('%s', 'trainee', '%s')" % (t, PASSWORD[t])
                      for t in sorted(PASSWORD) if t.startswith("t")]
        admin_sql += ["SELECT records_supervise('i1', '%s')" % t for t in ("t1", "t2", "t3")]
        admin_sql += ["SELECT records_supervise('i2', '%s')" % t for t in ("t4", "t5", "t6")]
        centre.psql("; ".join(admin_sql), user="admin1")
        rc, out = centre.psql("SELECT records_create_user('t9', 'trainee', '123456')", user="admin1", ok=False)
        check(rc != 0 and "password policy" in out, "a 6-digit PIN is refused as a server password: " + out.splitlines()[0])

        # Each trainee signs in as themselves on the station they train on (through that station's network).
        for k, trainees in TRAINEES.items():
            for t in trainees:
                r = centre.records(k, ["sign-in", "--server", "-", "--station", "station_s%d" % k], user=t)
                check(r.returncode == 0, "%s signs in on station_s%d: %s" % (t, k, r.stdout.strip()))
        env_wrong = dict(os.environ, PGPASSWORD="not-the-password")
        wrong = subprocess.run(["ip", "netns", "exec", station_ns(2), RECORDS, "--db", centre.station_db(2), "sign-in",
                                "--server", centre.conninfo(2, "t4"), "--station", "station_s2"],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env_wrong)
        check(wrong.returncode != 0 and "password authentication failed" in wrong.stdout,
              "a wrong password does not sign in")

        # Wave 1: every station imports and syncs concurrently; station 3 is offline throughout.
        centre.set_online(3, False)
        inbox = {k: os.path.join(tmp, "s%d" % k, "inbox") for k in STATIONS}
        for k in STATIONS:
            write_results(inbox[k] + "/w1", SESSIONS_PER_WAVE, TRAINEES[k], first=100 * k)
        # The same scripted sessions, unchanged, on stations 2 and 3: two sessions each on the server, one hash.
        write_results(inbox[2] + "/w1", len(REFERENCE), ["t3"], first=900, shift_stamps=False)
        write_results(inbox[3] + "/w1", len(REFERENCE), ["t5"], first=900, shift_stamps=False)
        # What the server must refuse from station 1: a trainee who never signed in there (t7), and guest.
        write_results(inbox[1] + "/w1", 2, ["t7"], first=990)
        write_results(inbox[1] + "/w1", 1, [], first=995)
        procs = []
        for k in STATIONS:
            script = "%s --db %s import %s/w1 >/dev/null && PGPASSWORD=%s %s --db %s sync --server '%s' --batch 4" % (
                RECORDS, centre.station_db(k), inbox[k], PASSWORD["station_s%d" % k], RECORDS, centre.station_db(k),
                centre.conninfo(k, "station_s%d" % k))
            procs.append(subprocess.Popen(["ip", "netns", "exec", station_ns(k), "bash", "-c", script],
                                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True))
        outs = [p.communicate()[0] for p in procs]
        check(procs[0].returncode == 3 and "3 held" in outs[0], "wave 1, station 1: synced, 3 held: " +
              outs[0].strip().splitlines()[-1])
        check(procs[1].returncode == 0, "wave 1, station 2 synced: " + outs[1].strip().splitlines()[-1])
        check(procs[2].returncode == 1 and "cannot connect" in outs[2],
              "wave 1, station 3 offline: its sync fails, its sessions stay: " + outs[2].strip().splitlines()[-1])

        # Station 3 runs its background sync (records sync --every 1, as a station would under a service) while it
        # is offline and while its wave 2 is imported next to it.
        background_log = open(os.path.join(tmp, "s3-background.log"), "w")
        background = centre.records(3, ["sync", "--server", "-", "--every", "1"], background=True, log=background_log)

        # Wave 2 imported everywhere; the server is killed in the middle of station 1's sync and restarted.
        for k in STATIONS:
            write_results(inbox[k] + "/w2", SESSIONS_PER_WAVE, TRAINEES[k], first=100 * k + 50)
            r = centre.records(k, ["import", inbox[k] + "/w2"])
            check(r.returncode == 0, "wave 2 imported on station %d" % k)
        # Station 1 as it is now, before the sync below: later the state of a station that crashed after the
        # server's COMMIT and before its own mark (its sessions on the server, still in its outbox).
        snapshot = os.path.join(tmp, "s1-before.sqlite")
        with sqlite3.connect(centre.station_db(1)) as live, sqlite3.connect(snapshot) as copy:
            live.backup(copy)
        with open(os.path.join(tmp, "s1-sync.log"), "w") as log:
            slow = centre.records(1, ["sync", "--server", "-", "--batch", "1", "--pause-ms", "150"], background=True,
                                  log=log)
            on_server = wait_for_count(centre, "station_s1", SESSIONS_PER_WAVE + 2)
            centre.kill9()
            rc = slow.wait(timeout=30)
        check(rc == 1, "station 1's sync fails when the server is killed (-9) under it (%d of its sessions were "
                       "on the server then)" % on_server)
        check(SESSIONS_PER_WAVE < on_server < 2 * SESSIONS_PER_WAVE,
              "the server was killed mid-sync (part of wave 2 uploaded)")
        centre.start()

        # Station 2's sync process is killed (-9) mid-sync.
        before = int(centre.value("SELECT count(*) FROM sessions WHERE station_id = 'station_s2'"))
        with open(os.path.join(tmp, "s2-sync.log"), "w") as log:
            slow = centre.records(2, ["sync", "--server", "-", "--batch", "1", "--pause-ms", "150"], background=True,
                                  log=log)
            wait_for_count(centre, "station_s2", before + 2)
            os.killpg(slow.pid, signal.SIGKILL)
            slow.wait(timeout=30)
        after = int(centre.value("SELECT count(*) FROM sessions WHERE station_id = 'station_s2'"))
        check(before < after < before + SESSIONS_PER_WAVE, "station 2 was killed mid-sync (%d -> %d of %d on the "
              "server)" % (before, after, before + SESSIONS_PER_WAVE))

        # Station 3 back online: its background sync uploads its backlog without being asked.
        centre.set_online(3, True)
        backlog = len(local_sessions(centre.station_db(3))[0])
        uploaded = wait_for_count(centre, "station_s3", backlog, timeout=60)
        os.killpg(background.pid, signal.SIGKILL)
        background.wait(timeout=10)
        background_log.close()
        check(uploaded == backlog, "station 3's background sync uploaded its %d sessions once it was back online (%d)"
              % (backlog, uploaded))

        # A live session: stored (and synced) before its bag's trajectory exists; session_trajectory --missing writes
        # it beside the bag later, and the next sync attaches it and adds it on the server, once.
        live = os.path.join(tmp, "s1", "live")
        os.makedirs(live)
        live_bag = os.path.join(live, "live_t1.bag")
        shutil.copy(REFERENCE[0][: -len(".result.json")] + ".bag", live_bag)
        write_results(live, 1, ["t1"], first=700, trajectory=False, bag=live_bag)
        r = centre.records(1, ["import", live])
        synced_before = centre.sync(1)
        live_key = [key for key, v in local_sessions(centre.station_db(1))[0].items() if v[6] == 0]
        check(len(live_key) == 1 and centre.value(
            "SELECT count(*) FROM trajectory_samples t JOIN sessions s ON s.id = t.session_id WHERE s.global_key = "
            "'%s'" % live_key[0]) == "0", "a live session goes up before its trajectory exists")
        run([TRAJECTORY, "--missing", live])

        # Everyone syncs to the end (twice: the second must find nothing to do).
        for k in STATIONS:
            first = centre.sync(k)
            second = centre.sync(k)
            expect = 3 if k == 1 else 0
            if k == 1:
                check("1 trajectories attached" in first.stdout, "station 1 attached the live session's trajectory")
            check(first.returncode == expect and second.returncode == expect,
                  "station %d synced: %s / %s" % (k, first.stdout.strip().splitlines()[-1],
                                                  second.stdout.strip().splitlines()[-1]))
            check(" 0 uploaded, 0 already" in " " + second.stdout.strip().splitlines()[-1],
                  "station %d: a second sync uploads nothing" % k)

        # The crash between the server's COMMIT and the station's mark: the re-sent sessions are recognised by their key.
        r = centre.records(1, ["sync", "--server", "-"], db=snapshot)
        check(r.stdout.strip().splitlines()[-1].startswith("0 uploaded, %d already on the server, 3 held"
                                                            % SESSIONS_PER_WAVE),
              "a station that lost its marks re-sends, and the server keeps one copy: " +
              r.stdout.strip().splitlines()[-1])

        # Every session exactly once, with all its items; the refused ones on their station only.
        rows = server_sessions(centre)
        keys = [r[0] for r in rows]
        check(len(keys) == len(set(keys)), "no session twice on the server (%d rows)" % len(keys))
        server = {r[0]: r for r in rows}
        expected = 0
        for k in STATIONS:
            local, integrity = local_sessions(centre.station_db(k))
            check(integrity == "ok", "station %d's store passes integrity_check" % k)
            held = {key: v for key, v in local.items() if v[0] in ("t7", "guest")}
            synced = {key: v for key, v in local.items() if key not in held}
            expected += len(synced)
            check(all(not v[1] for v in held.values()) and len(held) == (3 if k == 1 else 0),
                  "station %d: the refused sessions (%d) stay unsynced" % (k, len(held)))
            check(all(v[1] for v in synced.values()), "station %d: every other session is marked synced" % k)
            missing = [key for key in synced if key not in server]
            check(not missing, "station %d: all %d sessions on the server" % (k, len(synced)))
            wrong = [key for key, v in synced.items() if key in server and (
                server[key][1] != v[0] or server[key][2] != "station_s%d" % k or
                [int(x) for x in server[key][4:7]] != list(v[2:5]) or float(server[key][7]) != v[5] or
                int(server[key][8]) != v[6] or v[6] == 0)]
            check(not wrong, "station %d: user, station, items, groups, events, total and trajectory samples equal on "
                  "the server" % k)
            check(not any(key in server for key in held), "station %d: nothing refused reached the server" % k)
        check(len(rows) == expected, "the server holds exactly the stations' sessions (%d)" % expected)
        per_hash = {}
        for r in rows:
            per_hash.setdefault(r[3], set()).add(r[2])
        check(sum(1 for stations in per_hash.values() if stations == {"station_s2", "station_s3"}) == len(REFERENCE),
              "the same scripted session on two stations is two sessions (one content hash, two keys)")

        centre_export(centre, rows)
        schema_parity(centre)
        tls_checks(centre)
        role_checks(centre)
        print("centre_sync: %.1f s wall" % (time.monotonic() - started))
    finally:
        centre.stop()
        centre.netns_down()
        if keep or failures:
            print("centre_sync: logs kept in %s" % tmp)
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        print("FAILED: %d checks" % len(failures))
        return 1
    print("PASS centre_sync")
    return 0


def centre_export(centre, rows):
    """The data steward's export of the whole centre (records export --server as the database owner, on the server
    host), pseudonymised, read back with Python: every session once, its total and trajectory length as stored."""
    out = os.path.join(centre.tmp, "export")
    r = run([RECORDS, "export", "--server", "host=%s port=%d dbname=records user=postgres" % (centre.socket, centre.port),
             "--out-dir", out, "--pseudonym-key", os.path.join(centre.tmp, "centre.key")])
    tables = {}
    for name in ("sessions", "score_items", "trajectories"):
        with open(os.path.join(out, name + ".csv"), newline="") as f:
            tables[name] = list(csv.DictReader(f))
    by_key = {row[0]: row for row in rows}
    exported = {s["session_key"]: s for s in tables["sessions"]}
    check(len(tables["sessions"]) == len(rows) and set(exported) == set(by_key),
          "the centre's export lists every session on the server once (%d)" % len(rows))
    samples = {}
    for t in tables["trajectories"]:
        samples[t["session_key"]] = samples.get(t["session_key"], 0) + 1
    items = {}
    for t in tables["score_items"]:
        items[t["session_key"]] = items.get(t["session_key"], 0) + 1
    check(all(float(exported[k]["total"]) == float(by_key[k][7]) and samples.get(k, 0) == int(by_key[k][8]) and
              items.get(k, 0) == int(by_key[k][4]) for k in by_key),
          "the export's totals, score items and trajectory lengths are the server's")
    names = {s["user"] for s in tables["sessions"]} | {s["station"] for s in tables["sessions"]}
    check(all(n.startswith("p-") for n in names), "the centre's export is pseudonymised (%d pseudonyms)" % len(names))


def schema_parity(centre):
    """One schema, two back ends: the session data tables have the same columns on the station and on the server
    (the server adds its identity and centre columns: id, global_key, station_id, user_name, uploaded_at)."""
    con = sqlite3.connect("file:%s?mode=ro" % centre.station_db(1), uri=True)
    version = con.execute("PRAGMA user_version").fetchone()[0]
    check(centre.value("SELECT version FROM schema_info") == str(version),
          "station and server are at the same schema version (%d)" % version)
    server_only = {"global_key", "station_id", "user_name", "uploaded_at"}
    station_only = {"user_id", "synced_at"}
    for table in ("sessions", "score_items", "score_groups", "penalty_events", "trajectory_samples"):
        local = {row[1] for row in con.execute("PRAGMA table_info(%s)" % table)} - station_only - {"global_key"}
        remote = set(centre.value("SELECT string_agg(column_name, ',') FROM information_schema.columns "
                                  "WHERE table_name = '%s'" % table).split(",")) - server_only
        check(local == remote, "table %s: the same columns on both back ends %s" % (table, sorted(local ^ remote)))
    con.close()


def tls_checks(centre):
    """Station 3 is off the server's segment: its connections are TLS, and one without TLS is refused."""
    env = dict(os.environ, PGPASSWORD=PASSWORD["station_s3"])
    query = ["ip", "netns", "exec", station_ns(3), "psql", "-X", "-A", "-t", "-c",
             "SELECT ssl FROM pg_stat_ssl WHERE pid = pg_backend_pid()"]
    r = subprocess.run(query + ["-d", centre.conninfo(3, "station_s3")], stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True, env=env)
    check(r.returncode == 0 and r.stdout.strip() == "t", "station 3's connection is TLS, the certificate verified")
    r = subprocess.run(query + ["-d", centre.conninfo(3, "station_s3", sslmode="disable")], stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True, env=env)
    check(r.returncode != 0 and "no encryption" in r.stdout, "station 3 without TLS is refused")


def role_checks(centre):
    """What each may read and write, asked of the server directly (the policies, not the clients)."""
    own = centre.value("SELECT count(*), count(*) FILTER (WHERE user_name <> 't1') FROM sessions", user="t1")
    check(own.split("|")[0] != "0" and own.split("|")[1] == "0", "trainee t1 reads only their own sessions (%s)" % own)
    items = centre.value("SELECT count(DISTINCT session_id) FROM score_items", user="t1")
    check(items == own.split("|")[0], "trainee t1 reads only their own sessions' items")
    seen = centre.value("SELECT string_agg(DISTINCT user_name, ',' ORDER BY user_name) FROM sessions", user="i1")
    check(seen == "t1,t2,t3", "instructor i1 reads their trainees' sessions only (%s)" % seen)
    rc, out = centre.psql("SELECT count(*) FROM sessions", user="admin1", ok=False)
    check(rc != 0 and "permission denied" in out, "admin reads no sessions")
    rc, out = centre.psql("INSERT INTO sessions (global_key, session_key, station_id, user_name, scene, recorded_at) "
                          "VALUES ('x', 'x', 'station_s1', 't1', 'navigation', 'now')", user="t1", ok=False)
    check(rc != 0 and "permission denied" in out, "a trainee cannot insert sessions")
    rc, out = centre.psql("SELECT records_create_user('t8', 'trainee', 'trainee-secret-x8')", user="t1", ok=False)
    check(rc != 0, "a trainee cannot create users")
    rc, out = centre.psql("SELECT records_create_user('t8', 'admin', 'trainee-secret-x8')", user="i1", ok=False)
    check(rc != 0, "an instructor cannot create users")
    insert = ("BEGIN; SELECT records_hello(5); INSERT INTO sessions (global_key, session_key, station_id, user_name, "
              "scene, recorded_at) VALUES (gen_random_uuid()::text, 'x', current_user, '%s', 'navigation', 'now'); "
              "ROLLBACK")
    rc, out = centre.psql(insert % "t1", user="station_s1", ok=False)
    check(rc == 0, "station_s1 may insert a session of t1, who signed in on it " + out)
    rc, out = centre.psql(insert % "t3", user="station_s1", ok=False)
    check(rc != 0 and "row-level security" in out, "station_s1 may not insert for t3, who signed in elsewhere")
    rc, out = centre.psql(insert.replace("current_user", "'station_s2'") % "t1", user="station_s1", ok=False)
    check(rc != 0, "station_s1 may not insert under station_s2's name")
    rc, out = centre.psql(insert.replace("SELECT records_hello(5); ", "") % "t1", user="station_s1", ok=False)
    check(rc != 0 and "row-level security" in out, "a station that did not state its schema version inserts nothing")
    rc, out = centre.psql("SELECT records_hello(4)", user="station_s1", ok=False)
    check(rc != 0 and "station schema version 4 is older" in out and "update the station software" in out,
          "a station of schema version 4 is refused with a clear message: " + out.splitlines()[0][:160])
    others = centre.value("SELECT count(*) FROM sessions WHERE station_id <> 'station_s1'", user="station_s1")
    check(others == "0", "a station reads back only its own sessions")
    rc, out = centre.psql("SELECT count(*) FROM station_signins", user="t1", ok=False)
    check(rc != 0, "a trainee cannot read who signed in where")

    # A course assigned on the server by the instructor comes down to the trainee's station.
    course = "name: Basics\\nsteps:\\n  - module: navigation\\n    level: medium\\n    pass_mark: 50\\n"
    centre.psql("INSERT INTO course_assignments (user_name, course_name, course_text, assigned_by, assigned_at) "
                "VALUES ('t1', 'Basics', E'%s', 'i1', '2026-11-30T10:00:00Z')" % course, user="i1")
    rc, out = centre.psql("INSERT INTO course_assignments (user_name, course_name, course_text, assigned_by, "
                          "assigned_at) VALUES ('t4', 'Basics', 'x', 'i1', 'now')", user="i1", ok=False)
    check(rc != 0 and "row-level security" in out, "an instructor cannot assign a course to another's trainee")
    r = centre.sync(1)
    check("1 course assignments" in r.stdout, "the course comes down to station 1: " + r.stdout.strip()[-60:])
    con = sqlite3.connect(centre.station_db(1))
    course_here = con.execute("SELECT c.course_name FROM course_assignments c JOIN users u ON u.id = c.user_id "
                              "WHERE u.name = 't1'").fetchall()
    con.close()
    check(course_here == [("Basics",)], "station 1 has t1's course")

    # The instructor's centre view (what the console's centre screen shows), asked as i1 over station 1's network.
    expected = int(centre.value("SELECT count(*) FROM sessions WHERE user_name IN ('t1', 't2', 't3')"))
    r = centre.records(1, ["centre", "--server", "-"], user="i1")
    lines = r.stdout.strip().splitlines()
    curves = {tuple(line.split()[1:3]) for line in lines if line.startswith("curve ")}
    progress = [line for line in lines if line.startswith("progress ")]
    check(r.returncode == 0 and lines[0] == "%d sessions" % expected and {c[0] for c in curves} == {"t1", "t2", "t3"},
          "records centre as i1: every station's sessions of t1..t3 (%s), their learning curves" % lines[0])
    check(progress == ["progress t1 Basics 0/1", "progress t2 (no course) 0/0", "progress t3 (no course) 0/0"],
          "records centre as i1: the group's course progress %s" % progress)
    r = centre.records(1, ["centre", "--server", "-", "--station", "station_s2", "--scene", "navigation"],
                       user="i1")
    n = int(centre.value("SELECT count(*) FROM sessions WHERE user_name IN ('t1', 't2', 't3') "
                         "AND station_id = 'station_s2' AND scene = 'navigation'"))
    check(r.stdout.startswith("%d sessions" % n) and n > 0, "records centre filters by station and module (%d)" % n)

    # Deletion on request: t6's data leaves the server, and station 3 deletes its copy at the next sync.
    centre.psql("SELECT records_delete_user('t6')", user="admin1")
    check(centre.value("SELECT count(*) FROM sessions WHERE user_name = 't6'") == "0", "t6's sessions left the server")
    r = centre.sync(3)
    local, _ = local_sessions(centre.station_db(3))
    con = sqlite3.connect(centre.station_db(3))
    users = [u for (u,) in con.execute("SELECT name FROM users")]
    con.close()
    check(r.returncode == 0 and "t6" not in users and all(v[0] != "t6" for v in local.values()),
          "station 3 deleted t6 and their sessions at its next sync")
    rc, out = centre.psql("SELECT 1", user="t6", ok=False)
    check(rc != 0, "t6 can no longer sign in")


if __name__ == "__main__":
    sys.exit(main())
