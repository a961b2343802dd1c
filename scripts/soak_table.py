#!/usr/bin/env python3
"""Prints the soak's per-minute table (markdown, for BENCHMARKS.md) and its verdict from bench/results/soak.json;
with --png also plots it (manager and graph RSS, CPU, message rates, end-to-end latency p99 and dropped frames).
Usage: scripts/soak_table.py [--png FILE] [--every K] [SOAK_JSON]   (default bench/results/soak.json; --every K
prints every K-th minute plus the baseline and the last one)"""
import argparse
import json
import os
import sys

COLUMN_NAMES = {"/eye_state": "eye Hz", "/instrument_state": "instr. Hz", "/simulation_state": "sim. Hz",
                "/render_timing": "rendered Hz", "/display_timing": "shown Hz", "/stereo/left/image_raw": "left img Hz",
                "/stereo/right/image_raw": "right img Hz"}


def p99(row, stage):
    value = (row["latency_p99_ms"].get(stage) or {}).get("max")
    return "–" if value is None else f"{value:.0f}"


def table(result, every):
    rows = result["rows"]
    tissue = sorted({t for row in rows for t in row["rates_hz"] if t.startswith("/tissue/")})
    judged = result.get("judged_topics") or list(COLUMN_NAMES)
    columns = [(t, COLUMN_NAMES.get(t, t + " Hz")) for t in judged] + [(t, t[len("/tissue/"):] + " Hz") for t in tissue]
    head = (["min", "manager RSS MB", "manager CPU %", "graph RSS MB", "graph CPU %", "host load"] + [c[1] for c in columns] +
            ["frames dropped", "e2e p99 ms", "sim. p99 ms", "render p99 ms", "crashes", "cycles ok"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---:|" * len(head)]
    baseline = result["baseline_minute"]
    for row in rows:
        m = row["minute"]
        if every > 1 and m not in (1, baseline, rows[-1]["minute"]) and m % every:
            continue
        cells = [str(m) + (" (base)" if m == baseline else ""), f"{row['manager_rss_mb']}", f"{row['manager_cpu_percent']}",
                 f"{row['graph_rss_mb']}", f"{row['graph_cpu_percent']}", f"{row.get('load_average', '–')}"]
        cells += [f"{row['rates_hz'].get(topic, 0):.1f}" for topic, _ in columns]
        cells += [str(row["render_dropped"]), p99(row, "end_to_end"), p99(row, "simulation"), p99(row, "render"),
                  str(row["crashes_total"]), str(row["scenario_cycles_ok"])]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(result, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result["rows"]
    minutes = [r["minute"] for r in rows]
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex=True)
    ax = axes[0][0]
    ax.plot(minutes, [r["manager_rss_mb"] for r in rows], "o-", label="nodelet manager")
    ax.plot(minutes, [r["graph_rss_mb"] for r in rows], "s--", label="whole graph")
    base = rows[result["baseline_minute"] - 1]["manager_rss_mb"] if len(rows) >= result["baseline_minute"] else None
    if base:
        ax.axhline(base * 1.05, color="red", lw=0.8, ls=":", label="manager +5 % of the baseline")
    ax.set_ylabel("RSS (MB)")
    ax.legend(fontsize=8)
    ax = axes[0][1]
    ax.plot(minutes, [r["manager_cpu_percent"] for r in rows], "o-", label="nodelet manager")
    ax.plot(minutes, [r["graph_cpu_percent"] for r in rows], "s--", label="whole graph")
    ax.plot(minutes, [r["monitor_cpu_percent"] for r in rows], "^:", label="soak monitor (viewer)")
    ax.set_ylabel("CPU (% of one core)")
    ax.legend(fontsize=8)
    ax = axes[1][0]
    topics = sorted({t for r in rows for t in r["rates_hz"]})
    for topic in topics:
        ax.plot(minutes, [r["rates_hz"].get(topic, 0) for r in rows], ".-", label=topic)
    ax.set_ylabel("messages per s")
    ax.set_xlabel("minute")
    ax.legend(fontsize=7)
    ax = axes[1][1]
    for stage in ("end_to_end", "simulation", "render"):
        values = [(r["latency_p99_ms"].get(stage) or {}).get("max") for r in rows]
        ax.plot(minutes, [v if v is not None else float("nan") for v in values], "o-", label=f"{stage} p99")
    ax.set_ylabel("latency p99 (ms, max of 10 s windows)")
    ax.set_xlabel("minute")
    twin = ax.twinx()
    twin.bar(minutes, [r["render_dropped"] for r in rows], alpha=0.25, color="gray", label="frames dropped")
    twin.set_ylabel("frames dropped per minute")
    ax.legend(fontsize=8, loc="upper left")
    verdict = result["verdict"]
    fig.suptitle(f"soak: {result['minutes']} min, {result['scene']}, {result['date_utc']} UTC — {verdict['result']}"
                 f" (manager RSS growth {verdict['manager_rss_growth_percent']} % from minute "
                 f"{result['baseline_minute']})" + (" — smoke mode" if result["smoke"] else ""), fontsize=10)
    from matplotlib.ticker import MaxNLocator
    for ax in axes.flat:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("json", nargs="?", default=os.path.join(os.path.dirname(__file__), "..", "bench", "results",
                                                                 "soak.json"))
    parser.add_argument("--png", default="")
    parser.add_argument("--every", type=int, default=1)
    args = parser.parse_args()
    with open(args.json) as f:
        result = json.load(f)
    verdict = result["verdict"]
    print(f"Soak, {result['minutes']} min ({result['minute_seconds']:.0f} s each), {result['date_utc']} UTC, "
          f"{result['cores']} cores{', smoke mode' if result['smoke'] else ''}: **{verdict['result']}** — "
          f"manager RSS growth {verdict['manager_rss_growth_percent']} % from minute {result['baseline_minute']}, "
          f"{len(result['crashes'])} crashes, {sum(1 for c in result['cycles'] if c['ok'])}/{len(result['cycles'])} "
          f"scenario cycles acknowledged.")
    for reason in verdict["reasons"]:
        print(f"- {reason}")
    print()
    print(table(result, args.every))
    if args.png:
        plot(result, args.png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
