#include <cmath>

#include "integrators_impl.h"

namespace vrm_sim {
namespace tissue {
namespace {

// XPBD (Macklin, Müller & Chentanez 2016) as a modern baseline: predict with the non-spring forces, then project
// the spring constraints C = |d| − l with compliance α = 1/k in Gauss-Seidel sweeps; velocities from the position
// change. Unconditionally stable, converges to implicit Euler as the iteration count grows.
class Xpbd : public Integrator {
 public:
  explicit Xpbd(const IntegratorOptions& options) : options_(options) {}
  const char* name() const override { return "xpbd"; }
  int lastIterations() const override { return options_.xpbd_iterations; }

  void step(const SystemView& system, const ForceModel& forces, double dt) override {
    const std::size_t n = system.node_count;
    Eigen::Vector3d* previous = ensureSize(previous_, n);
    double* lambda = ensureSize(lambda_, system.spring_count);
    const double h2 = dt * dt;
    for (std::size_t i = 0; i < n; ++i) {
      previous[i] = system.positions[i];
      if (!system.isFree(i)) continue;
      Eigen::Vector3d external =
          system.masses[i] * forces.params.gravity - forces.params.damping * system.velocities[i];
      if (!forces.external.empty()) external += forces.external[i];
      system.positions[i] += dt * system.velocities[i] + (h2 / system.masses[i]) * external;
    }
    for (std::size_t s = 0; s < system.spring_count; ++s) lambda[s] = 0.0;
    for (int iteration = 0; iteration < options_.xpbd_iterations; ++iteration) {
      for (std::size_t s = 0; s < system.spring_count; ++s) {
        const auto& ends = system.springs[s];
        const double w0 = system.isFree(ends[0]) ? 1.0 / system.masses[ends[0]] : 0.0;
        const double w1 = system.isFree(ends[1]) ? 1.0 / system.masses[ends[1]] : 0.0;
        const double k = system.stiffnesses[s];
        if (w0 + w1 == 0.0 || k <= 0.0) continue;
        const Eigen::Vector3d d = system.positions[ends[1]] - system.positions[ends[0]];
        const double length = d.norm();
        if (length < kMinSpringLength) continue;
        const double alpha = 1.0 / (k * h2);
        const double c = length - system.rest_lengths[s];
        const double delta = (-c - alpha * lambda[s]) / (w0 + w1 + alpha);
        lambda[s] += delta;
        const Eigen::Vector3d correction = (delta / length) * d;
        system.positions[ends[0]] -= w0 * correction;
        system.positions[ends[1]] += w1 * correction;
      }
      for (const Anchor& anchor : forces.anchors) {
        if (!system.isFree(anchor.node) || anchor.stiffness <= 0.0) continue;
        // Zero-rest-length spring to a fixed point: the closed-form XPBD update per component (no λ history
        // across sweeps needed for a single-body constraint solved exactly each sweep).
        const double w = 1.0 / system.masses[anchor.node];
        const double alpha = 1.0 / (anchor.stiffness * h2);
        Eigen::Vector3d& x = system.positions[anchor.node];
        x += (w / (w + alpha)) * (anchor.point - x) / options_.xpbd_iterations;
      }
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (system.isFree(i)) system.velocities[i] = (system.positions[i] - previous[i]) / dt;
    }
  }

 private:
  IntegratorOptions options_;
  std::vector<Eigen::Vector3d> previous_;
  std::vector<double> lambda_;
};

}  // namespace

std::unique_ptr<Integrator> makeXpbd(const IntegratorOptions& options) { return std::make_unique<Xpbd>(options); }

}  // namespace tissue
}  // namespace vrm_sim
