#!/usr/bin/env python3
"""What the simulation did in a session, from the outputs bag run.sh records (vrm_msgs/SimulationState per frame and
vrm_msgs/StageTiming): frames, per tissue the meshes published, grasped nodes, strain, lift and peel outcome, retina
contacts, and the frame cost; the view's frame rate and latency (render_timing, display_timing), with a warning when
this machine is too slow for real time; then the training scenario's end state and score table
(vrm_msgs/ScenarioStatus). With --check, exit 1 unless frames were produced, where the scene has tissue the tissue was
published deformed and grasped, and the scenario finished (the scripted expert completes its task); a slow machine
only warns (CI machines are noisy).
With --result RESULT.json, the session's result file (read through scripts/session_result.py, the schema of
doc/session_result.md) is summarised too, and --check also fails when it is malformed or disagrees with the last
recorded status (state, total).
From the session's input bag (--inputs SESSION.bag, default session.bag next to OUTPUTS.bag) the tracked fraction per
instrument slot: the share of its instrument_state messages from the session's START on that were valid (with
tracking:=true what the optical tracking saw; issue 33: the light pipe's markers are at times occluded by the other
shaft). --check also fails when a slot the tracking saw at all was valid < 90 % of the session (a slot never valid is
reported, not failed: the bag does not say whether the script used it).
Usage: session_summary.py [--check] [--result RESULT.json] [--inputs SESSION.bag] OUTPUTS.bag"""
import math
import os
import sys

import rosbag

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import session_result  # noqa: E402  (scripts/session_result.py: the result's one Python reader)

OUTCOMES = {0: "untouched", 1: "grasped", 2: "lifted (clean peel so far)", 3: "torn"}
STATES = {0: "idle", 1: "running", 2: "paused", 3: "finished", 4: "failed"}


def print_score(status):
    """The score table a trainee sees at the end of a session."""
    level = f" ({status.difficulty})" if status.difficulty else ""
    print(f"scenario '{status.scenario}'{level}: {STATES.get(status.state, status.state)} after {status.elapsed:.1f} s"
          f" - {status.message}")
    print(f"  {'item':<22} {'value':>12} {'unit':<5} {'weight':>6}")
    for item in status.score.items:
        weight = f"{item.weight:g}" if item.weight > 0 else "-"
        print(f"  {item.name:<22} {item.value:>12.6g} {item.unit:<5} {weight:>6}")
    print(f"  {'total':<22} {status.score.total:>12.1f} / 100")


def percentile(values, fraction):
    if not values:
        return 0.0
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(fraction * (len(ordered) - 1) + 0.5))]


# Real time as EyeSi defined it (thesis §7.4.2, eq. 7.1; §1.3): 47-57 ms from input to image at >= 25 Hz; below 20 Hz
# the view no longer counts as real time. The latency monitor warns at the same limits (launch/include/latency.launch).
REAL_TIME_MIN_FPS = 20.0
REAL_TIME_MAX_P50_MS = 57.0


def nearest_rank(values, fraction):
    """vrm_sim::world::nearestRank (latency.h): the percentiles bench_latency and the latency monitor report."""
    if not values:
        return 0.0
    ordered = sorted(values)
    index = max(1, math.ceil(fraction * len(ordered))) - 1
    return ordered[min(index, len(ordered) - 1)]


def stage(timing, name):
    return next((s for s in timing.stages if s.stage == name), None)


def view_summary(render, display):
    """The view's line (and a warning on a slow machine) from render_timing and display_timing: frames per second
    shown (the display twin pairs the eyes), end to end = input stamp -> image published (latency.h's end_to_end),
    input stamp -> both eyes shown, and the stereo frame's render time."""
    end_to_end, render_ms = [], []
    for timing in render:
        published, rendered = stage(timing, "image_published"), stage(timing, "render")
        if published is not None:
            end_to_end.append(1e3 * (published.end - timing.header.stamp).to_sec())
        if rendered is not None:
            render_ms.append(1e3 * (rendered.end - rendered.start).to_sec())
    shown_at, shown_ms = [], []
    for timing in display:
        shown = stage(timing, "displayed")
        if shown is not None:
            shown_at.append(shown.end.to_sec())
            shown_ms.append(1e3 * (shown.end - timing.header.stamp).to_sec())
    if not render and not display:
        print("view: no render_timing or display_timing recorded (render:=false?)")
        return
    if shown_at:
        frames, what = len(shown_at), "stereo frames shown"
        seconds = max(shown_at) - min(shown_at)
    else:  # display:=false: the frames rendered for whoever watched (or for the snapshots)
        ends = [stage(t, "image_published").end.to_sec() for t in render if stage(t, "image_published") is not None]
        frames, what = len(ends), "frames rendered, no display twin (display:=false)"
        seconds = max(ends) - min(ends) if ends else 0.0
    fps = (frames - 1) / seconds if frames > 1 and seconds > 0 else 0.0
    p50 = nearest_rank(end_to_end, 0.50)
    line = (f"view: {fps:.1f} fps ({frames} {what} in {seconds:.1f} s); end to end (input stamp -> image published) "
            f"p50 {p50:.0f} ms, p99 {nearest_rank(end_to_end, 0.99):.0f} ms")
    if shown_ms:
        line += f"; shown p50 {nearest_rank(shown_ms, 0.50):.0f} / p99 {nearest_rank(shown_ms, 0.99):.0f} ms"
    print(line + f"; render p50 {nearest_rank(render_ms, 0.50):.0f} ms")
    slow = []
    if shown_at and fps < REAL_TIME_MIN_FPS:  # without the display twin only snapshots and watchers cause frames
        slow.append(f"{fps:.1f} fps < {REAL_TIME_MIN_FPS:.0f} fps")
    if p50 > REAL_TIME_MAX_P50_MS:
        slow.append(f"end-to-end p50 {p50:.0f} ms > {REAL_TIME_MAX_P50_MS:.0f} ms")
    if slow:
        print(f"view: WARNING: this machine is too slow for real time ({', '.join(slow)}): EyeSi showed an input "
              f"47-57 ms later at >= 25 Hz, and below {REAL_TIME_MIN_FPS:.0f} Hz a view no longer counts as real "
              "time (thesis §7.4.2, §1.3).")


def summarise_result(path, status):
    """The result file's line; False if it is malformed or disagrees with the last recorded status."""
    try:
        result = session_result.read(path)
    except session_result.ResultError as error:
        print(f"result: {error}", file=sys.stderr)
        return False
    total = "-" if session_result.is_unknown(result["total"]) else f"{result['total']:.1f} / 100"
    print(f"result: {path}: {result['state']}, total {total}, final state {result['final_state_hash']} after "
          f"{result['frames']} frames")
    if status is None:
        return True
    # The file carries 15 significant digits; a total without samples is null (NaN) in the file.
    same_total = (session_result.is_unknown(result["total"]) and math.isnan(status.score.total)) or math.isclose(
        result["total"], status.score.total, rel_tol=1e-13, abs_tol=1e-13)
    agree = result["state"] == STATES.get(status.state) and same_total
    if not agree:
        print(f"result: {path} says {result['state']} / {result['total']}, the last status "
              f"{STATES.get(status.state, status.state)} / {status.score.total}", file=sys.stderr)
    return agree


MIN_TRACKED_FRACTION = 0.9


def tracked_fractions(path):
    """{slot: [valid, total]} over the instrument_state messages stamped at or after the session's first START (all
    of them without a recorded START); None if the bag cannot be read."""
    try:
        bag = rosbag.Bag(path)
    except Exception as error:  # rosbag raises several types for missing/corrupt files
        print(f"tracking: cannot open {path}: {error}")
        return None
    counts, start = {}, None
    with bag:
        for _, command, _ in bag.read_messages(topics=["/scenario_command"]):
            if command.command == command.START:
                start = command.header.stamp.to_sec()
                break
        for _, state, _ in bag.read_messages(topics=["/instrument_state"]):
            if start is not None and state.header.stamp.to_sec() < start:
                continue
            entry = counts.setdefault(state.instrument_id, [0, 0])
            entry[0] += 1 if state.valid else 0
            entry[1] += 1
    return counts


def tracking_summary(path):
    """Prints the tracked fraction per slot; returns the slots seen at all but tracked < MIN_TRACKED_FRACTION."""
    counts = tracked_fractions(path)
    if counts is None:
        return []
    if not counts:
        print(f"tracking: no instrument_state after the START in {path}")
        return []
    low, parts = [], []
    for slot, (valid, total) in sorted(counts.items()):
        fraction = valid / total
        parts.append(f"{slot} {100 * fraction:.1f} % ({valid} of {total})" if valid else f"{slot} never tracked")
        if valid and fraction < MIN_TRACKED_FRACTION:
            low.append(f"{slot} {100 * fraction:.1f} %")
    print("tracking: valid instrument states since the START: " + ", ".join(parts))
    return low


def main(arguments):
    check = "--check" in arguments
    arguments = [a for a in arguments if a != "--check"]
    result_path = None
    if "--result" in arguments:
        at = arguments.index("--result")
        if at + 1 >= len(arguments):
            print(__doc__, file=sys.stderr)
            return 2
        result_path = arguments[at + 1]
        del arguments[at:at + 2]
    inputs = None
    if "--inputs" in arguments:
        at = arguments.index("--inputs")
        if at + 1 >= len(arguments):
            print(__doc__, file=sys.stderr)
            return 2
        inputs = arguments[at + 1]
        del arguments[at:at + 2]
    paths = arguments
    if len(paths) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    if inputs is None:
        beside = os.path.join(os.path.dirname(os.path.abspath(paths[0])), "session.bag")
        inputs = beside if os.path.exists(beside) else None
    try:
        bag = rosbag.Bag(paths[0])
    except Exception as error:  # rosbag raises several types for missing/corrupt files
        print(f"session_summary: cannot open {paths[0]}: {error}", file=sys.stderr)
        return 1
    frames, wall_ms, last, tissues, late = 0, [], None, {}, 0
    render, display = [], []
    with bag:
        for _, state, _ in bag.read_messages(topics=["/simulation_state"]):
            frames += 1
            wall_ms.append(1e3 * state.wall_time)
            last = state
            late = state.late_inputs
            for tissue in state.tissues:
                entry = tissues.setdefault(tissue.tissue_id, {"meshes": 0, "version": None, "grasped": 0,
                                                              "strain": 0.0, "lift": 0.0, "first_grasp": None})
                if entry["version"] is not None and tissue.version != entry["version"]:
                    entry["meshes"] += 1
                entry["version"] = tissue.version
                entry["grasped"] = max(entry["grasped"], tissue.grasped_nodes)
                entry["strain"] = max(entry["strain"], tissue.max_strain)
                entry["lift"] = max(entry["lift"], tissue.max_lift)
                if tissue.grasped_nodes and entry["first_grasp"] is None:
                    entry["first_grasp"] = state.header.stamp.to_sec()
                entry["last"] = tissue
        start = bag.get_start_time() if frames else 0.0
        for topic, timing, _ in bag.read_messages(topics=["/render_timing", "/display_timing"]):
            (render if topic == "/render_timing" else display).append(timing)
        status = None
        for _, message, _ in bag.read_messages(topics=["/scenario_status"]):
            status = message
    if not frames:
        print("simulation: no frames (scenario_manager published no simulation_state)")
        return 1 if check else 0
    print(f"simulation: {frames} frames, frame cost {sum(wall_ms) / len(wall_ms):.2f} ms mean, "
          f"{percentile(wall_ms, 0.95):.2f} ms p95, {max(wall_ms):.2f} ms max; {late} late inputs")
    ok = True
    for name, entry in sorted(tissues.items()):
        final = entry["last"]
        grasp = f"first grasp at {entry['first_grasp'] - start:.1f} s" if entry["first_grasp"] else "never grasped"
        print(f"  tissue '{name}': {entry['meshes']} tissue frames published, grasped nodes max {entry['grasped']} "
              f"({grasp}), max strain {entry['strain']:.2f}, max lift {1e3 * entry['lift']:.2f} mm, "
              f"outcome {OUTCOMES.get(final.outcome, final.outcome)} (torn springs {final.torn_springs}, "
              f"adhesions released {final.released_adhesions}, topology v{final.topology_version})")
        ok = ok and entry["meshes"] > 0 and entry["grasped"] > 0
    print(f"  retina: {last.retina_contacts} contacts, max injury {last.max_injury:.2f}")
    view_summary(render, display)
    low_tracking = tracking_summary(inputs) if inputs else []
    if inputs is None:
        print("tracking: no session bag (--inputs, or session.bag next to the outputs bag)")
    if check and not ok:
        print("session_summary: --check failed: the tissue was not published deformed and grasped", file=sys.stderr)
        return 1
    if check and low_tracking:
        print(f"session_summary: --check failed: tracked < {100 * MIN_TRACKED_FRACTION:.0f} % of the session: "
              + ", ".join(low_tracking), file=sys.stderr)
        return 1
    if status is None:
        print("scenario: no scenario_status recorded")
        return 1 if check else 0
    print_score(status)
    if result_path is not None and not summarise_result(result_path, status) and check:
        print("session_summary: --check failed: the result file is malformed or disagrees with the session",
              file=sys.stderr)
        return 1
    if check and STATES.get(status.state) != "finished":
        print(f"session_summary: --check failed: the scenario ended {STATES.get(status.state, status.state)}, "
              "not finished", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
