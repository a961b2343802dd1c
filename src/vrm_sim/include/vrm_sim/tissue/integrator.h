#pragma once
// Time integration of the mass-spring system (thesis §5.1): a small interface, one implementation per file, chosen
// by name from the scene YAML (`tissue.integrator`).
//
// Names: explicit_euler (eq. 5.4), quasi_static_euler (eq. 5.5), rk2 (midpoint), implicit_euler (eqs. 5.7-5.10,
// Baraff & Witkin 1998, filtered conjugate gradients), symplectic_euler (semi-implicit, modern baseline), xpbd
// (extended position based dynamics, Macklin et al. 2016, modern baseline).

#include <memory>
#include <string>
#include <vector>

#include "vrm_scene/registry.h"
#include "vrm_sim/state/state_archive.h"
#include "vrm_sim/tissue/system.h"

namespace vrm_sim {
namespace tissue {

struct IntegratorOptions {
  int cg_max_iterations = 30;  // implicit_euler
  double cg_tolerance = 1e-8;  // relative residual |r| / |b|
  // implicit_euler: "jacobi" (diagonal of A), "block_jacobi" (3x3 node blocks of A) or "none".
  std::string cg_preconditioner = "jacobi";
  // implicit_euler: start CG from the previous step's Δv (scaled to this dt) instead of 0 (bench_implicit: 8× lower
  // residual and 14× lower error after 10 iterations at 10k nodes, for 0–5 % more time).
  bool cg_warm_start = true;
  int xpbd_iterations = 10;  // constraint sweeps per step
};

class Integrator {
 public:
  virtual ~Integrator() = default;
  virtual const char* name() const = 0;
  // Advances the free nodes of `system` by dt. Buffers are sized on the first step after a topology change only.
  virtual void step(const SystemView& system, const ForceModel& forces, double dt) = 0;
  // Work done in the last step, for benchmarks: CG or constraint iterations (1 for one-shot methods).
  virtual int lastIterations() const { return 1; }
  // Relative residual |r| / |b| the last step's linear solve ended with (0 for methods without one).
  virtual double lastResidual() const { return 0.0; }
  // Every step starts from rest (quasi-static Euler): the velocities it leaves are reported for the collision
  // response and rendering, not carried into the next step (so the strain limit need not make them agree with its
  // corrections).
  virtual bool startsFromRest() const { return false; }
  // Checkpoints (issue 39 §1): what the integrator carries from one step into the next, for the membrane `system`
  // it will step next. Most carry nothing (their buffers are rewritten every step); implicit Euler keeps its warm
  // start.
  virtual void transferState(StateArchive& /*archive*/, const SystemView& /*system*/) {}
};

using IntegratorFactory = std::unique_ptr<Integrator> (*)(const IntegratorOptions& options);

// The names `tissue.integrator` accepts, in this order: "auto" first (the default: the integrator is chosen per
// membrane by TissueSimulator, see integrator_choice.h; its factory builds the integrator "auto" starts with,
// symplectic_euler, before the first choice), then the integrators proper. The scene schema check, makeIntegrator()
// and the listings all read this table.
const Registry<IntegratorFactory>& integratorRegistry();
// The integrators proper: integratorRegistry()'s names without "auto", in table order.
const std::vector<std::string>& integratorNames();
// integratorRegistry().at(name).make(options): throws std::invalid_argument naming the known integrators for an
// unknown name.
std::unique_ptr<Integrator> makeIntegrator(const std::string& name, const IntegratorOptions& options = {});

// Explicit stability bound of eq. 5.6 in its empirical form Δt ≤ 0.4π·sqrt(m0/k0) with k0 = max k_ij, m0 = min m_i
// (thesis §5.1). Anchors count as springs.
double explicitStabilityBound(const SystemView& system, const ForceModel& forces);

}  // namespace tissue
}  // namespace vrm_sim
