#!/usr/bin/python3
"""The headline tables of BENCHMARKS.md's "tissue" section, printed as Markdown from one run's JSON (issue 19), so
the document is rebuilt from one run and not edited by hand. Times: median of the repetitions [min–max].
A verdict is "faster"/"slower" only when the whole spread of the ratio (our min / their max .. our max / their min)
is on one side of 1, "within noise" when it crosses 1.
Usage: tissue_tables.py [bench/results/tissue.json]"""
import json
import sys

rows = json.load(open(sys.argv[1] if len(sys.argv) > 1 else "bench/results/tissue.json"))["rows"]


def g(value, digits=3):
    return "–" if value is None else f"{value:.{digits}g}"


def spread(median, low, high, digits=3):
    return f"{g(median, digits)} [{g(low, digits)}–{g(high, digits)}]"


def verdict(r):
    if r.get("ratio_ours_to_peer") is None:
        return "no configuration of ours is as accurate"
    if r["ratio_max"] < 1:
        return "**faster**"
    if r["ratio_min"] > 1:
        return "slower"
    return "within noise"


def label(r):
    name = r["integrator"]
    if r.get("integrator_chosen"):
        name += f" ({r['integrator_chosen']})"
    return name


print("Reference checks\n")
print("| check | run | dt (s) | distance to the reference rms / max (m) |")
print("|---|---|---|---|")
for r in rows:
    if r["scene"].startswith("reference_check_"):
        if r["integrator"] == "newton_static":
            print(f"| {r['scene'][16:]} | Newton, {r['iterations']} iterations | – | residual {g(r['error_max'])} N, "
                  f"deepest node {g(r['max_strain'])} m |")
        else:
            print(f"| {r['scene'][16:]} | {r['integrator']} | {g(r['dt'])} | {g(r['error_rms'])} / {g(r['error_max'])} |")

for kind, title in (("matched_", "Matched accuracy: our fastest configuration with an error rms no worse than Bullet's"),
                    ("like_for_like_", "Like for like: XPBD 10 iterations vs btSoftBody 10 iterations, same dt")):
    print(f"\n{title} (ms of wall time per simulated ms)\n")
    print("| case | Bullet it. | Bullet dt | kLST | Bullet error rms (m) | Bullet ms/sim-ms | ours | our dt | "
          "our error rms (m) | our ms/sim-ms | ours/Bullet | verdict |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if not r["scene"].startswith(kind):
            continue
        case = r["scene"][len(kind):]
        print(f"| {case} | {r['peer_iterations']} | {g(r['peer_dt'])} | {g(r['peer_klst'])} | {g(r['peer_error_rms'])} | "
              f"{spread(r['peer_ms_per_sim_ms'], r['peer_ms_per_sim_ms_min'], r['peer_ms_per_sim_ms_max'])} | "
              f"{label(r)} | {g(r.get('dt'))} | {g(r.get('error_rms'))} | "
              f"{spread(r.get('ours_ms_per_sim_ms'), r.get('ours_ms_per_sim_ms_min'), r.get('ours_ms_per_sim_ms_max'))} | "
              f"{spread(r.get('ratio_ours_to_peer'), r.get('ratio_min'), r.get('ratio_max'))} | {verdict(r)} |")

print("\nFull step, probe in contact (ms per step, median [min–max] of the repetitions; contacts per step)\n")
print("| mesh | dt | integrator | ms/step | contacts/step | fallbacks | / naive_soa |")
print("|---|---|---|---|---|---|---|")
for r in rows:
    if not r["scene"].startswith("full_step_"):
        continue
    name = label(r) if r.get("peer") == "ours" else f"btSoftBody {r['iterations']} it., kLST {g(r.get('bullet_klst'))}"
    if r.get("impl") == "naive_soa":
        name = "naive_soa (symplectic, no collision)"
    elif r.get("impl") == "ours_single_precision_springs":
        name += f" (single-precision springs, {g(r.get('error_rms'))} m rms from double)"
    extra = ""
    if r.get("peer") == "bullet":
        extra = f" (nodes inside the probe {g(r.get('nodes_inside_probe'), 2)}; auto/Bullet {g(r.get('ratio_ours_to_bullet'))})"
    print(f"| {r['scene'][10:]} | {g(r['dt'])} | {name} | {spread(r['ms_per_step'], r.get('ms_min'), r.get('ms_max'))} | "
          f"{g(r.get('contacts'), 2)}{extra} | {r.get('fallbacks', 0)} | {g(r.get('ratio_to_naive'))} |")
