#!/usr/bin/env python3
"""The station keeps one session graph up across sessions (issue 32), against the real graph on a master of its own.

  test     Two consecutive recorded live sessions with different scenes (membrane_peeling, then navigation) run in
           ONE graph: the nodelet manager (/vrm_manager) has the same process id for both; each session has its own
           closed bag whose session_info names its scene (and its seed); the second session, started and stopped,
           gets a result file with its bag and trainee, and its bag replays offline to the result's final state. A
           load_session of a scene that does not exist is sent as a LOAD, reported with the scene owner's reason,
           and leaves the previous scene running (same announcement, frames going on, the same manager process).
  measure  Time from load_session to the new scene's first simulation_state and to the station's READY, for
           --runs loads alternating between two scenes, with the station given by --station (default: this
           workspace's session_station). A station that relaunches the graph per session shows the relaunch time.

Every wait is on a condition with a timeout. Prints PASS/FAIL lines and exits 1 on any failure.
Usage: station_one_graph.py test|measure [--port N] [--out DIR] [--runs N] [--station PATH] [--record true|false]
(run with the workspace sourced: scripts/common.sh)
"""
import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import xmlrpc.client

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "scripts"))
import session_result  # noqa: E402  (scripts/session_result.py)

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
FAILURES = []
SCENE_A, SCENE_B, MISSING = "membrane_peeling", "navigation", "no_such_scene"


def check(name, ok, detail=""):
    print(("PASS: " if ok else "FAIL: ") + name + ("" if ok or not detail else " (" + str(detail) + ")"), flush=True)
    if not ok:
        FAILURES.append(name)
    return ok


def wait_for(condition, timeout, step=0.05):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(step)
    return condition()


class Station:
    """A master, the session station (which launches the graph) and this process as a ROS node watching it."""

    def __init__(self, out, port, station_binary):
        self.out = out
        os.environ["ROS_MASTER_URI"] = "http://localhost:%d" % port
        os.environ.setdefault("ROS_HOSTNAME", "localhost")
        os.environ["ROS_LOG_DIR"] = os.path.join(out, "ros_log")
        self.records = os.path.join(out, "sessions")
        self.logs = []
        self.processes = []
        self.master = xmlrpc.client.ServerProxy(os.environ["ROS_MASTER_URI"])
        self._spawn(["roscore", "-p", str(port)], "roscore.log")
        if not wait_for(self._master_up, 30, 0.2):
            raise RuntimeError("no ROS master on port %d" % port)
        launch = os.path.join(ROOT, "launch")
        station = [station_binary] if station_binary else ["rosrun", "eyesi_gui", "session_station"]
        self.station_command = station + [
            "__name:=station", "_simulator_launch:=" + os.path.join(launch, "simulator.launch"),
            "_replay_launch:=" + os.path.join(launch, "replay.launch"),
            "_recorder_launch:=" + os.path.join(launch, "recorder.launch"), "_records_dir:=" + self.records,
            "_launch_args:=sim:=true tracking:=false", "_script:=scenario:expert"]
        self.station = self._spawn(self.station_command, "station.log")
        import rospy  # after ROS_MASTER_URI is set
        from vrm_msgs.msg import RunningScene, ScenarioCommand, ScenarioStatus, SimulationState, StationStatus
        self.rospy = rospy
        rospy.init_node("station_one_graph", anonymous=True, disable_signals=True)
        self.lock = threading.Lock()
        self.statuses = []  # (monotonic, StationStatus)
        self.scenes = []  # (monotonic, RunningScene)
        self.frames = []  # monotonic of each simulation_state
        self.scenario = []  # (monotonic, ScenarioStatus)
        self.subscribers = [
            rospy.Subscriber("/station/station_status", StationStatus, self._append(self.statuses), queue_size=50),
            rospy.Subscriber("/running_scene", RunningScene, self._append(self.scenes), queue_size=10),
            rospy.Subscriber("/scenario_status", ScenarioStatus, self._append(self.scenario), queue_size=50),
            rospy.Subscriber("/simulation_state", SimulationState, self._on_frame, queue_size=50),
        ]
        self.command = rospy.Publisher("/scenario_command", ScenarioCommand, queue_size=5)
        self.ScenarioCommand = ScenarioCommand
        self.StationStatus = StationStatus
        rospy.wait_for_service("/station/load_session", timeout=30)

    def crash_station(self):
        """kill -9 of the station alone (its graphs run in process groups of their own)."""
        self.station.kill()
        self.station.wait()

    def restart_station(self, log):
        self.station = self._spawn(self.station_command, log)
        self.rospy.wait_for_service("/station/load_session", timeout=30)

    def state_file(self):
        try:
            with open(os.path.join(self.records, "station_state.json")) as handle:
                return json.load(handle)
        except (OSError, ValueError):
            return None

    def _spawn(self, command, log):
        handle = open(os.path.join(self.out, log), "w")
        self.logs.append(handle)
        process = subprocess.Popen(command, stdout=handle, stderr=subprocess.STDOUT, start_new_session=True)
        self.processes.append(process)
        return process

    def _master_up(self):
        try:
            return self.master.getSystemState("/station_one_graph")[0] == 1
        except OSError:
            return False

    def _append(self, series):
        def callback(message):
            with self.lock:
                series.append((time.monotonic(), message))
        return callback

    def _on_frame(self, _message):
        with self.lock:
            self.frames.append(time.monotonic())

    def pid(self, node):
        try:
            code, _, uri = self.master.lookupNode("/station_one_graph", node)
            if code != 1:
                return None
            code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/station_one_graph")
            return pid if code == 1 else None
        except (OSError, xmlrpc.client.Error):
            return None

    def load_session(self, **fields):
        from vrm_msgs.srv import LoadSession
        return self.rospy.ServiceProxy("/station/load_session", LoadSession)(**fields)

    def status(self):
        with self.lock:
            return self.statuses[-1][1] if self.statuses else None

    def status_since(self, start, state):
        """The first station_status with `state` received after `start` (monotonic), as (time, message)."""
        with self.lock:
            for entry in self.statuses:
                if entry[0] >= start and entry[1].state == state:
                    return entry
        return None

    def scene(self):
        with self.lock:
            return self.scenes[-1][1] if self.scenes else None

    def scene_since(self, start, name):
        with self.lock:
            for entry in self.scenes:
                if entry[0] >= start and entry[1].name == name:
                    return entry
        return None

    def first_frame_after(self, start):
        with self.lock:
            return next((t for t in self.frames if t >= start), None)

    def frames_after(self, start):
        with self.lock:
            return sum(1 for t in self.frames if t >= start)

    def send(self, command, argument=""):
        """A console's command: stamped ahead of the newest frame as the console does (wall clock = input time)."""
        message = self.ScenarioCommand()
        message.header.stamp = self.rospy.Time.now() + self.rospy.Duration(0.5)
        message.command = command
        message.argument = argument
        self.command.publish(message)

    def stop(self):
        for handle in self.subscribers:
            handle.unregister()
        # The station first (SIGINT: it closes the recorder's bag and stops its graph), then the master.
        for process in reversed(self.processes):
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGINT)
                try:
                    process.wait(timeout=40)
                except subprocess.TimeoutExpired:
                    os.killpg(process.pid, signal.SIGKILL)
                    process.wait()
        for handle in self.logs:
            handle.close()


def load(station, scene, seed, record=True, user="anna"):
    """load_session; returns (request time, response)."""
    start = time.monotonic()
    response = station.load_session(mode="session", user=user, scene=scene, difficulty="", seed=seed,
                            record=record, script="", bag="")
    return start, response


def wait_ready(station, start, timeout):
    ready = wait_for(lambda: station.status_since(start, station.StationStatus.READY), timeout)
    if not ready:
        failed = station.status_since(start, station.StationStatus.FAILED)
        return None, failed[1].message if failed else (station.status().message if station.status() else "")
    return ready, ""


def bag_session_infos(path):
    import rosbag
    with rosbag.Bag(path) as bag:
        return [(message.scene, message.seed) for _, message, _ in bag.read_messages(topics=["/session_info"])]


def run_test(station, out):
    # --- session 1: scene A, started by the trainee
    start, response = load(station, SCENE_A, 11)
    check("load_session %s accepted" % SCENE_A, response.accepted, response.message)
    bag_a = response.bag
    ready, why = wait_ready(station, start, 180)
    if not check("%s READY (graph launched) after %.1f s" % (SCENE_A, (ready[0] - start) if ready else -1),
                 ready is not None, why):
        return
    manager = station.pid("/vrm_manager")
    check("the nodelet manager /vrm_manager runs (pid %s)" % manager, manager is not None)
    loads_a = station.scene().load if station.scene() else None
    station.send(station.ScenarioCommand.START)
    check("session 1 RUNNING after the console's START",
          wait_for(lambda: station.status_since(start, station.StationStatus.RUNNING), 30) is not None)

    # --- session 2: scene B while session 1 runs: a LOAD into the same graph
    start, response = load(station, SCENE_B, 22)
    check("load_session %s accepted" % SCENE_B, response.accepted, response.message)
    bag_b, result_b = response.bag, response.result_file
    ready, why = wait_ready(station, start, 120)
    if not check("%s READY (LOAD) after %.1f s" % (SCENE_B, (ready[0] - start) if ready else -1), ready is not None,
                 why):
        return
    announced = station.scene()
    check("running_scene announces %s with a higher load count (%s -> %s)" % (SCENE_B, loads_a,
                                                                              announced.load if announced else None),
          announced is not None and announced.name == SCENE_B and loads_a is not None and announced.load > loads_a)
    check("the same nodelet manager process runs both sessions (pid %s, then %s)" % (manager,
                                                                                      station.pid("/vrm_manager")),
          manager is not None and station.pid("/vrm_manager") == manager)
    check("session 1's bag is closed when session 2 starts (%s)" % os.path.basename(bag_a),
          os.path.isfile(bag_a) and not os.path.exists(bag_a + ".active"))

    # Session 2 runs and is stopped at the console: its result file names its bag and trainee.
    station.send(station.ScenarioCommand.START)
    check("session 2 RUNNING after the console's START",
          wait_for(lambda: station.status_since(start, station.StationStatus.RUNNING), 30) is not None)
    station.send(station.ScenarioCommand.STOP, "stopped by station_one_graph")
    ended = wait_for(lambda: station.status_since(start, station.StationStatus.ENDED), 60)
    check("session 2 ENDED after STOP (its recording closed)", ended is not None,
          station.status().message if station.status() else "")
    result = {}
    if wait_for(lambda: os.path.isfile(result_b), 10):
        result = session_result.read(result_b)  # the schema's Python reader: a malformed result fails here
    check("session 2's result file names its scene, bag and trainee (%s)" % os.path.basename(result_b),
          result.get("scene") == SCENE_B and result.get("bag") == bag_b and result.get("user") == "anna", result)
    check("session 2's bag is closed (%s)" % os.path.basename(bag_b),
          wait_for(lambda: os.path.isfile(bag_b) and not os.path.exists(bag_b + ".active"), 20))

    # --- a scene that does not exist: LOADed, refused by the scene owner, the previous scene runs on
    before = station.scene()
    start, response = load(station, MISSING, 33, record=False)
    check("load_session %s accepted by the station (the scene owner decides)" % MISSING, response.accepted,
          response.message)
    refused = wait_for(lambda: next((m for t, m in list(station.statuses) if t >= start and "refused" in m.message),
                                    None), 60)
    check("the refusal reaches station_status: '%s'" % (refused.message if refused else ""),
          refused is not None and MISSING in refused.message and refused.scene == SCENE_B and
          refused.state == station.StationStatus.ENDED)
    after_refusal = time.monotonic()
    check("the previous scene keeps running: frames go on after the refusal",
          wait_for(lambda: station.frames_after(after_refusal) >= 10, 10))
    check("running_scene still announces %s (load %s)" % (SCENE_B, before.load if before else None),
          station.scene() is not None and before is not None and station.scene().name == SCENE_B and
          station.scene().load == before.load)
    check("still the same nodelet manager process (pid %s)" % station.pid("/vrm_manager"),
          station.pid("/vrm_manager") == manager)

    # --- the bags: one per session, each with its own scene's session_info
    for bag, scene, seed in [(bag_a, SCENE_A, 11), (bag_b, SCENE_B, 22)]:
        infos = bag_session_infos(bag) if os.path.isfile(bag) else []
        check("%s holds session_info of %s (seed %d) only: %s" % (os.path.basename(bag), scene, seed, infos),
              len(infos) >= 1 and all(info == (scene, seed) for info in infos))
    bags = sorted(name for name in os.listdir(station.records) if name.endswith(".bag"))
    check("two bags in the records folder, one per session: %s" % bags, len(bags) == 2)
    if result.get("final_state_hash") and os.path.isfile(bag_b):
        replayed, why = replayed_hash(bag_b)
        check("session 2's bag replays offline to its result's final state (%s / %s)" % (
            result["final_state_hash"], replayed), replayed == result["final_state_hash"], why)

    run_station_crashes(station, manager)


def replayed_hash(bag):
    replay = subprocess.run(["rosrun", "vrm_sim", "session_replay", "--bag", bag], capture_output=True, text=True,
                            timeout=300)
    try:
        return json.loads(replay.stdout.splitlines()[0])["final_state_hash"], ""
    except (IndexError, ValueError, KeyError):
        return "", replay.stderr[-300:]


def status_with(station, start, text):
    with station.lock:
        return next((m for t, m in station.statuses if t >= start and text in m.message), None)


def run_station_crashes(station, manager):
    # --- a station crash mid-session; the session ends while no station runs
    start, response = load(station, SCENE_A, 44, user="ben")
    check("load_session %s accepted" % SCENE_A, response.accepted, response.message)
    bag, result_file = response.bag, response.result_file
    ready, why = wait_ready(station, start, 120)
    if not check("%s READY (LOAD)" % SCENE_A, ready is not None, why):
        return
    station.send(station.ScenarioCommand.START)
    check("session 3 RUNNING", wait_for(lambda: station.status_since(start, station.StationStatus.RUNNING), 30))
    state = station.state_file()
    check("the station's state file names its graph and session 3's bag",
          state is not None and state["graph"]["pid"] > 0 and state["session"]["bag"] == bag, state)
    station.crash_station()
    crashed = time.monotonic()
    station.send(station.ScenarioCommand.STOP, "stopped while no station runs")
    check("session 3 ends while no station runs",
          wait_for(lambda: next((m for t, m in list(station.scenario) if t >= crashed and m.scenario == SCENE_A and
                                 m.state not in (m.RUNNING, m.PAUSED)), None), 30) is not None)
    check("no result file while no station runs", not os.path.exists(result_file))
    restarted = time.monotonic()
    station.restart_station("station.2.log")
    took_over = wait_for(lambda: status_with(station, restarted, "took over"), 30)
    check("the station started again takes the session over: '%s'" % (took_over.message if took_over else ""),
          took_over is not None)
    ended = wait_for(lambda: station.status_since(restarted, station.StationStatus.ENDED), 60)
    check("session 3 ENDED after the take-over", ended is not None, station.status().message if station.status() else "")
    result = session_result.read(result_file) if wait_for(lambda: os.path.isfile(result_file), 10) else {}
    check("session 3's result file, written by the new station, names its scene, bag and trainee",
          result.get("scene") == SCENE_A and result.get("bag") == bag and result.get("user") == "ben", result)
    check("session 3's bag is closed", wait_for(lambda: os.path.isfile(bag) and not os.path.exists(bag + ".active"), 20))
    check("the same nodelet manager process still runs the graph (pid %s)" % station.pid("/vrm_manager"),
          station.pid("/vrm_manager") == manager)
    if result.get("final_state_hash") and os.path.isfile(bag):
        replayed, why = replayed_hash(bag)
        check("session 3's bag replays offline to its result's final state (%s / %s)" % (
            result["final_state_hash"], replayed), replayed == result["final_state_hash"], why)

    # --- a station crash, and its graph ends too before a station runs again: the result comes from the bag
    start, response = load(station, SCENE_B, 55, user="cleo")
    bag, result_file = response.bag, response.result_file
    ready, why = wait_ready(station, start, 120)
    if not check("%s READY (LOAD)" % SCENE_B, ready is not None, why):
        return
    station.send(station.ScenarioCommand.START)
    running = wait_for(lambda: station.status_since(start, station.StationStatus.RUNNING), 30)
    check("session 4 RUNNING", running is not None)
    check("session 4 simulates frames", wait_for(lambda: station.frames_after(running[0]) >= 50, 20) if running else 0)
    state = station.state_file()
    station.crash_station()
    graph = state["graph"]["pid"] if state else 0
    if graph:
        os.killpg(graph, signal.SIGINT)  # the graph's roslaunch ends its nodes; its recorder is left orphaned
        check("session 4's graph ends", wait_for(lambda: not os.path.exists("/proc/%d" % graph), 60))
    restarted = time.monotonic()
    station.restart_station("station.3.log")
    ended = wait_for(lambda: station.status_since(restarted, station.StationStatus.ENDED), 120)
    check("the next station replays session 4's bag into its result: '%s'" % (
        ended[1].message if ended else (station.status().message if station.status() else "")), ended is not None)
    result = session_result.read(result_file) if os.path.isfile(result_file) else {}
    check("session 4's result is interrupted, names its scene, bag and trainee",
          result.get("scene") == SCENE_B and result.get("bag") == bag and result.get("user") == "cleo" and
          result.get("interrupted") is True and result.get("state") == "interrupted", result)
    check("session 4's bag was closed by its orphaned recorder's shutdown", os.path.isfile(bag) and
          not os.path.exists(bag + ".active"))
    check("no state file is left once nothing runs", wait_for(lambda: station.state_file() is None, 10))


def run_measure(station, runs, record):
    rows = []
    scenes = [SCENE_A, SCENE_B]
    for run in range(runs + 1):
        scene = scenes[run % 2]
        start, response = load(station, scene, 100 + run, record=record)
        if not response.accepted:
            check("load_session %s" % scene, False, response.message)
            return
        announced = wait_for(lambda: station.scene_since(start, scene), 180)
        ready, why = wait_ready(station, start, 180)
        if not check("%s ready" % scene, ready is not None and announced is not None, why):
            return
        frame = wait_for(lambda: station.first_frame_after(announced[0]), 10)
        rows.append((run, scene, frame - start if frame else float("nan"), ready[0] - start))
    print("run  scene              first frame [s]  READY [s]")
    for run, scene, frame, ready in rows:
        print("%3d  %-17s  %15.2f  %9.2f%s" % (run, scene, frame, ready, "   (graph start)" if run == 0 else ""))
    later = rows[1:]
    if later:
        print("mean of runs 1..%d: first frame %.2f s, READY %.2f s" % (
            len(later), sum(r[2] for r in later) / len(later), sum(r[3] for r in later) / len(later)))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("mode", choices=["test", "measure"])
    parser.add_argument("--port", type=int, default=12100 + os.getpid() % 200)
    parser.add_argument("--out", default="")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--station", default="", help="session_station binary (default: rosrun eyesi_gui)")
    parser.add_argument("--record", default="true", choices=["true", "false"])
    args = parser.parse_args()
    out = args.out or tempfile.mkdtemp(prefix="station_one_graph.")
    os.makedirs(out, exist_ok=True)
    print("station_one_graph: %s, output in %s, master port %d" % (args.mode, out, args.port), flush=True)
    station = None
    try:
        station = Station(out, args.port, args.station)
        if args.mode == "test":
            run_test(station, out)
        else:
            run_measure(station, args.runs, args.record == "true")
    except Exception as error:  # a broken set-up is a failure with its reason, not a traceback
        check("set-up", False, repr(error))
    finally:
        if station:
            station.stop()
    leftovers = subprocess.run(["pgrep", "-f", "__log:=" + os.path.join(out, "ros_log")], capture_output=True,
                               text=True).stdout.split()
    check("no process of the station's graphs is left", not leftovers, leftovers)
    if FAILURES:
        print("station_one_graph: %d FAILED (output kept in %s)" % (len(FAILURES), out))
        return 1
    print("station_one_graph: PASS")
    if not args.out:
        shutil.rmtree(out, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
