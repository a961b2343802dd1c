#!/usr/bin/env python3
"""`records export` round trip (issue 41): the committed reference sessions, with the trajectories session_trajectory
takes from their bags, imported into a fresh store and exported as tidy CSV tables; read back here with Python's csv
module and compared with the result JSON files (scores) and the bags themselves (trajectory lengths, read with the
rosbag Python API, not with the C++ extractor). Then the pseudonymised export: no name, station or path left, the
same pseudonym for the same person with the same key, another with another key.

Usage: records_export.py   (EYESI_RECORDS_TOOL / EYESI_TRAJECTORY_TOOL override the built tools)
"""
import csv
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile

import rosbag

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "../../.."))
DEVEL = os.path.join(ROOT, "build/devel/lib/eyesi_gui")
RECORDS = os.environ.get("EYESI_RECORDS_TOOL", os.path.join(DEVEL, "records"))
TRAJECTORY = os.environ.get("EYESI_TRAJECTORY_TOOL", os.path.join(DEVEL, "session_trajectory"))
BAGS = os.path.join(ROOT, "src/vrm_sim/test/bags")
TABLES = ("sessions", "score_items", "score_groups", "penalty_events", "trajectories")

failures = []


def check(condition, what):
    print(("PASS " if condition else "FAIL ") + what, flush=True)
    if not condition:
        failures.append(what)


def run(*cmd):
    result = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        raise RuntimeError("%s: %s" % (" ".join(cmd), result.stdout))
    return result.stdout


def read_tables(folder):
    tables = {}
    for name in TABLES:
        with open(os.path.join(folder, name + ".csv"), newline="") as f:
            tables[name] = list(csv.DictReader(f))
    return tables


def samples_in_bag(path):
    """One sample per source and simulation frame (the eye and every slot), or per device message in an old bag."""
    with rosbag.Bag(path) as bag:
        frames = [m for _, m, _ in bag.read_messages(topics=["/input_frame"]) if m.kind == 0]
        if frames:
            return sum(1 + len(f.instruments) for f in frames)
        return bag.get_message_count(topic_filters=["/eye_state", "/instrument_state"])


def main():
    tmp = tempfile.mkdtemp(prefix="eyesi-export-")
    try:
        results = sorted(glob.glob(os.path.join(BAGS, "*.result.json")))
        inbox = os.path.join(tmp, "in")
        os.makedirs(inbox)
        expected = {}
        users = ["anna", "ben", "anna"]
        db = os.path.join(tmp, "records.sqlite")
        for i, result in enumerate(results):
            stem = os.path.basename(result)[: -len(".result.json")]
            shutil.copy(result, inbox)
            run(TRAJECTORY, os.path.join(BAGS, stem + ".bag"), "--out", os.path.join(inbox, stem + ".trajectory.json"))
            with open(result) as f:
                data = json.load(f)
            expected[(data["scene"], float(data["start_stamp"]))] = (data, samples_in_bag(
                os.path.join(BAGS, stem + ".bag")), users[i])
            run(RECORDS, "--db", db, "import", os.path.join(inbox, stem + ".result.json"), "--user", users[i])

        out = os.path.join(tmp, "plain")
        print(run(RECORDS, "--db", db, "export", "--out-dir", out).strip())
        t = read_tables(out)
        check(len(t["sessions"]) == len(results), "one sessions row per session (%d)" % len(t["sessions"]))
        for s in t["sessions"]:
            data, samples, user = expected[(s["scene"], float(s["start_stamp"]))]
            key = s["session_key"]
            check(float(s["total"]) == float(data["total"]) and s["user"] == user,
                  "%s: the total (%s) and the user read back" % (s["scene"], s["total"]))
            items = [r for r in t["score_items"] if r["session_key"] == key]
            check([(r["item"], float(r["points"]), float(r["value"])) for r in items] ==
                  [(it["name"], float(it["points"]), float(it["value"])) for it in data["items"]],
                  "%s: every score item, in order, with its value and points" % s["scene"])
            check(len([r for r in t["score_groups"] if r["session_key"] == key]) == len(data.get("groups", [])),
                  "%s: the factor groups" % s["scene"])
            check(len([r for r in t["penalty_events"] if r["session_key"] == key]) == len(data.get("events", [])),
                  "%s: the penalty events" % s["scene"])
            traj = [r for r in t["trajectories"] if r["session_key"] == key]
            check(len(traj) == samples and samples > 0,
                  "%s: %d trajectory samples, as many as the bag's frames x sources" % (s["scene"], len(traj)))
            check(all(float(r["time"]) >= 0 for r in traj) and {r["source"] for r in traj} >= {"eye"},
                  "%s: the eye's trajectory and times from the session's first frame" % s["scene"])

        key_file = os.path.join(tmp, "centre.key")
        first, second, other = (os.path.join(tmp, n) for n in ("p1", "p2", "p3"))
        run(RECORDS, "--db", db, "export", "--out-dir", first, "--pseudonym-key", key_file)
        check(oct(os.stat(key_file).st_mode & 0o777) == "0o600", "the pseudonym key file is the owner's only")
        run(RECORDS, "--db", db, "export", "--out-dir", second, "--pseudonym-key", key_file)
        run(RECORDS, "--db", db, "export", "--out-dir", other, "--pseudonym-key", os.path.join(tmp, "other.key"))
        text = "".join(open(os.path.join(first, n + ".csv")).read() for n in TABLES)
        stations = {d.get("station", "") for d, _, _ in expected.values()} - {""}
        leaked = [n for n in ["anna", "ben", tmp, BAGS] + sorted(stations) if n in text]
        check(not leaked, "the pseudonymised export names no user, station or path %s" % leaked)
        p1, p2, p3 = (read_tables(f)["sessions"] for f in (first, second, other))
        check([r["user"] for r in p1] == [r["user"] for r in p2], "the same key gives the same pseudonyms")
        check(len({r["user"] for r in p1}) == 2, "two people, two pseudonyms")
        check({r["user"] for r in p1}.isdisjoint({r["user"] for r in p3}), "another key gives other pseudonyms")
        check(all(len(r["recorded_at"]) == 10 for r in p1), "wall-clock times cut to the date")
        check([r["total"] for r in p1] == [r["total"] for r in t["sessions"]], "the scores stay as they are")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        print("FAILED: %d checks" % len(failures))
        return 1
    print("PASS records_export")
    return 0


if __name__ == "__main__":
    sys.exit(main())
