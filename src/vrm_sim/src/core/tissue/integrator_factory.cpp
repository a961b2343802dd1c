#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "integrators_impl.h"

namespace vrm_sim {
namespace tissue {

const std::vector<std::string>& integratorNames() {
  static const std::vector<std::string> names{"explicit_euler", "quasi_static_euler", "rk2",
                                              "implicit_euler", "symplectic_euler",   "xpbd"};
  return names;
}

std::unique_ptr<Integrator> makeIntegrator(const std::string& name, const IntegratorOptions& options) {
  if (name == "explicit_euler") return makeExplicitEuler();
  if (name == "quasi_static_euler") return makeQuasiStaticEuler();
  if (name == "rk2") return makeRk2();
  if (name == "implicit_euler") return makeImplicitEuler(options);
  if (name == "symplectic_euler") return makeSymplecticEuler();
  if (name == "xpbd") return makeXpbd(options);
  std::string known;
  for (const auto& known_name : integratorNames()) known += (known.empty() ? "" : ", ") + known_name;
  throw std::invalid_argument("unknown tissue integrator '" + name + "' (known: " + known + ")");
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
