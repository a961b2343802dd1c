#!/usr/bin/python3
"""Plot of bench/results/validity.json (benchmark `validity`, issue 35):
  validity.png  per module, the totals of the expert, intermediate and novice cohorts on seeds 1-10 (box: median and
                IQR, whiskers 1.5 IQR, every member a dot), the rank test's p against the novices above each module,
                and the course battery's pass mark with the test seeds' false passes and fails in the title
Usage: plot_validity.py [validity.json] [output directory]   (defaults: bench/results/validity.json, its folder)"""
import json
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

src = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench/results/validity.json")
out = pathlib.Path(sys.argv[2]) if len(sys.argv) > 2 else src.parent
data = json.load(open(src))
rows = data["rows"]
modules = list(dict.fromkeys(r["module"] for r in rows))
cohorts = ["expert", "intermediate", "novice"]
colours = {"expert": "tab:green", "intermediate": "tab:orange", "novice": "tab:red"}

fig, ax = plt.subplots(figsize=(max(6, 2.2 * len(modules)), 5))
for m, module in enumerate(modules):
    for c, cohort in enumerate(cohorts):
        row = next(r for r in rows if r["module"] == module and r["cohort"] == cohort)
        x = m * 4 + c
        ax.boxplot([row["totals"]], positions=[x], widths=0.7, patch_artist=True, showfliers=False,
                   boxprops={"facecolor": colours[cohort], "alpha": 0.35}, medianprops={"color": "black"})
        ax.scatter([x] * len(row["totals"]), row["totals"], s=8, color=colours[cohort], zorder=3)
    expert = next(r for r in rows if r["module"] == module and r["cohort"] == "expert")
    ax.text(m * 4 + 1, 103, "p=%.2g" % expert["p_vs_novice"], ha="center", fontsize=8)
ax.set_xticks([m * 4 + 1 for m in range(len(modules))])
ax.set_xticklabels(modules, rotation=20)
ax.set_ylim(0, 108)
ax.set_ylabel("module total (0-100), seeds 1-10")
for cohort in cohorts:
    ax.plot([], [], "s", color=colours[cohort], label=cohort)
ax.legend(loc="lower left", fontsize=8)
course = data["course"]
ax.set_title("validity: %d of %d modules separate experts from novices (p < 0.01); course pass mark %g of %d "
             "\n(seeds %d-%d: %d false fails, %d false passes of %d)"
             % (data["separating_modules"], data["modules"], course["pass_mark"], course["max"],
                course["test_seeds"][0], course["test_seeds"][1], course["false_fail"], course["false_pass"],
                course["n_test"]), fontsize=9)
fig.tight_layout()
fig.savefig(out / "validity.png", dpi=110)
print("wrote", out / "validity.png")
