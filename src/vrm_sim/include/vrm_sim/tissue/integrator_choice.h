#pragma once
// `integrator: auto` (issue 15 §3): per membrane, the cheapest integrator that is stable for its stiffness, masses,
// damping and Δt. Explicit candidates: symplectic Euler (the smallest error of the one-evaluation integrators at a
// stable Δt, see BENCHMARKS.md) and the thesis' quasi-static Euler (eq. 5.5; the same cost, stable where damping
// makes symplectic Euler overshoot), each in n equal substeps when Δt exceeds its bound; the implicit candidate is
// implicit Euler (eqs. 5.7-5.10), stable at any Δt. The cheapest by a cost model over the work the steps count
// (TissueWork) wins; explicit substeps below the a-priori bound are tried, the watchdog keeping or refusing them.

#include <string>
#include <vector>

#include "vrm_sim/tissue/system.h"

namespace vrm_sim {
namespace tissue {

struct AutoIntegratorOptions {
  // The explicit step must stay below this fraction of the bound: eq. 5.6 is empirical (Provot and the collision
  // response perturb the linear analysis), the hard cases of bench_tissue hold with 0.8.
  double margin = 0.8;
  // The cost model (issue 40 §2), counted in one explicit integration (force evaluation, integration, energy balance,
  // one Provot pass and the bound check's scan: 23.9 ns per spring here). Fitted with bench_tissue's work counts
  // (TissueWork) on its full-step rows — 22×22 and 100×100, 0.25 and 1 ms, every integrator, within ±8 % — not on
  // the hard cases, which test it (BENCHMARKS.md, "auto with a cost model of the steps' own work"; refit with
  // src/vrm_sim/bench/fit_auto_cost.py):
  // Refitted after the implicit step's one-sweep assembly (2026-12-01): its set-up now costs less than an explicit
  // integration's force pass and integration (implicit_extra < 0), a CG iteration 0.15 of one.
  double implicit_extra = -0.19;  // implicit Euler's integration beyond an explicit one, its CG iterations aside
  double cg_iteration = 0.15;     // one CG iteration
  double bound_sweep = 0.20;      // one BFS sweep of the bound projection (paid per integration, by either)
  // eq. 5.6 is empirical, and its margin is a guess: the count without the margin is tried where it is smaller (the
  // watchdog proves it, or the margin's count follows at once); where the bound asks for more substeps than implicit
  // Euler is worth, the count it is worth is tried if that is at least this fraction of the count without the margin
  // (or implicit Euler follows at once).
  double probe_fraction = 0.5;
  // Trials need the watchdog to judge them: off, every count is the bound's with its margin.
  bool trials = true;
};

// What the steps so far did (TissueWork, averaged): CG iterations per implicit integration (negative: none ran yet,
// the iteration budget is assumed) and bound sweeps per integration.
struct ObservedWork {
  double cg_iterations = -1.0;
  double bound_sweeps = 0.0;
};

struct IntegratorChoice {
  std::string integrator;  // "symplectic_euler", "quasi_static_euler" or "implicit_euler"
  int substeps = 1;        // explicit substeps per Δt
  double bound = 0.0;      // s: the explicit bound with the margin (infinity: no spring, no damping)
  // Explicit substeps below the a-priori count, on trial: the first step the watchdog rejects at this count turns the
  // choice into the safe one (TissueSimulator::rejectIntegratorProbe()): `safe_substeps` of the same integrator, or
  // implicit Euler when that is 0.
  bool probe = false;
  int safe_substeps = 0;
  double implicit_cost = 0.0;  // the model's implicit Euler step, in explicit substeps
  std::string reason;          // one line for the log: why this integrator
  void transferState(StateArchive& archive) {
    archive(integrator)(substeps)(bound)(probe)(safe_substeps)(implicit_cost)(reason);
  }
};

// The explicit stability bound per node, generalised from eq. 5.6 to damping: a node of mass m_i whose stiffest
// spring (or anchor) is k_i oscillates at ω_i = 2 / (0.4π·sqrt(m_i/k_i)) (so the undamped bound 2/ω_i is exactly
// eq. 5.6 for that node) and is damped at γ_i = c/m_i; symplectic Euler on that damped oscillator is stable for
// Δt < (−γ + sqrt(γ² + 4ω²)) / ω² (→ 2/ω without damping, → 2/γ without springs). The minimum over free nodes.
// `scratch` (optional) is reused so that a re-decision after a grasp allocates nothing.
double dampedExplicitBound(const SystemView& system, const ForceModel& forces, std::vector<double>* scratch = nullptr);

// Quasi-static Euler (eq. 5.5) resets the velocities, so damping does not enter: Δt < 2/ω_i = eq. 5.6 per node.
double quasiStaticBound(const SystemView& system, const ForceModel& forces, std::vector<double>* scratch = nullptr);

// `cg_budget`: implicit Euler's iteration limit (IntegratorOptions::cg_max_iterations; the shipped scenes' 10), the CG
// iterations assumed before any implicit step ran.
IntegratorChoice chooseIntegrator(const SystemView& system, const ForceModel& forces, double dt,
                                  const AutoIntegratorOptions& options = {}, std::vector<double>* scratch = nullptr,
                                  const ObservedWork& observed = {}, int cg_budget = 10);

// The name that selects this: TissueConfig::integrator / the scene's `tissue.integrator`.
constexpr const char* kAutoIntegrator = "auto";

}  // namespace tissue
}  // namespace vrm_sim
