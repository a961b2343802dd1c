#include "vrm_sim/tissue/integrator_choice.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

namespace vrm_sim {
namespace tissue {

namespace {

// Per free node: the stiffest spring or anchor at it (eq. 5.6's k0, per node) and its mass.
template <typename Visit>
void forEachFreeNode(const SystemView& system, const ForceModel& forces, std::vector<double>* scratch, Visit visit) {
  const std::size_t n = system.node_count;
  std::vector<double> local;
  std::vector<double>& stiffest = scratch != nullptr ? *scratch : local;
  stiffest.assign(n, 0.0);
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    const double k = system.stiffnesses[s];
    for (std::uint32_t end : system.springs[s]) stiffest[end] = std::max(stiffest[end], k);
  }
  for (const Anchor& anchor : forces.anchors) {
    if (anchor.node < n) stiffest[anchor.node] = std::max(stiffest[anchor.node], anchor.stiffness);
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (system.isFree(i) && system.masses[i] > 0.0) visit(system.masses[i], stiffest[i]);
  }
}

// ω of eq. 5.6 for one node: 2/ω is the thesis' bound 0.4π·sqrt(m/k).
double omegaSquared(double mass, double stiffness) { return stiffness / (mass * (0.2 * M_PI) * (0.2 * M_PI)); }

}  // namespace

namespace {

struct ExplicitBounds {
  double symplectic = std::numeric_limits<double>::infinity();
  double quasi_static = std::numeric_limits<double>::infinity();
};

// Both candidates' bounds from one pass over the nodes (and one over the springs for their stiffest).
ExplicitBounds explicitBounds(const SystemView& system, const ForceModel& forces, std::vector<double>* scratch) {
  const double damping = std::max(forces.params.damping, 0.0);
  ExplicitBounds bounds;
  forEachFreeNode(system, forces, scratch, [&](double mass, double stiffness) {
    const double omega2 = omegaSquared(mass, stiffness);
    const double gamma = damping / mass;
    if (omega2 > 0.0) {
      bounds.symplectic = std::min(bounds.symplectic, (-gamma + std::sqrt(gamma * gamma + 4.0 * omega2)) / omega2);
      bounds.quasi_static = std::min(bounds.quasi_static, 2.0 / std::sqrt(omega2));
    } else if (gamma > 0.0) {
      bounds.symplectic = std::min(bounds.symplectic, 2.0 / gamma);
    }
  });
  return bounds;
}

}  // namespace

double dampedExplicitBound(const SystemView& system, const ForceModel& forces, std::vector<double>* scratch) {
  return explicitBounds(system, forces, scratch).symplectic;
}

double quasiStaticBound(const SystemView& system, const ForceModel& forces, std::vector<double>* scratch) {
  return explicitBounds(system, forces, scratch).quasi_static;
}

IntegratorChoice chooseIntegrator(const SystemView& system, const ForceModel& forces, double dt,
                                  const AutoIntegratorOptions& options, std::vector<double>* scratch,
                                  const ObservedWork& observed, int cg_budget) {
  const auto substepsFor = [dt](double bound) {
    return std::isfinite(bound) ? std::max(1.0, std::ceil(dt / bound - 1e-9)) : 1.0;
  };
  const ExplicitBounds bounds = explicitBounds(system, forces, scratch);
  const double symplectic_bound = options.margin * bounds.symplectic;
  const double quasi_static_bound = options.margin * bounds.quasi_static;
  const double symplectic_steps = substepsFor(symplectic_bound);
  const double quasi_static_steps = substepsFor(quasi_static_bound);
  IntegratorChoice choice;
  // Equal cost per step: symplectic Euler follows the dynamics (second-order energy behaviour), quasi-static Euler
  // relaxes towards equilibrium and ignores the damping, so it wins only when it needs fewer substeps (heavily damped
  // light nodes, where symplectic Euler's velocity damping overshoots).
  const bool quasi_static = quasi_static_steps < symplectic_steps;
  const double needed = quasi_static ? quasi_static_steps : symplectic_steps;
  const double without_margin = substepsFor(quasi_static ? bounds.quasi_static : bounds.symplectic);
  choice.bound = quasi_static ? quasi_static_bound : symplectic_bound;
  // The cost model: an implicit step in explicit substeps. Both pay the bound projection's sweeps per integration.
  const double iterations = observed.cg_iterations >= 0.0 ? observed.cg_iterations : std::max(cg_budget, 1);
  const double projection = options.bound_sweep * std::max(observed.bound_sweeps, 0.0);
  choice.implicit_cost =
      (1.0 + options.implicit_extra + options.cg_iteration * iterations + projection) / (1.0 + projection);
  const double probe = std::floor(choice.implicit_cost + 1e-9);
  const char* name = quasi_static ? "quasi_static_euler" : "symplectic_euler";
  char line[320];
  if (needed <= std::max(1.0, choice.implicit_cost)) {
    choice.integrator = name;
    choice.substeps = static_cast<int>(needed);
    if (options.trials && without_margin < needed) {
      choice.safe_substeps = choice.substeps;
      choice.substeps = static_cast<int>(without_margin);
      choice.probe = true;
    }
    std::snprintf(
        line, sizeof line,
        "explicit bound %.3g ms (symplectic %.3g, quasi-static %.3g; margin %.2f), dt %.3g ms: %s, %d "
        "substep%s%s (an implicit step costs %.2f)",
        1e3 * choice.bound, 1e3 * symplectic_bound, 1e3 * quasi_static_bound, options.margin, 1e3 * dt, name,
        choice.substeps, choice.substeps > 1 ? "s" : "",
        choice.probe ? (" on trial, the margin's " + std::to_string(choice.safe_substeps) + " if refused").c_str() : "",
        choice.implicit_cost);
  } else if (options.trials && probe >= 1.0 && probe >= options.probe_fraction * without_margin) {
    choice.integrator = name;
    choice.substeps = static_cast<int>(probe);
    choice.probe = true;
    std::snprintf(line, sizeof line,
                  "explicit bound %.3g ms (margin %.2f) needs %.0f substeps of dt %.3g ms (%.0f without the margin), "
                  "an implicit step costs %.2f: %s x%d on trial (the watchdog decides)",
                  1e3 * choice.bound, options.margin, needed, 1e3 * dt, without_margin, choice.implicit_cost, name,
                  choice.substeps);
  } else {
    choice.integrator = "implicit_euler";
    std::snprintf(line, sizeof line,
                  "explicit bound %.3g ms (margin %.2f) needs %.0f substeps of dt %.3g ms, more than one implicit step "
                  "costs (%.2f): implicit_euler",
                  1e3 * choice.bound, options.margin, needed, 1e3 * dt, choice.implicit_cost);
  }
  choice.reason = line;
  return choice;
}

}  // namespace tissue
}  // namespace vrm_sim
