#include "integrators_impl.h"

namespace vrm_sim {
namespace tissue {
namespace {

// Eq. 5.5: the system is assumed to come to rest after every step, so velocities are reset and the position moves
// by Δt²·M⁻¹F — a damped relaxation towards equilibrium, the thesis' choice for interactive membranes.
class QuasiStaticEuler : public Integrator {
 public:
  const char* name() const override { return "quasi_static_euler"; }
  bool startsFromRest() const override { return true; }
  void step(const SystemView& system, const ForceModel& forces, double dt) override {
    Eigen::Vector3d* f = ensureSize(forces_, system.node_count);
    if (zero_velocities_.size() < system.node_count)
      zero_velocities_.resize(system.node_count, Eigen::Vector3d::Zero());
    const Eigen::Vector3d* zero = zero_velocities_.data();
    forces.compute(system, system.positions, zero, f);
    for (std::size_t i = 0; i < system.node_count; ++i) {
      if (!system.isFree(i)) continue;
      const Eigen::Vector3d dx = (dt * dt / system.masses[i]) * f[i];
      system.positions[i] += dx;
      // Reported velocity (for collision response and rendering); the next step starts from rest again.
      system.velocities[i] = dx / dt;
    }
  }

 private:
  std::vector<Eigen::Vector3d> forces_;
  std::vector<Eigen::Vector3d> zero_velocities_;
};

}  // namespace

std::unique_ptr<Integrator> makeQuasiStaticEuler() { return std::make_unique<QuasiStaticEuler>(); }

}  // namespace tissue
}  // namespace vrm_sim
