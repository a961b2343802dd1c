#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "integrators_impl.h"
#include "vrm_sim/tissue/integrator_choice.h"

namespace vrm_sim {
namespace tissue {

const Registry<IntegratorFactory>& integratorRegistry() {
  static const Registry<IntegratorFactory> registry(
      "tissue integrator",
      {{kAutoIntegrator, [](const IntegratorOptions&) { return makeSymplecticEuler(); },
        "chosen per membrane from its stiffness, masses, damping and dt (integrator_choice.h)"},
       {"explicit_euler", [](const IntegratorOptions&) { return makeExplicitEuler(); }, "explicit Euler (eq. 5.4)"},
       {"quasi_static_euler", [](const IntegratorOptions&) { return makeQuasiStaticEuler(); },
        "quasi-static Euler, velocities reset every step (eq. 5.5)"},
       {"rk2", [](const IntegratorOptions&) { return makeRk2(); }, "second-order Runge-Kutta (midpoint)"},
       {"implicit_euler", makeImplicitEuler,
        "implicit Euler, filtered conjugate gradients (eqs. 5.7-5.10, Baraff & Witkin 1998)"},
       {"symplectic_euler", [](const IntegratorOptions&) { return makeSymplecticEuler(); },
        "semi-implicit Euler (modern baseline)"},
       {"xpbd", makeXpbd, "extended position based dynamics (Macklin et al. 2016, modern baseline)"}});
  return registry;
}

const std::vector<std::string>& integratorNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> proper = integratorRegistry().names();
    proper.erase(std::remove(proper.begin(), proper.end(), std::string(kAutoIntegrator)), proper.end());
    return proper;
  }();
  return names;
}

std::unique_ptr<Integrator> makeIntegrator(const std::string& name, const IntegratorOptions& options) {
  return integratorRegistry().at(name).make(options);
}

double explicitStabilityBound(const SystemView& system, const ForceModel& forces) {
  double max_stiffness = 0.0;
  for (std::size_t s = 0; s < system.spring_count; ++s) max_stiffness = std::max(max_stiffness, system.stiffnesses[s]);
  for (const Anchor& anchor : forces.anchors) max_stiffness = std::max(max_stiffness, anchor.stiffness);
  double min_mass = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < system.node_count; ++i) {
    if (system.isFree(i)) min_mass = std::min(min_mass, system.masses[i]);
  }
  if (max_stiffness <= 0.0 || !std::isfinite(min_mass)) return std::numeric_limits<double>::infinity();
  return 0.4 * M_PI * std::sqrt(min_mass / max_stiffness);
}

}  // namespace tissue
}  // namespace vrm_sim
