#!/usr/bin/env python3
"""One scene owner (issue 32): one running graph switches scenes through LOAD, and every node follows.

launch/simulator.launch (tracking:=true, render:=true, auto_start:=false) starts on navigation; then, in the same
graph, LOAD membrane_peeling -> a test scene whose eye centre (1 mm off) and trocar azimuths (140 / 40 deg) no shipped
scene has (test/graph/scenes/offset_eye.yaml) -> vitrectomy -> a scene that does not exist. After each LOAD:
  - scenario_manager announces the scene on the latched running_scene (name, file, level, load count);
  - scene_manager publishes the scene's surfaces (meshes/<object>) and markers (scene_markers: one DELETEALL, then
    one marker per object and instrument), and the previous scene's objects are gone;
  - the trocar frames on tf are the scene's (trocar_left / trocar_right in the eye frame);
  - the tracker's /diagnostics report the scene, its eye centre and trocars;
  - a stereo frame rendered after the switch is saved (PPM) and differs from the previous scene's;
  - START, a few seconds of the scripted surgeon, STOP: the session result names the scene;
and the nodelet manager's process id never changes. The nonexistent scene is refused: no announcement, the graph
stays on vitrectomy. Prints PASS/FAIL lines and the time from LOAD to the announcement and to the first frame shown
of the new scene; exits 1 on any failure.

Usage: scene_switch.py [--out DIR]   (workspace sourced: scripts/common.sh)
"""
import argparse
import math
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
import xmlrpc.client

ROOT = os.path.abspath(os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..", "..", ".."))
TEST_SCENE = os.path.join(ROOT, "src", "vrm_sim", "test", "graph", "scenes", "offset_eye.yaml")
SCENES = os.path.join(ROOT, "src", "vrm_sim", "config", "scenes")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import session_result  # noqa: E402  (scripts/session_result.py: the session result's Python reader)

failures = []


def check(what, ok, detail=""):
    print("%s: %s%s" % ("PASS" if ok else "FAIL", what, "" if ok or detail == "" else " (%s)" % (detail,)), flush=True)
    if not ok:
        failures.append(what)
    return ok


def wait_for(condition, timeout, poll=0.05):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(poll)
    return condition()


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def scene_contents(path):
    """Object names, instrument count and trocars (name -> azimuth deg) as the scene file writes them."""
    import yaml
    with open(path) as stream:
        document = yaml.safe_load(stream)
    objects = [entry["name"] for entry in document.get("objects", [])]
    trocars = {entry["name"]: float(entry["azimuth_deg"]) for entry in document.get("eye", {}).get("trocars", [])}
    if not trocars:  # the loader's defaults (scene_description.h)
        trocars = {"left": 150.0, "right": 30.0}
    centre = document.get("eye", {}).get("centre", [0.0, 0.0, 0.0])
    return objects, len(document.get("instruments", [])), trocars, [float(v) for v in centre]


class Graph:
    def __init__(self, out, launch_args):
        self.port = free_port()
        os.environ["ROS_MASTER_URI"] = "http://localhost:%d" % self.port
        os.environ.setdefault("ROS_HOSTNAME", "localhost")
        os.environ["ROS_LOG_DIR"] = os.path.join(out, "ros_log")
        self.log = open(os.path.join(out, "launch.log"), "w")
        command = ["timeout", "-k", "10", "400", "roslaunch", "-p", str(self.port),
                   os.path.join(ROOT, "launch", "simulator.launch")] + launch_args
        print("scene_switch: " + " ".join(command), flush=True)
        self.process = subprocess.Popen(command, stdout=self.log, stderr=subprocess.STDOUT, start_new_session=True)
        self.master = xmlrpc.client.ServerProxy(os.environ["ROS_MASTER_URI"])
        if not wait_for(self._master_up, 30, 0.2):
            raise RuntimeError("no ROS master on port %d" % self.port)
        import rospy
        rospy.init_node("scene_switch", anonymous=True, disable_signals=True)

    def _master_up(self):
        try:
            return self.master.getSystemState("/scene_switch")[0] == 1
        except OSError:
            return False

    def pid(self, node):
        try:
            code, _, uri = self.master.lookupNode("/scene_switch", node)
            if code != 1:
                return None
            code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/scene_switch")
            return pid if code == 1 else None
        except (OSError, xmlrpc.client.Error):
            return None

    def publishers(self, topic):
        try:
            code, _, state = self.master.getSystemState("/scene_switch")
        except OSError:
            return []
        for name, nodes in state[0]:
            if name == topic:
                return nodes
        return []

    def stop(self):
        import signal
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGINT)
            try:
                self.process.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()


class Watch:
    """The graph's outputs this test looks at, kept as they arrive."""

    def __init__(self):
        import rospy
        from diagnostic_msgs.msg import DiagnosticArray
        from sensor_msgs.msg import Image
        from visualization_msgs.msg import MarkerArray
        from vrm_msgs.msg import RunningScene, ScenarioStatus, SessionResult
        self.lock = threading.Lock()
        self.scenes = []  # (wall, RunningScene)
        self.markers = None
        self.status = None
        self.statuses = []  # (wall, scenario, state)
        self.results = []
        self.image = None  # (wall, Image)
        self.tracker = {}  # the tracker's last diagnostics: key -> value
        self.subscribers = [
            rospy.Subscriber("/running_scene", RunningScene, self._on_scene, queue_size=10),
            rospy.Subscriber("/scene_markers", MarkerArray, self._on_markers, queue_size=2),
            rospy.Subscriber("/scenario_status", ScenarioStatus, self._on_status, queue_size=50),
            rospy.Subscriber("/session_result", SessionResult, self._on_result, queue_size=5),
            rospy.Subscriber("/stereo/left/image_raw", Image, self._on_image, queue_size=1, buff_size=1 << 24),
            rospy.Subscriber("/diagnostics", DiagnosticArray, self._on_diagnostics, queue_size=50),
        ]

    def _on_scene(self, message):
        with self.lock:
            self.scenes.append((time.monotonic(), message))

    def _on_markers(self, message):
        with self.lock:
            self.markers = message

    def _on_status(self, message):
        with self.lock:
            self.status = message
            self.statuses.append((time.monotonic(), message.scenario, message.state))

    def _on_result(self, message):
        with self.lock:
            self.results.append(message)

    def _on_image(self, message):
        with self.lock:
            self.image = (time.monotonic(), message)

    def _on_diagnostics(self, message):
        with self.lock:
            for status in message.status:
                if status.name.startswith("tracker") or "tracker" in status.name.split(":")[0]:
                    values = {kv.key: kv.value for kv in status.values}
                    if "scene" in values:
                        self.tracker = values

    def latest_scene(self):
        with self.lock:
            return self.scenes[-1][1] if self.scenes else None


def save_ppm(image, path):
    """RGB8 / BGR8 / RGBA8 stereo frame as a binary PPM (no image library needed)."""
    channels = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4}.get(image.encoding)
    if channels is None:
        return False
    data = bytes(image.data)
    pixels = bytearray()
    for row in range(image.height):
        line = data[row * image.step:row * image.step + image.width * channels]
        for column in range(image.width):
            pixel = line[column * channels:column * channels + 3]
            pixels += pixel if image.encoding.startswith("rgb") else pixel[::-1]
    with open(path, "wb") as stream:
        stream.write(b"P6\n%d %d\n255\n" % (image.width, image.height))
        stream.write(pixels)
    return True


def mean_difference(a, b):
    if a is None or b is None or len(a.data) != len(b.data):
        return float("inf")
    first, second = bytes(a.data), bytes(b.data)
    samples = range(0, len(first), 97)
    return sum(abs(first[i] - second[i]) for i in samples) / len(samples)


def switch(graph, watch, command_pub, name, path, load, manager_pid, previous_objects, previous_image, out):
    """LOAD `name` (a shipped scene or a path), check every follower; returns (objects, image)."""
    from vrm_msgs.msg import ScenarioCommand
    import rospy
    objects, instrument_count, trocars, centre = scene_contents(path)
    scene_name = os.path.splitext(os.path.basename(path))[0]
    sent = time.monotonic()
    command = ScenarioCommand()
    command.header.stamp = rospy.Time.now()
    command.command = ScenarioCommand.LOAD
    command.scenario = name
    command.seed = 7
    command_pub.publish(command)
    announced = wait_for(lambda: (lambda s: s if s and s.load == load else None)(watch.latest_scene()), 20)
    announced_at = time.monotonic()
    check("LOAD %s: running_scene announces it (load %d)" % (scene_name, load),
          announced is not None and announced.name == scene_name and os.path.realpath(announced.file) ==
          os.path.realpath(path) and announced.content_hash != 0 and announced.seed == 7,
          announced and (announced.name, announced.file, announced.load))
    # The first frame of the new scene: an image of a frame after the LOAD's that differs from the old scene's.
    load_stamp = announced.header.stamp if announced else None

    def new_scene_shown():
        with watch.lock:
            image = watch.image
        if image is None or load_stamp is None or image[1].header.stamp <= load_stamp:
            return None
        return image if mean_difference(image[1], previous_image) > 2.0 else None
    shown = wait_for(new_scene_shown, 20, poll=0.01)
    print("scene_switch: %s: LOAD -> announced %.0f ms, -> its first frame received %.0f ms" % (
        scene_name, 1000 * (announced_at - sent), 1000 * ((shown[0] if shown else float("nan")) - sent)), flush=True)

    def markers_match():
        with watch.lock:
            markers = watch.markers
        return markers is not None and len(markers.markers) == 1 + len(objects) + instrument_count and \
            markers.markers[0].action == 3
    check("%s: scene_markers are its %d objects and %d instruments (after a DELETEALL)" % (
        scene_name, len(objects), instrument_count), wait_for(markers_match, 10),
        watch.markers and len(watch.markers.markers))
    missing = [o for o in objects if not wait_for(lambda: graph.publishers("/meshes/" + o), 5)]
    check("%s: a latched meshes/<object> for each of its objects" % scene_name, not missing, missing)
    gone = [o for o in previous_objects if o not in objects and graph.publishers("/meshes/" + o)]
    check("%s: the previous scene's other objects have no mesh topic any more" % scene_name, not gone, gone)

    # tf: the trocars of this scene, in the eye frame.
    import tf2_ros
    buffer = tf2_ros.Buffer()
    listener = tf2_ros.TransformListener(buffer)  # noqa: F841 (keeps the subscription)

    def trocar_azimuths():
        result = {}
        for trocar in trocars:
            try:
                t = buffer.lookup_transform("eye", "trocar_" + trocar, rospy.Time(0)).transform.translation
            except (tf2_ros.LookupException, tf2_ros.ExtrapolationException, tf2_ros.ConnectivityException):
                return None
            result[trocar] = math.degrees(math.atan2(t.y, t.x)) % 360.0
        return result if all(abs(result[k] - trocars[k]) < 0.5 for k in trocars) else None
    azimuths = wait_for(trocar_azimuths, 10)
    check("%s: tf has its trocars at azimuths %s deg" % (scene_name, trocars), azimuths is not None)

    def tracker_follows():
        with watch.lock:
            values = dict(watch.tracker)
        return values if values.get("scene") == scene_name else None
    tracker = wait_for(tracker_follows, 10)
    check("%s: the tracker's diagnostics name it" % scene_name, tracker is not None, watch.tracker.get("scene"))
    if tracker is not None:
        reported = [float(v) for v in tracker.get("eye_centre", "nan nan nan").split()]
        check("%s: the tracker's eye centre is the scene's %s m" % (scene_name, centre),
              len(reported) == 3 and all(abs(a - b) < 1e-6 for a, b in zip(reported, centre)), reported)
        for trocar, azimuth in trocars.items():
            value = tracker.get("trocar_%s_azimuth_deg" % trocar)
            check("%s: the tracker's trocar %s at azimuth %.0f deg" % (scene_name, trocar, azimuth),
                  value is not None and abs(float(value) - azimuth) < 0.5, value)

    image = shown[1] if shown else None
    if image is not None:
        save_ppm(image, os.path.join(out, "%d_%s.ppm" % (load, scene_name)))
    check("%s: a stereo frame after the LOAD differs from the previous scene's (saved %d_%s.ppm)" % (
        scene_name, load, scene_name), image is not None,
        "mean |difference| %.2f" % mean_difference(watch.image[1] if watch.image else None, previous_image))

    # A short session of this scene: START, the scripted surgeon for a few seconds, STOP.
    with watch.lock:
        results_before = len(watch.results)
    command = ScenarioCommand()
    command.header.stamp = rospy.Time.now()
    command.command = ScenarioCommand.START
    command_pub.publish(command)
    running = wait_for(lambda: watch.status is not None and watch.status.scenario == scene_name and
                       watch.status.state == 1 and watch.status.elapsed > 2.0, 20)
    check("%s: the scenario runs after START" % scene_name, bool(running),
          watch.status and (watch.status.scenario, watch.status.state, watch.status.elapsed))
    command = ScenarioCommand()
    command.header.stamp = rospy.Time.now()
    command.command = ScenarioCommand.STOP
    command.argument = "scene_switch test"
    command_pub.publish(command)
    result = wait_for(lambda: watch.results[-1] if len(watch.results) > results_before else None, 20)
    try:
        scene_in_result = session_result.from_json(result.json, "session_result")["scene"] if result else None
    except session_result.ResultError as error:  # the schema's Python reader (scripts/session_result.py)
        scene_in_result = "%s: %s" % (error, result.json[:600])
    check("%s: the session result names it" % scene_name, scene_in_result == scene_name, scene_in_result)
    check("%s: the nodelet manager is the same process" % scene_name, graph.pid("/vrm_manager") == manager_pid,
          graph.pid("/vrm_manager"))
    return objects, image


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="")
    args = parser.parse_args()
    out = args.out or tempfile.mkdtemp(prefix="vrm_scene_switch.")
    os.makedirs(out, exist_ok=True)
    print("scene_switch: output in " + out, flush=True)
    graph = Graph(out, ["scene:=navigation", "tracking:=true", "render:=true", "auto_start:=false",
                        "latency_monitor:=false"])
    try:
        import rospy
        from vrm_msgs.msg import ScenarioCommand
        watch = Watch()
        command_pub = rospy.Publisher("/scenario_command", ScenarioCommand, queue_size=10)
        first = wait_for(watch.latest_scene, 90)
        check("start-up: running_scene announces navigation (load 0)",
              first is not None and first.name == "navigation" and first.load == 0, first and first.name)
        manager_pid = wait_for(lambda: graph.pid("/vrm_manager"), 30)
        wait_for(lambda: command_pub.get_num_connections() > 0, 20)
        image = wait_for(lambda: watch.image, 60)
        image = image[1] if image else None
        objects = scene_contents(os.path.join(SCENES, "navigation.yaml"))[0]
        for load, (name, path) in enumerate([
                ("membrane_peeling", os.path.join(SCENES, "membrane_peeling.yaml")),
                (TEST_SCENE, TEST_SCENE),
                ("vitrectomy", os.path.join(SCENES, "vitrectomy.yaml"))], start=1):
            objects, image = switch(graph, watch, command_pub, name, path, load, manager_pid, objects, image, out)

        # A scene that does not exist: refused, nothing announced, every node stays on vitrectomy.
        command = ScenarioCommand()
        command.header.stamp = rospy.Time.now()
        command.command = ScenarioCommand.LOAD
        command.scenario = "no_such_scene"
        command_pub.publish(command)
        refused = wait_for(lambda: watch.status is not None and "refused" in watch.status.message, 10)
        check("LOAD no_such_scene is refused and says why", bool(refused), watch.status and watch.status.message)
        time.sleep(0)  # the announcement below would have come with the refusal's status
        latest = watch.latest_scene()
        check("after the refusal running_scene is still vitrectomy (load 3)",
              latest is not None and latest.name == "vitrectomy" and latest.load == 3, latest and latest.name)
        with watch.lock:
            tracker_scene = watch.tracker.get("scene")
        check("after the refusal the tracker is still on vitrectomy", tracker_scene == "vitrectomy", tracker_scene)
        check("the nodelet manager never restarted", graph.pid("/vrm_manager") == manager_pid)
    finally:
        graph.stop()
    print("scene_switch: %s" % ("PASS" if not failures else "FAILED (%s)" % ", ".join(failures)), flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
