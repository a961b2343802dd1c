#!/usr/bin/env python3
"""Soak monitor (issue 14 §4), started by scripts/soak.sh next to the product graph on the soak's own master.

Once a second it samples /proc for the nodelet manager and every other process of the graph (RSS, CPU time; a
process that died or came back with another pid counts as a crash), counts the messages of the watched topics and
reads the renderer's and the latency monitor's /diagnostics. Once a minute it writes one row (RSS, CPU %, rates,
dropped frames, latency p99) and, half-way through every minute, cycles the scenario STOP -> LOAD -> START with
vrm_msgs/ScenarioCommand on /scenario_command, stamped like the console does (a little after the newest
/simulation_state stamp: the commands are session inputs, recorded in the bag and applied to the same frames in a
replay). The view's rate is counted on /render_timing (one per frame rendered, both eyes) and /display_timing (one
per frame the headless station's display twin shows): the display twin watches the renderer, as a station's screen
does, so the monitor need not take the images. Taking them (2 x 1.4 MB at 15-25 Hz through rospy) cost the monitor
56-58 % of a core in the soak of 2026-11-29, on the two cores the graph shares. --images subscribes them as well
(rospy.AnyMsg, counted, never deserialised). The monitor's own CPU is a column.

The JSON (--out) holds the rows, the verdict (RSS growth <= 5 % from the baseline minute to the end, no rate below
90 % of the baseline minute's, zero crashes; baseline minute 5, or minute 1 with fewer than 6 minutes: smoke mode)
and what the run was. Exit status 0 = verdict PASS, 1 = FAIL, 2 = the graph never came up.
"""
import argparse
import json
import os
import socket
import struct
import sys
import threading
import time

import rospy
from vrm_msgs.msg import ScenarioCommand, ScenarioStatus

TICKS = os.sysconf("SC_CLK_TCK")
PAGE = os.sysconf("SC_PAGE_SIZE")
RATE_TOPICS = ["/eye_state", "/instrument_state", "/simulation_state", "/render_timing", "/display_timing"]
IMAGE_TOPICS = ["/stereo/left/image_raw", "/stereo/right/image_raw"]
# Judged against the baseline: the steady streams. /tissue/<object> is published only when the tissue changed, i.e.
# depending on where the looping demo script is relative to the scenario cycle; its rate is reported, not judged.
JUDGED_TOPICS = RATE_TOPICS


def judged_topics(args):
    return JUDGED_TOPICS + (IMAGE_TOPICS if args.images else [])


def parse_diagnostics(buff):
    """[(name, hardware_id, {key: value})] of a serialised diagnostic_msgs/DiagnosticArray (python3 has no
    diagnostic_msgs module on this system; the layout is small: Header, then DiagnosticStatus[])."""
    offset = 12  # seq, stamp

    def string():
        nonlocal offset
        (length,) = struct.unpack_from("<I", buff, offset)
        offset += 4 + length
        return bytes(buff[offset - length:offset]).decode(errors="replace")

    string()  # frame_id
    (count,) = struct.unpack_from("<I", buff, offset)
    offset += 4
    statuses = []
    for _ in range(count):
        offset += 1  # level
        name, _message, hardware_id = string(), string(), string()
        (pairs,) = struct.unpack_from("<I", buff, offset)
        offset += 4
        values = {}
        for _ in range(pairs):
            key = string()
            values[key] = string()
        statuses.append((name, hardware_id, values))
    return statuses


def read_proc(pid):
    """(utime + stime in s, RSS in bytes, start time in ticks) of a live process, else None."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        with open(f"/proc/{pid}/statm") as f:
            rss_pages = int(f.read().split()[1])
    except (OSError, IndexError, ValueError):
        return None
    # fields[0] is field 3 (state): utime = field 14, stime = 15, starttime = 22.
    return (int(fields[11]) + int(fields[12])) / TICKS, rss_pages * PAGE, int(fields[19])


def children(pid):
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            return [int(p) for p in f.read().split()]
    except OSError:
        return []


def node_name(pid):
    """The ROS name of a process of the launch (__name:=X; rosmaster), else None (a helper such as `rosparam`)."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            args = f.read().decode(errors="replace").split("\0")
    except OSError:
        return None
    for arg in args:
        if arg.startswith("__name:="):
            return arg[len("__name:="):]
    if len(args) > 1 and args[1].endswith("rosmaster"):
        return "rosmaster"
    return None


class Graph:
    """The launch's ROS processes by name (every descendant of roslaunch, so a supervisor's child counts too: a
    process named like its parent keeps the name, the parent becomes "NAME (supervisor)"). A pid that vanished or
    changed under a name is a crash (or a respawn)."""

    def __init__(self, launch_pid, manager):
        self.launch_pid = launch_pid
        self.manager = manager
        self.pids = {}  # name -> (pid, starttime)
        self.crashes = []  # {"t", "node", "old_pid", "new_pid"}
        # Scans each (pid, start) was seen in: a process seen once is a shell's command substitution (it carries the
        # script's command line, __name:= included, e.g. session_recorder's $(rosparam get ...)), not a node.
        self.seen = {}
        self.supervisors = set()  # pids of processes whose child has their name (supervised_manager, rosbag)

    def processes(self):
        found = {}  # pid -> (name, parent name)
        stack = [(pid, None) for pid in children(self.launch_pid)]
        while stack:
            pid, parent = stack.pop()
            name = node_name(pid)
            if name:
                found[pid] = (name, parent)
            stack += [(child, name) for child in children(pid)]
        supervised = {parent for name, parent in found.values() if parent == name}
        for pid, (name, parent) in found.items():
            if name in supervised and parent != name:
                self.supervisors.add(pid)  # stays one while its child is down between restarts
        return {f"{name} (supervisor)" if pid in self.supervisors else name: pid for pid, (name, _) in found.items()}

    def scan(self, t):
        found = {}
        for name, pid in self.processes().items():
            sample = read_proc(pid)
            if sample:
                found[name] = (pid, sample[2], sample)
        alive = {(pid, start) for pid, start, _ in found.values()}
        for name, (pid, start) in list(self.pids.items()):
            if (pid, start) in alive:
                continue  # still running (perhaps under another label: a supervisor's child appeared)
            sample = read_proc(pid)
            if sample and sample[2] == start:
                continue  # alive, though no longer under roslaunch's tree this instant
            now = found.get(name)
            if self.seen.get((pid, start), 0) >= 2:
                self.crashes.append({"t": round(t, 1), "node": name, "old_pid": pid,
                                     "new_pid": now[0] if now and now[0] != pid else None})
            del self.pids[name]
        for name, (pid, start, _) in found.items():
            self.pids[name] = (pid, start)
            self.seen[(pid, start)] = self.seen.get((pid, start), 0) + 1
        return {name: sample for name, (_, _, sample) in found.items()}


class Monitor:
    def __init__(self, args):
        self.args = args
        self.lock = threading.Lock()
        self.counts = {}
        self.newest_stamp = rospy.Time(0)
        self.status = None
        self.diag = {"render_fps": [], "render_dropped": 0, "render_frames": 0, "p99": {}}
        self.subscribers = []
        for topic in RATE_TOPICS + (IMAGE_TOPICS if args.images else []):
            self.watch(topic)
        self.command_pub = rospy.Publisher("/scenario_command", ScenarioCommand, queue_size=5)
        rospy.Subscriber("/scenario_status", ScenarioStatus, self.on_status, queue_size=5)
        rospy.Subscriber("/diagnostics", rospy.AnyMsg, self.on_diagnostics, queue_size=50)

    def watch(self, topic):
        self.counts.setdefault(topic, 0)
        callback = self.on_state if topic == "/simulation_state" else (lambda _m, t=topic: self.count(t))
        # Big buffer for the images: a stereo frame is 2 x 1.4 MB; AnyMsg keeps the bytes as they came.
        self.subscribers.append(rospy.Subscriber(topic, rospy.AnyMsg, callback, queue_size=2, buff_size=1 << 24,
                                                 tcp_nodelay=True))

    def watch_tissue(self):
        """Tissue topics appear with the scene (tissue/<object>); watch those that exist."""
        try:
            topics = rospy.get_published_topics()
        except Exception:  # the master is gone: the graph scan reports it
            return
        for name, kind in topics:
            if name.startswith("/tissue/") and kind == "vrm_msgs/TissueMesh" and name not in self.counts:
                self.watch(name)

    def count(self, topic):
        self.counts[topic] += 1  # one callback thread per topic: no other writer

    def on_state(self, message):
        # AnyMsg: the header's stamp is bytes 4..12 (seq, secs, nsecs); no full deserialisation needed.
        secs, nsecs = struct.unpack_from("<II", message._buff, 4)
        stamp = rospy.Time(secs, nsecs)
        with self.lock:
            if stamp > self.newest_stamp:
                self.newest_stamp = stamp
        self.counts["/simulation_state"] += 1

    def on_status(self, status):
        with self.lock:
            self.status = status

    def on_diagnostics(self, message):
        try:
            statuses = parse_diagnostics(message._buff)
        except struct.error:
            return
        with self.lock:
            for name, hardware_id, values in statuses:
                if hardware_id == "stereo_view":
                    self.diag["render_dropped"] += int(values.get("dropped", 0))
                    self.diag["render_frames"] += int(values.get("frames", 0))
                    self.diag["render_fps"].append(float(values.get("fps", 0)))
                elif hardware_id == "vrm_graph" and "latency p99 ms" in values:
                    stage = name.split(": ", 1)[-1]
                    if int(values.get("frames in window", 0)) > 0:
                        self.diag["p99"].setdefault(stage, []).append(float(values["latency p99 ms"]))

    def take_diagnostics(self):
        with self.lock:
            taken = self.diag
            self.diag = {"render_fps": [], "render_dropped": 0, "render_frames": 0, "p99": {}}
        return taken

    def state(self):
        with self.lock:
            return None if self.status is None else self.status.state

    def send(self, command, scenario="", argument="", ahead=0.2):
        message = ScenarioCommand()
        with self.lock:
            base = self.newest_stamp
        message.header.stamp = base + rospy.Duration(ahead)
        message.command = command
        message.scenario = scenario
        message.argument = argument
        message.seed = self.args.seed
        self.command_pub.publish(message)

    def wait_state(self, wanted, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end and not rospy.is_shutdown():
            if self.state() in wanted:
                return True
            time.sleep(0.05)
        return False

    def cycle(self):
        """STOP -> LOAD -> START as the console does it; returns what happened (each step waits on the status)."""
        started = time.monotonic()
        steps = {}
        self.send(ScenarioCommand.STOP, argument="soak cycle")
        steps["stop"] = self.wait_state({ScenarioStatus.FINISHED, ScenarioStatus.FAILED, ScenarioStatus.IDLE}, 5.0)
        with self.lock:
            self.status = None  # the LOAD's status (a new world: idle) must be a new message
        self.send(ScenarioCommand.LOAD, scenario=self.args.scene)
        steps["load"] = self.wait_state({ScenarioStatus.IDLE}, 10.0)
        self.send(ScenarioCommand.START, ahead=0.5)
        steps["start"] = self.wait_state({ScenarioStatus.RUNNING}, 10.0)
        steps["seconds"] = round(time.monotonic() - started, 2)
        steps["ok"] = steps["stop"] and steps["load"] and steps["start"]
        return steps


def p99_summary(values):
    return {"max": round(max(values), 2), "median": round(sorted(values)[len(values) // 2], 2)} if values else None


def own_cpu():
    t = os.times()
    return t.user + t.system


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=int, default=30)
    parser.add_argument("--launch-pid", type=int, required=True)
    parser.add_argument("--manager", default="vrm_manager")
    parser.add_argument("--scene", default="membrane_peeling")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--minute", type=float, default=60.0, help="s per row (tests: shorter)")
    parser.add_argument("--warmup-timeout", type=float, default=180.0)
    parser.add_argument("--images", action="store_true",
                        help="also take both eyes' images (counted, judged like the rest); the monitor then costs more")
    parser.add_argument("--no-cycle", action="store_true", help="never cycle the scenario (a control run)")
    parser.add_argument("--bag", default="")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()

    rospy.init_node("soak_monitor", disable_signals=True)
    monitor = Monitor(args)
    graph = Graph(args.launch_pid, args.manager)
    smoke = args.minutes < 6
    baseline = 1 if smoke else 5

    # Warm-up: the graph is up when frames are simulated, the scenario runs (session_control's START) and both eyes
    # arrive; the manager is known; the command publisher reaches the scenario manager and the recorder.
    deadline = time.monotonic() + args.warmup_timeout
    ready = False
    while time.monotonic() < deadline and not rospy.is_shutdown():
        graph.scan(0.0)
        counts = dict(monitor.counts)
        ready = (args.manager in graph.pids and counts["/simulation_state"] > 0 and
                 counts["/display_timing"] > 0 and monitor.state() == ScenarioStatus.RUNNING and
                 monitor.command_pub.get_num_connections() >= 2)
        if ready:
            break
        time.sleep(0.5)
    if not ready:
        print(f"soak_monitor: the graph did not come up within {args.warmup_timeout:.0f} s "
              f"(manager {'found' if args.manager in graph.pids else 'missing'}, counts {dict(monitor.counts)}, "
              f"scenario state {monitor.state()})", file=sys.stderr)
        return 2
    time.sleep(5.0)  # the first frames, caches, the renderer's first shaders
    monitor.watch_tissue()
    print(f"soak_monitor: graph up ({len(graph.pids)} processes, manager pid {graph.pids[args.manager][0]}); "
          f"{args.minutes} min of {args.minute:.0f} s, scenario cycled every minute"
          f"{'; smoke mode: baseline minute 1' if smoke else ''}", flush=True)

    rows = []
    t0 = time.monotonic()
    samples = graph.scan(0.0)
    cpu_start = {name: s[0] for name, s in samples.items()}
    count_start = dict(monitor.counts)
    own_start = own_cpu()
    monitor.take_diagnostics()
    cycles = []
    for minute in range(1, args.minutes + 1):
        minute_start = time.monotonic()
        rss_max = 0
        cycled = False
        graph_alive = True
        while time.monotonic() - minute_start < args.minute and not rospy.is_shutdown():
            time.sleep(1.0)
            t = time.monotonic() - t0
            samples = graph.scan(t)
            if args.manager in samples:
                rss_max = max(rss_max, samples[args.manager][1])
            if not samples or not os.path.exists(f"/proc/{args.launch_pid}"):
                graph_alive = False
                break
            if not cycled and not args.no_cycle and time.monotonic() - minute_start >= args.minute / 2:
                cycled = True
                steps = monitor.cycle()
                steps["minute"] = minute
                cycles.append(steps)
                if not steps["ok"]:
                    print(f"soak_monitor: minute {minute}: the scenario cycle did not complete: {steps}", flush=True)
                monitor.watch_tissue()
        elapsed = time.monotonic() - minute_start
        counts = dict(monitor.counts)
        diagnostics = monitor.take_diagnostics()
        own = own_cpu()
        manager = samples.get(args.manager)
        cpu = {name: (s[0] - cpu_start.get(name, s[0])) / elapsed * 100.0 for name, s in samples.items()}
        row = {
            "minute": minute,
            "seconds": round(elapsed, 1),
            "manager_rss_mb": round(manager[1] / 2**20, 1) if manager else None,
            "manager_rss_max_mb": round(rss_max / 2**20, 1),
            "manager_cpu_percent": round(cpu.get(args.manager, 0.0), 1),
            "graph_rss_mb": round(sum(s[1] for s in samples.values()) / 2**20, 1),
            "graph_cpu_percent": round(sum(cpu.values()), 1),
            "graph_processes": len(samples),
            "monitor_cpu_percent": round((own - own_start) / elapsed * 100.0, 1),
            "load_average": round(os.getloadavg()[0], 2),  # the host's 1-min load: a shared machine shows here
            "rates_hz": {topic: round((counts[topic] - count_start.get(topic, 0)) / elapsed, 2)
                         for topic in sorted(counts)},
            "render_frames": diagnostics["render_frames"],
            "render_dropped": diagnostics["render_dropped"],
            "render_fps_mean": round(sum(diagnostics["render_fps"]) / len(diagnostics["render_fps"]), 1)
            if diagnostics["render_fps"] else None,
            "latency_p99_ms": {stage: p99_summary(v) for stage, v in sorted(diagnostics["p99"].items())},
            "crashes_total": len(graph.crashes),
            "scenario_cycles_ok": sum(1 for c in cycles if c["ok"]),
        }
        rows.append(row)
        cpu_start = {name: s[0] for name, s in samples.items()}
        count_start = counts
        own_start = own
        e2e = (row["latency_p99_ms"].get("end_to_end") or {}).get("max")
        print(f"soak_monitor: minute {minute}: manager RSS {row['manager_rss_mb']} MB, CPU {row['manager_cpu_percent']} %"
              f" (graph {row['graph_cpu_percent']} %, monitor {row['monitor_cpu_percent']} %), simulation "
              f"{row['rates_hz'].get('/simulation_state')} Hz, view {row['rates_hz'].get('/display_timing')} Hz,"
              f" dropped {row['render_dropped']}, end-to-end p99 {e2e} ms, crashes {len(graph.crashes)}", flush=True)
        if not graph_alive:
            print("soak_monitor: the graph is gone (roslaunch ended: a required node died)", flush=True)
            break

    result = verdict(rows, graph, cycles, args, baseline, smoke)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)
        f.write("\n")
    print(f"soak_monitor: {result['verdict']['result']}: " + "; ".join(result["verdict"]["reasons"] or ["all targets met"]))
    return 0 if result["verdict"]["result"] == "PASS" else 1


def verdict(rows, graph, cycles, args, baseline, smoke):
    reasons = []
    base = rows[baseline - 1] if len(rows) >= baseline else None
    last = rows[-1] if rows else None
    growth = None
    if len(rows) < args.minutes:
        reasons.append(f"ended after {len(rows)} of {args.minutes} minutes")
    if base and last and base["manager_rss_mb"] and last["manager_rss_mb"]:
        growth = (last["manager_rss_mb"] - base["manager_rss_mb"]) / base["manager_rss_mb"] * 100.0
        if growth > 5.0:
            reasons.append(f"manager RSS grew {growth:.1f} % from minute {baseline} to minute {last['minute']} (> 5 %)")
    elif rows:
        reasons.append(f"no manager RSS at minute {baseline} or at the end")
    low = []
    if base:
        for row in rows[baseline:]:
            for topic in judged_topics(args):
                rate = row["rates_hz"].get(topic, 0.0)
                reference = base["rates_hz"].get(topic, 0.0)
                if reference > 0 and rate < 0.9 * reference:
                    low.append(f"{topic} {rate} Hz at minute {row['minute']} (< 90 % of {reference} Hz)")
    reasons += low
    if graph.crashes:
        reasons.append(f"{len(graph.crashes)} crashes: " +
                       ", ".join(f"{c['node']} (pid {c['old_pid']} -> {c['new_pid']})" for c in graph.crashes))
    failed_cycles = [c["minute"] for c in cycles if not c["ok"]]
    if failed_cycles:
        reasons.append(f"scenario cycle incomplete at minutes {failed_cycles}")
    return {
        "suite": "soak",
        "host": socket.gethostname(),
        "cores": os.cpu_count(),
        "date_utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()),
        "minutes": args.minutes,
        "minute_seconds": args.minute,
        "smoke": smoke,
        "baseline_minute": baseline,
        "scene": args.scene,
        "bag": args.bag,
        "graph": "launch/simulator.launch headless:=true sim:=true tracking:=true record:=true, render watched by "
                 "the display twin" + (" and this monitor (--images: both eyes)" if args.images else
                                       " (the view counted on render_timing / display_timing)") +
                 ", built-in demo script looping, " +
                 ("scenario never cycled (--no-cycle control run)" if args.no_cycle else
                  "scenario STOP/LOAD/START every minute"),
        "cycled": not args.no_cycle,
        "judged_topics": judged_topics(args),
        "notes": "rates in Hz over each minute (/tissue/* reported, not judged: published only when the tissue "
                 "changed); CPU in % of one core; load_average = the host's 1-min load at the end of the minute; latency_p99_ms per stage = max and median of "
                 "the latency monitor's 10 s-window p99 reported during the minute; render_dropped = the renderer's "
                 "replaced triggers (diagnostics 'dropped') summed over the minute",
        "rows": rows,
        "crashes": graph.crashes,
        "cycles": cycles,
        "verdict": {
            "result": "PASS" if not reasons else "FAIL",
            "reasons": reasons,
            "manager_rss_growth_percent": None if growth is None else round(growth, 2),
            "targets": f"manager RSS growth <= 5 % from minute {baseline} to the end; no rate below 90 % of minute "
                       f"{baseline}'s; zero crashes" + ("; smoke mode (< 6 minutes): baseline minute 1" if smoke
                                                        else ""),
        },
    }


if __name__ == "__main__":
    sys.exit(main())
