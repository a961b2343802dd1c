#!/usr/bin/env python3
"""bench_determinism (issue 31): live = replay under load. Records run.sh's session (membrane_peeling, the scripted
expert, tracking:=false, headless, rendered, 12 s) RUNS times per perturbation — each alone, then all at once — and
compares the live result (final state hash and score) with two offline replays of the same bag: from its recorded
input frames (what session_replay and replay.launch do since issue 31) and from its device topics through the mediator
(session_replay --input devices: how a bag replayed before). Prints a table, writes JSON.

Usage (scripts/bench.sh determinism): bench_determinism [--quick] [--runs N] [--configs a,b] [--out FILE]
  --quick: one recording of the all-at-once configuration.
  --configs: only these configurations; their records replace those in an existing --out file (the others are kept),
             e.g. to measure again the runs a shared machine's rebuild broke (the JSON lists every command).
Perturbations (src/vrm_sim/test/graph/determinism.py): idle = none; busy = two shell busy loops on the two cores for the
recording; delay = the test relay holds instrument:right back by 3 of its messages on its way to the simulation
node only; eye_100hz = the eye state at 100 Hz, instruments at 50 Hz; silence = the relay drops instrument:right for
1 s from 1 s after START; all = every one at once (the CI test's configuration).
idle and busy play the same inputs: their live final states must be one (idle_vs_loaded in the JSON).
"""
import argparse
import json
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, "@PROJECT_SOURCE_DIR@/test/graph")
import determinism  # noqa: E402

CONFIGS = [
    ("idle", dict()),
    ("busy", dict(busy=2)),
    ("delay", dict(delay="instrument:right")),
    ("eye_100hz", dict(eye_rate=100.0)),
    ("silence", dict(silence="instrument:right")),
    ("all", dict(determinism.ALL)),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--duration", type=float, default=12.0)
    parser.add_argument("--configs", default="")
    parser.add_argument("--out", default="")
    args = parser.parse_args()
    configs = [c for c in CONFIGS if c[0] == "all"] if args.quick else CONFIGS
    if args.configs:
        wanted = args.configs.split(",")
        unknown = set(wanted) - {c[0] for c in CONFIGS}
        if unknown:
            parser.error("unknown configs %s (have %s)" % (sorted(unknown), [c[0] for c in CONFIGS]))
        configs = [c for c in CONFIGS if c[0] in wanted]
    runs = 1 if args.quick else args.runs
    command = "./scripts/bench.sh " + ("--quick " if args.quick else "") + "determinism"
    if args.configs:
        command = "build/devel/lib/vrm_sim/bench_determinism --configs %s --out %s" % (args.configs, args.out)
    work = tempfile.mkdtemp(prefix="bench_determinism_")
    records = []
    start = time.monotonic()
    for name, perturbation in configs:
        for run in range(runs):
            out_dir = os.path.join(work, "%s_%d" % (name, run))
            try:
                record = determinism.record_session(out_dir, duration=args.duration, **perturbation)
            except Exception as error:  # a failed recording is a row of its own, not the end of the benchmark
                record = {"error": str(error), "equal_frames": False, "equal_devices": False, "live": {}}
            record.update(config=name, run=run)
            records.append(record)
            live = record["live"]
            print("%-10s run %d: live %s score %s late %s without_source %s | frames %s | devices %s%s | load %.1f" % (
                name, run, live.get("final_state_hash"), live.get("total"), live.get("late_inputs"),
                live.get("frames_without_source"), "=" if record["equal_frames"] else "DIFFERS",
                "=" if record["equal_devices"] else "differs",
                " (%s)" % record["replay_devices"].get("final_state_hash") if "replay_devices" in record else "",
                record.get("load_after", 0.0)), flush=True)
    commands = [command]
    if args.configs and args.out and os.path.exists(args.out):
        with open(args.out) as f:
            previous = json.load(f)
        kept = [r for r in previous["records"] if r["config"] not in {c[0] for c in configs}]
        records = kept + records
        commands = previous.get("commands", [previous["command"]]) + commands
        command = previous["command"]
    summary = []
    for name, _ in CONFIGS:
        if not any(r["config"] == name for r in records):
            continue
        rows = [r for r in records if r["config"] == name]
        late = [r["live"].get("late_inputs") or 0 for r in rows]
        without = [r["live"].get("frames_without_source") or 0 for r in rows]
        summary.append({
            "config": name,
            "runs": len(rows),
            "live_equals_replay_frames": sum(r["equal_frames"] for r in rows),
            "live_equals_replay_devices": sum(r["equal_devices"] for r in rows),
            "late_inputs": [min(late), max(late)],
            "frames_without_source": [min(without), max(without)],
            "load_max": max(r.get("load_after", 0.0) for r in rows),
            "distinct_live_hashes": len({r["live"].get("final_state_hash") for r in rows}),
        })
    # The same script with the same inputs, idle and under busy loops: one live state (issue 31 item 5).
    same_inputs = [r for r in records if r["config"] in ("idle", "busy")]
    idle_vs_loaded = {
        "runs": len(same_inputs),
        "distinct_live_hashes": len({r["live"].get("final_state_hash") for r in same_inputs}),
        "distinct_live_totals": len({r["live"].get("total") for r in same_inputs}),
    }
    if same_inputs:
        print("idle and busy: %d runs, %d distinct live state hash(es), %d distinct score(s)" % (
            idle_vs_loaded["runs"], idle_vs_loaded["distinct_live_hashes"], idle_vs_loaded["distinct_live_totals"]))
    print("\n%-10s %-30s %-31s %-13s %-15s %s" % ("config", "live == replay (frames)", "live == replay (devices)",
                                                  "late_inputs", "without_source", "load"))
    for s in summary:
        print("%-10s %-30s %-31s %-13s %-15s %.1f" % (
            s["config"], "%d of %d" % (s["live_equals_replay_frames"], s["runs"]),
            "%d of %d" % (s["live_equals_replay_devices"], s["runs"]), "%d-%d" % tuple(s["late_inputs"]),
            "%d-%d" % tuple(s["frames_without_source"]), s["load_max"]))
    result = {"suite": "determinism", "command": command, "commands": commands, "quick": args.quick,
              "runs_per_config": runs,
              "duration": args.duration, "wall_seconds": round(time.monotonic() - start, 1),
              "summary": summary, "idle_vs_loaded": idle_vs_loaded, "records": records}
    if args.out:
        with open(args.out, "w") as f:
            json.dump(result, f, indent=1)
    shutil.rmtree(work, ignore_errors=True)
    return 0 if all(s["live_equals_replay_frames"] == s["runs"] for s in summary) else 1


if __name__ == "__main__":
    sys.exit(main())
