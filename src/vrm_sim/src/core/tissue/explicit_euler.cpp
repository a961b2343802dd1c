#include "integrators_impl.h"

namespace vrm_sim {
namespace tissue {
namespace {

// Eq. 5.4: both changes from the state at the start of the step (Δx uses v^s, not the updated velocity).
class ExplicitEuler : public Integrator {
 public:
  const char* name() const override { return "explicit_euler"; }
  void step(const SystemView& system, const ForceModel& forces, double dt) override {
    Eigen::Vector3d* f = ensureSize(forces_, system.node_count);
    forces.compute(system, system.positions, system.velocities, f);
    for (std::size_t i = 0; i < system.node_count; ++i) {
      if (!system.isFree(i)) continue;
      system.positions[i] += dt * system.velocities[i];
      system.velocities[i] += (dt / system.masses[i]) * f[i];
    }
  }

 private:
  std::vector<Eigen::Vector3d> forces_;
};

}  // namespace

std::unique_ptr<Integrator> makeExplicitEuler() { return std::make_unique<ExplicitEuler>(); }

}  // namespace tissue
}  // namespace vrm_sim
