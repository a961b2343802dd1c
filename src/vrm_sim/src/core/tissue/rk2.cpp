#include "integrators_impl.h"

namespace vrm_sim {
namespace tissue {
namespace {

// Runge-Kutta 2 (midpoint, thesis §5.2.1): F evaluated at the half step, second order.
class Rk2 : public Integrator {
 public:
  const char* name() const override { return "rk2"; }
  void step(const SystemView& system, const ForceModel& forces, double dt) override {
    const std::size_t n = system.node_count;
    Eigen::Vector3d* f = ensureSize(forces_, n);
    Eigen::Vector3d* xm = ensureSize(mid_positions_, n);
    Eigen::Vector3d* vm = ensureSize(mid_velocities_, n);
    forces.compute(system, system.positions, system.velocities, f);
    for (std::size_t i = 0; i < n; ++i) {
      xm[i] = system.positions[i];
      vm[i] = system.velocities[i];
      if (!system.isFree(i)) continue;
      xm[i] += (0.5 * dt) * system.velocities[i];
      vm[i] += (0.5 * dt / system.masses[i]) * f[i];
    }
    forces.compute(system, xm, vm, f);
    for (std::size_t i = 0; i < n; ++i) {
      if (!system.isFree(i)) continue;
      system.positions[i] += dt * vm[i];
      system.velocities[i] += (dt / system.masses[i]) * f[i];
    }
  }

 private:
  std::vector<Eigen::Vector3d> forces_, mid_positions_, mid_velocities_;
};

}  // namespace

std::unique_ptr<Integrator> makeRk2() { return std::make_unique<Rk2>(); }

}  // namespace tissue
}  // namespace vrm_sim
