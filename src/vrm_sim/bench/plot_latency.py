#!/usr/bin/python3
"""Plot of bench/results/latency.json (benchmark `latency`, issue 12, thesis §2.5.2):
  latency_histogram.png  per configuration (synchronisation pattern x tracking) the histogram of the end-to-end
                         latency (input stamp -> image published, 1 ms bins), for the pipelined pattern also of the
                         simulated effect (input stamp of the simulation frame shown -> image published); p50 and p99
                         marked, and the latency the thesis predicts from the measured stage times (eq. 2.3/2.4/2.7)
Usage: plot_latency.py [latency.json] [output directory]   (defaults: bench/results/latency.json, its folder)"""
import json
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

src = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench/results/latency.json")
out = pathlib.Path(sys.argv[2]) if len(sys.argv) > 2 else src.parent
data = json.load(open(src))
configs = data["configs"]
rows = data["rows"]
if not configs:
    sys.exit("plot_latency.py: no configurations in " + str(src))


def row(config, stage):
    return next((r for r in rows if r["config"] == config and r["stage"] == stage), None)


patterns = ["sequential", "parallel_async", "pipelined"]
tracking_values = [False, True]
# With several runs per configuration (bench_latency --runs), the first run is drawn (rows and histogram alike).
present = {}
for c in configs:
    present.setdefault((c["pattern"], c["tracking"]), c)
columns = [p for p in patterns if any((p, t) in present for t in tracking_values)]
lines = [t for t in tracking_values if any((p, t) in present for p in patterns)]
fig, axes = plt.subplots(len(lines), len(columns), figsize=(5 * len(columns), 3.6 * len(lines)), squeeze=False,
                         sharex=True)
limit = 1
for i, tracking in enumerate(lines):
    for j, pattern in enumerate(columns):
        ax = axes[i][j]
        config = present.get((pattern, tracking))
        if config is None:
            ax.set_visible(False)
            continue
        name = config["config"]
        series = [("end_to_end", config["histogram_end_to_end"], "tab:blue")]
        if pattern == "pipelined":
            series.append(("end_to_end_world", config["histogram_end_to_end_world"], "tab:orange"))
        for stage, counts, colour in series:
            r = row(name, stage)
            total = max(1, sum(counts))
            ax.bar(range(len(counts)), [c / total for c in counts], width=1.0, align="edge", color=colour, alpha=0.6,
                   label=f"{stage}: p50 {r['p50_ms']:.1f}, p99 {r['p99_ms']:.1f} ms")
            last = max((k for k, c in enumerate(counts) if c), default=0)
            limit = max(limit, last + 5)
            ax.axvline(r["p99_ms"], color=colour, linestyle=":", linewidth=1)
            if "predicted_ms" in r:
                ax.axvline(r["predicted_ms"], color="k", linestyle="--", linewidth=1.2,
                           label=f"eq. {r['predicted_eq']}: {r['predicted_ms']:.1f} ms")
                if abs(r["predicted_graph_ms"] - r["predicted_ms"]) > 0.05:
                    ax.axvline(r["predicted_graph_ms"], color="grey", linestyle="-.", linewidth=1.2,
                               label=f"with the graph's clocks: {r['predicted_graph_ms']:.1f} ms")
        e2e = row(name, "end_to_end")
        ax.set_title(f"{pattern}, tracking:={'true' if tracking else 'false'}\n"
                     f"{e2e['fps']:.1f} fps, {e2e['dropped']} input ticks not shown", fontsize=10)
        ax.set(xlabel="latency [ms]", ylabel="fraction of frames")
        ax.legend(fontsize=7, loc="upper right")
for ax in axes.flat:
    ax.set_xlim(0, min(250, limit))
    ax.grid(alpha=0.3)
targets = "targets: tracking:=false p99 <= 47 ms; tracking:=true p50 <= 57, p99 <= 90 ms, >= 25 fps"
fig.suptitle(f"End-to-end latency per synchronisation pattern (thesis Fig. 2.6), {data['seconds_per_config']:.0f} s "
             f"per configuration at {data['input_rate_hz']:.0f} Hz input, stereo 800x600 watched\n{targets}",
             fontsize=10)
fig.tight_layout()
out.mkdir(parents=True, exist_ok=True)
fig.savefig(out / "latency_histogram.png", dpi=110)
print(f"wrote {out / 'latency_histogram.png'}")
