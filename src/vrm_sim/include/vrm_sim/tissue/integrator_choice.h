#pragma once
// `integrator: auto` (issue 15 §3): per membrane, the cheapest integrator that is stable for its stiffness, masses,
// damping and Δt. Explicit candidates: symplectic Euler (the smallest error of the one-evaluation integrators at a
// stable Δt, see BENCHMARKS.md) and the thesis' quasi-static Euler (eq. 5.5; the same cost, stable where damping
// makes symplectic Euler overshoot), each in n equal substeps when Δt exceeds its bound; the implicit candidate is
// implicit Euler (eqs. 5.7-5.10), stable at any Δt. The cheapest by a measured cost ratio wins.

#include <string>
#include <vector>

#include "vrm_sim/tissue/system.h"

namespace vrm_sim {
namespace tissue {

struct AutoIntegratorOptions {
  // The explicit step must stay below this fraction of the bound: eq. 5.6 is empirical (Provot and the collision
  // response perturb the linear analysis), the hard cases of bench_tissue hold with 0.8.
  double margin = 0.8;
  // Cost of one implicit Euler step (10 CG iterations, watchdog) in explicit full steps (symplectic Euler, watchdog)
  // of the same membrane, measured on the grasp-and-pull: 2.6 at 10k nodes, 2.9 at 529 (bench_tissue full_step rows).
  // Explicit substeps are chosen while n ≤ this.
  double implicit_cost = 2.5;
};

struct IntegratorChoice {
  std::string integrator;  // "symplectic_euler", "quasi_static_euler" or "implicit_euler"
  int substeps = 1;        // explicit substeps per Δt
  double bound = 0.0;      // s: the explicit bound with the margin (infinity: no spring, no damping)
  std::string reason;      // one line for the log: why this integrator
};

// The explicit stability bound per node, generalised from eq. 5.6 to damping: a node of mass m_i whose stiffest
// spring (or anchor) is k_i oscillates at ω_i = 2 / (0.4π·sqrt(m_i/k_i)) (so the undamped bound 2/ω_i is exactly
// eq. 5.6 for that node) and is damped at γ_i = c/m_i; symplectic Euler on that damped oscillator is stable for
// Δt < (−γ + sqrt(γ² + 4ω²)) / ω² (→ 2/ω without damping, → 2/γ without springs). The minimum over free nodes.
// `scratch` (optional) is reused so that a re-decision after a grasp allocates nothing.
double dampedExplicitBound(const SystemView& system, const ForceModel& forces, std::vector<double>* scratch = nullptr);

// Quasi-static Euler (eq. 5.5) resets the velocities, so damping does not enter: Δt < 2/ω_i = eq. 5.6 per node.
double quasiStaticBound(const SystemView& system, const ForceModel& forces, std::vector<double>* scratch = nullptr);

IntegratorChoice chooseIntegrator(const SystemView& system, const ForceModel& forces, double dt,
                                  const AutoIntegratorOptions& options = {}, std::vector<double>* scratch = nullptr);

// The name that selects this: TissueConfig::integrator / the scene's `tissue.integrator`.
constexpr const char* kAutoIntegrator = "auto";

}  // namespace tissue
}  // namespace vrm_sim
