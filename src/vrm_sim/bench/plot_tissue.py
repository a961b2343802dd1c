#!/usr/bin/python3
"""Plot of bench/results/tissue.json (benchmark `tissue`, thesis §5, issue 3):
  tissue_error_vs_cost.png  Pareto plot (issue 19): error against the case's reference (Newton static solve for
                            static_sag_*, implicit Euler at dt -> 0 for grasp_pull_*) vs cost (ms of wall time per
                            simulated second, median of the repetitions, bars min..max), log-log; one line per
                            integrator through its dt values, our Pareto front dashed, Bullet btSoftBody (best kLST) as
                            red squares labelled by iterations and dt; one panel per case; unstable runs hollow.
                            Right: ms per step of the full step (probe in contact) per integrator next to Bullet.
Usage: plot_tissue.py [tissue.json] [output directory]   (defaults: bench/results/tissue.json, its folder)"""
import json
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

src = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench/results/tissue.json")
out = pathlib.Path(sys.argv[2]) if len(sys.argv) > 2 else src.parent
rows = json.load(open(src))["rows"]


def positive(value):
    return isinstance(value, (int, float)) and value > 0


accuracy = [r for r in rows if r["scene"].startswith(("grasp_pull_", "static_sag_")) and r.get("peer", "ours") == "ours"]
bullet = [r for r in rows if r["scene"].startswith(("grasp_pull_", "static_sag_")) and r.get("peer") == "bullet"]
meshes = sorted({r["scene"] for r in accuracy}, key=lambda name: (name.split("_")[0], int(name.split("_")[-1].split("x")[0])))
integrators = sorted({r["integrator"] for r in accuracy})
full = [r for r in rows if r["scene"].startswith("full_step_")]

fig, axes = plt.subplots(1, len(meshes) + 1, figsize=(6 * (len(meshes) + 1), 5.5), squeeze=False)
axes = axes[0]
for ax, mesh in zip(axes, meshes):
    for integrator in integrators:
        sel = sorted((r for r in accuracy if r["scene"] == mesh and r["integrator"] == integrator
                      and positive(r["error_rms"]) and positive(r["ms_per_step"])), key=lambda r: r["dt"])
        if not sel:
            continue
        cost = [r["ms_per_step"] / r["dt"] for r in sel]  # ms of wall time per simulated second
        error = [r["error_rms"] for r in sel]
        (line,) = ax.plot(cost, error, "-", label=integrator)
        lo = [max(c - r.get("ms_min", r["ms_per_step"]) / r["dt"], 0) for c, r in zip(cost, sel)]
        hi = [max(r.get("ms_max", r["ms_per_step"]) / r["dt"] - c, 0) for c, r in zip(cost, sel)]
        ax.errorbar(cost, error, xerr=[lo, hi], fmt="none", ecolor=line.get_color(), alpha=0.5, lw=0.8)
        for c, e, r in zip(cost, error, sel):
            ax.plot(c, e, "o", color=line.get_color(), fillstyle="full" if r["stable"] else "none")
            ax.annotate(f"{r['dt'] * 1e3:g} ms", (c, e), fontsize=6, xytext=(3, 3), textcoords="offset points")
    front = sorted(((r["ms_per_step"] / r["dt"], r["error_rms"]) for r in accuracy
                    if r["scene"] == mesh and r["stable"] and positive(r["error_rms"]) and positive(r["ms_per_step"])))
    pareto, best = [], float("inf")
    for c, e in front:
        if e < best:
            pareto.append((c, e))
            best = e
    if pareto:
        ax.step([c for c, _ in pareto], [e for _, e in pareto], "k--", where="post", lw=1, label="ours: Pareto front")
    for r in bullet:
        if r["scene"] != mesh or not positive(r.get("error_rms")) or not positive(r["ms_per_step"]):
            continue
        c = r["ms_per_step"] / r["dt"]
        ax.errorbar([c], [r["error_rms"]], xerr=[[max(c - r.get("ms_min", r["ms_per_step"]) / r["dt"], 0)],
                                                  [max(r.get("ms_max", r["ms_per_step"]) / r["dt"] - c, 0)]],
                    fmt="s", color="tab:red", ms=5, lw=0.8)
        ax.annotate(f"B{r['iterations']} {r['dt'] * 1e3:g} ms", (c, r["error_rms"]), fontsize=6, color="tab:red",
                    xytext=(3, -8), textcoords="offset points")
    first = next((r for r in accuracy if r["scene"] == mesh), None)
    nodes = f" ({first['nodes']} nodes, {first['springs']} springs)" if first else ""
    ax.set(xscale="log", yscale="log", xlabel="cost [ms wall time per simulated s]",
           ylabel="RMS position error vs reference [m]", title=f"{mesh}{nodes}\nref: {first.get('reference', '?') if first else ''}")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)

ax = axes[-1]
labels, values, colours = [], [], []
for r in sorted(full, key=lambda r: (r["nodes"], r["dt"], r.get("peer", "ours") != "ours", r["integrator"])):
    if not positive(r["ms_per_step"]):
        continue
    side = int(round(r["nodes"] ** 0.5)) - 1
    contacts = f" ({r['contacts']:.1f} contacts)" if isinstance(r.get("contacts"), (int, float)) else ""
    labels.append(f"{side}² dt {r['dt'] * 1e3:g} ms {r['integrator']}{'' if r.get('impl', 'ours') == 'ours' else ' ' + r['impl']}{contacts}")
    values.append(r["ms_per_step"])
    colours.append("tab:red" if r.get("peer") == "bullet" else "tab:blue")
ax.barh(range(len(values)), values, color=colours)
ax.set_yticks(range(len(values)))
ax.set_yticklabels(labels, fontsize=6)
ax.invert_yaxis()
ax.set(xscale="log", xlabel="ms per step (blue: ours, full step; red: Bullet btSoftBody)",
       title="full step, probe in contact, vs btSoftBody (10 it., kinematic sphere)")
ax.grid(True, which="both", axis="x", alpha=0.3)
fig.tight_layout()
fig.savefig(out / "tissue_error_vs_cost.png", dpi=110)
print(f"wrote {out / 'tissue_error_vs_cost.png'}")
