#!/usr/bin/env python3
"""What the simulation did in a session, from the outputs bag run.sh records (vrm_msgs/SimulationState per frame and
vrm_msgs/StageTiming): frames, per tissue the meshes published, grasped nodes, strain, lift and peel outcome, retina
contacts, and the frame cost; then the training scenario's end state and score table (vrm_msgs/ScenarioStatus). With
--check, exit 1 unless frames were produced, where the scene has tissue the tissue was published deformed and grasped,
and the scenario finished (the scripted expert completes its task).
Usage: session_summary.py [--check] OUTPUTS.bag"""
import sys

import rosbag

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


def main(arguments):
    check = "--check" in arguments
    paths = [a for a in arguments if a != "--check"]
    if len(paths) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        bag = rosbag.Bag(paths[0])
    except Exception as error:  # rosbag raises several types for missing/corrupt files
        print(f"session_summary: cannot open {paths[0]}: {error}", file=sys.stderr)
        return 1
    frames, wall_ms, last, tissues, late = 0, [], None, {}, 0
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
    if check and not ok:
        print("session_summary: --check failed: the tissue was not published deformed and grasped", file=sys.stderr)
        return 1
    if status is None:
        print("scenario: no scenario_status recorded")
        return 1 if check else 0
    print_score(status)
    if check and STATES.get(status.state) != "finished":
        print(f"session_summary: --check failed: the scenario ended {STATES.get(status.state, status.state)}, "
              "not finished", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
