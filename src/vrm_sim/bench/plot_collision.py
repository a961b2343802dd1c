#!/usr/bin/python3
"""Plots of bench/results/collision.json (benchmark `collision`, thesis §4.2.6-4.2.7):
  collision_accuracy.png  deformation error (ZCOLL/F's 1-ring definition), triangle recall, and — against one exact
                          definition for every method (issue 19) — vertex recall / precision and the per-vertex axial
                          penetration error vs resolution, FCL and the primitives as horizontal lines; the cone test's
                          full-detection depth next to the prediction d = p / (2 tan 25°)
  collision_time.png      time per query vs resolution, image-space methods next to FCL and the exact primitives
Usage: plot_collision.py [collision.json] [output directory]   (defaults: bench/results/collision.json, its folder)"""
import json
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

src = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench/results/collision.json")
out = pathlib.Path(sys.argv[2]) if len(sys.argv) > 2 else src.parent
rows = json.load(open(src))["rows"]
teapot = [r for r in rows if r["scene"] == "teapot_membrane"]
cones = sorted((r for r in rows if r["scene"] == "cone_test"), key=lambda r: r["resolution"])
image_methods = sorted({r["method"] for r in teapot if isinstance(r["resolution"], int)})
styles = {"heavy": "-", "light": "--"}
colours = {m: plt.cm.tab10(i % 10) for i, m in enumerate(image_methods)}  # one colour per method, style = severity

fig, axes = plt.subplots(1, 5, figsize=(25, 4.5))
for method in image_methods:
    for severity in ("heavy", "light"):
        sel = sorted((r for r in teapot if r["method"] == method and r["severity"] == severity and r["deformed"]),
                     key=lambda r: r["resolution"])
        if not sel:
            continue
        res = [r["resolution"] for r in sel]
        axes[0].plot(res, [r["deform_err_um"] for r in sel], styles[severity], marker="o", color=colours[method],
                     label=f"{method} {severity}")
        axes[1].plot(res, [r["tris_found"] / max(1, r["tris_exact"]) for r in sel], styles[severity], marker="o",
                     color=colours[method], label=f"{method} {severity}")
pixel = sorted({(r["resolution"], r["pixel_um"]) for r in teapot if r["method"] == "zcoll_f_cpu"})
axes[0].plot([p[0] for p in pixel], [p[1] for p in pixel], "k:", label="pixel size")
axes[0].set(xscale="log", yscale="log", xlabel="resolution r (r x r pixels)", ylabel="RMS deformation error [µm]",
            title="vs ZCOLL/F's own definition (1-ring max along the axis)")
axes[1].set(xscale="log", xlabel="resolution r", ylabel="colliding triangles found / exact",
            title="triangle recall (several triangles per pixel -> one)")
# One definition for every method (issue 19): vertices inside the instrument solid, exact axial depth per vertex.
scored = [r for r in teapot if r["deformed"] and r.get("verts_exact") is not None and r["severity"] == "heavy"]
for method in image_methods:
    sel = sorted((r for r in scored if r["method"] == method), key=lambda r: r["resolution"])
    if not sel:
        continue
    res = [r["resolution"] for r in sel]
    axes[2].plot(res, [r["verts_hit"] / max(1, r["verts_exact"]) for r in sel], "-", marker="o", color=colours[method],
                 label=f"{method} recall")
    axes[2].plot(res, [r["verts_hit"] / max(1, r["verts_found"]) for r in sel], ":", marker="x", color=colours[method],
                 label=f"{method} precision")
    axes[3].plot(res, [r["depth_err_um"] for r in sel], "-", marker="o", color=colours[method], label=method)
for r in scored:
    if isinstance(r["resolution"], int) or r["method"] == "fcl_build":
        continue
    label = r["method"] + (f" ({r['bv']})" if r.get("bv") else "")
    axes[2].axhline(r["verts_hit"] / max(1, r["verts_exact"]), linestyle="--", linewidth=1, color="grey")
    axes[2].text(30, r["verts_hit"] / max(1, r["verts_exact"]), label + " recall", fontsize=6, va="bottom")
axes[2].set(xscale="log", xlabel="resolution r", ylabel="fraction",
            title="vertices inside the solid (exact), heavy: recall / precision")
axes[3].set(xscale="log", xlabel="resolution r", ylabel="RMS axial penetration error [µm]",
            title="per-vertex depth vs exact point-in-solid (heavy; FCL: none)")
for ax in axes[:4]:
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
axes = list(axes[:2]) + [axes[4]]
if cones:
    r = [c["resolution"] for c in cones]
    axes[2].plot(r, [c["depth_um"] for c in cones], "o-", label="measured (all 16 cones detected)")
    axes[2].plot(r, [c["predicted_um"] for c in cones], "k--", label="prediction p / (2 tan 25°)")
    axes[2].plot(r, [2 ** 0.5 * c["predicted_um"] for c in cones], "k:", label="√2 x prediction")
    axes[2].set(xscale="log", yscale="log", xlabel="resolution r", ylabel="penetration depth [µm]",
                title="cone test (thesis §4.2.6, Fig. 4.14)")
    axes[2].legend(fontsize=7)
    axes[2].grid(True, which="both", alpha=0.3)
fig.tight_layout()
fig.savefig(out / "collision_accuracy.png", dpi=110)

fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
for ax, deformed in zip(axes, (False, True)):
    for method in image_methods:
        for severity in ("heavy", "light"):
            sel = sorted((r for r in teapot if r["method"] == method and r["severity"] == severity
                          and r["deformed"] == deformed), key=lambda r: r["resolution"])
            if sel:
                ax.plot([r["resolution"] for r in sel], [r["ms_total"] for r in sel], styles[severity], marker="o",
                        color=colours[method], label=f"{method} {severity}")
    for r in teapot:
        if r["deformed"] == deformed and not isinstance(r["resolution"], int) and r["severity"] == "heavy":
            label = r["method"] + (f" ({r['bv']})" if r.get("bv") else "")
            ax.axhline(r["ms_total"], linestyle=":", linewidth=1, color="grey")
            ax.text(300, r["ms_total"], label, fontsize=6, va="bottom", ha="right")
    ax.set(xscale="log", yscale="log", xlabel="resolution r", ylabel="ms per query",
           title=("deformed" if deformed else "static") + " membrane (horizontal: FCL / primitives, heavy)")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
fig.tight_layout()
fig.savefig(out / "collision_time.png", dpi=110)
print(f"wrote {out / 'collision_accuracy.png'} and {out / 'collision_time.png'}")
