#!/usr/bin/python3
"""The constants of `auto`'s cost model (issue 40 §2, AutoIntegratorOptions in integrator_choice.h), fitted to the
full-step rows of bench_tissue's JSON: each row's CPU ms per step against its work counts per step (work_per_step,
TissueWork), per spring:
    ms = springs * (E * integrations + I0 * implicit integrations + C * CG iterations + W * bound sweeps)
by least squares relative to each row (symplectic, quasi-static and implicit Euler; 22x22 and 100x100 at 0.25 and
1 ms). Prints E, I0, C, W, the model's ratios I0/E, C/E, W/E (the options' defaults) and each row's fit; with a
second file (a run with --only hard) also how the model predicts the hard cases, which were not fitted.
Usage: fit_auto_cost.py FULL_STEP_JSON [HARD_JSON]
       (bench_tissue --only full_step --out FULL_STEP_JSON; bench_tissue --only hard --out HARD_JSON)"""
import json
import sys

import numpy as np

INTEGRATORS = ("symplectic_euler", "quasi_static_euler", "implicit_euler")


def rows(path):
    for row in json.load(open(path))["rows"]:
        if row.get("impl") != "ours" or row["integrator"] not in INTEGRATORS or not row.get("work_per_step"):
            continue
        if row.get("dt_divisor"):
            continue
        work = {key: float(value) for key, value in row["work_per_step"].items()}
        springs = float(row["springs"])
        implicit = 1.0 if row["integrator"] == "implicit_euler" else 0.0
        features = [springs * work["integrations"], springs * implicit * work["integrations"],
                    springs * work["cg_iterations"], springs * work["bound_sweeps"]]
        ms = float(row.get("cpu_ms_per_step") or row["ms_per_step"])
        yield features, ms, "%s %s dt %g" % (row["scene"], row["integrator"], row["dt"])


if len(sys.argv) < 2:
    sys.exit(__doc__)
fit = list(rows(sys.argv[1]))
if len(fit) < 4:
    sys.exit("fit_auto_cost.py: %s has %d full-step rows with work counts (bench_tissue --only full_step --out)"
             % (sys.argv[1], len(fit)))
features = np.array([f for f, _, _ in fit])
ms = np.array([m for _, m, _ in fit])
weights = 1.0 / ms
x, *_ = np.linalg.lstsq(features * weights[:, None], ms * weights, rcond=None)
print("per spring: E %.2f ns, I0 %.2f ns, C %.2f ns, W %.2f ns" % tuple(1e6 * x))
print("AutoIntegratorOptions: implicit_extra %.2f, cg_iteration %.3f, bound_sweep %.3f (in E)"
      % (x[1] / x[0], x[2] / x[0], x[3] / x[0]))
for path, label in [(sys.argv[1], "fit ")] + ([(sys.argv[2], "hard")] if len(sys.argv) > 2 else []):
    for f, m, name in rows(path):
        predicted = float(np.dot(f, x))
        print("%s %-55s %9.4f ms, model %9.4f (%+.0f %%)" % (label, name, m, predicted, 100 * (predicted / m - 1)))
