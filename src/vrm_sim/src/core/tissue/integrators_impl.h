#pragma once
// Factories of the integrator implementations (one per file), used by makeIntegrator().
#include <memory>

#include "vrm_sim/tissue/integrator.h"

namespace vrm_sim {
namespace tissue {

std::unique_ptr<Integrator> makeExplicitEuler();
std::unique_ptr<Integrator> makeQuasiStaticEuler();
std::unique_ptr<Integrator> makeRk2();
std::unique_ptr<Integrator> makeImplicitEuler(const IntegratorOptions& options);
std::unique_ptr<Integrator> makeSymplecticEuler();
std::unique_ptr<Integrator> makeXpbd(const IntegratorOptions& options);

// Grows `buffer` to `size` (allocation only after a topology change; never shrinks).
template <typename T>
T* ensureSize(std::vector<T>& buffer, std::size_t size) {
  if (buffer.size() < size) buffer.resize(size);
  return buffer.data();
}

}  // namespace tissue
}  // namespace vrm_sim
