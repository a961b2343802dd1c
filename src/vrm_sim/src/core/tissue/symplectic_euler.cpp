#include "integrators_impl.h"

namespace vrm_sim {
namespace tissue {
namespace {

// Semi-implicit Euler: the position update uses the new velocity, which makes the undamped oscillator
// energy-conserving on average (stable for Δt < 2/ω_max) at the cost of one force evaluation like eq. 5.4.
class SymplecticEuler : public Integrator {
 public:
  const char* name() const override { return "symplectic_euler"; }
  void step(const SystemView& system, const ForceModel& forces, double dt) override {
    Eigen::Vector3d* f = ensureSize(forces_, system.node_count);
    forces.compute(system, system.positions, system.velocities, f);
    for (std::size_t i = 0; i < system.node_count; ++i) {
      if (!system.isFree(i)) continue;
      system.velocities[i] += (dt / system.masses[i]) * f[i];
      system.positions[i] += dt * system.velocities[i];
    }
  }

 private:
  std::vector<Eigen::Vector3d> forces_;
};

}  // namespace

std::unique_ptr<Integrator> makeSymplecticEuler() { return std::make_unique<SymplecticEuler>(); }

}  // namespace tissue
}  // namespace vrm_sim
