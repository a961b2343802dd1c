#include <algorithm>
#include <cmath>

#include "spring_kernels.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/system.h"

namespace vrm_sim {
namespace tissue {

SystemView viewOf(mge::Membrane& membrane, const std::uint8_t* constrained) {
  SystemView view;
  view.node_count = membrane.nodeCount();
  view.positions = membrane.positions();
  view.velocities = membrane.velocities();
  view.masses = membrane.masses();
  view.constrained = constrained;
  view.spring_count = membrane.springCount();
  view.springs = membrane.springNodeSlots();
  view.rest_lengths = membrane.restLengths();
  view.stiffnesses = membrane.stiffnesses();
  return view;
}

void ForceModel::scatterInTwoPasses(const SystemView& system, const Eigen::Vector3d* x, Eigen::Vector3d* forces) const {
  const std::size_t m = system.spring_count;
  if (spring_forces_.size() < 4 * m) spring_forces_.resize(4 * m);
  double* f = spring_forces_.data();
  if (capture_ != nullptr) {
    kernels::hookeForcesAndEnergy(m, system.springs, x, system.stiffnesses, system.rest_lengths, f, f + m, f + 2 * m,
                                  f + 3 * m);
    *capture_ = kernels::sumOf(f + 3 * m, m);
    capture_ = nullptr;
  } else {
    kernels::hookeForces(m, system.springs, x, system.stiffnesses, system.rest_lengths, f, f + m, f + 2 * m);
  }
  kernels::scatterSpringForces(m, system.springs, f, f + m, f + 2 * m, forces);
}

void ForceModel::bodyForces(const SystemView& system, const Eigen::Vector3d* v, Eigen::Vector3d* forces) const {
  const std::size_t n = system.node_count;
  for (std::size_t i = 0; i < n; ++i) {
    forces[i] = system.masses[i] * params.gravity - params.damping * v[i];
  }
  if (!external.empty()) {
    for (std::size_t i = 0; i < n; ++i) forces[i] += external[i];
  }
}

void ForceModel::addAnchorAndPressureForces(const Eigen::Vector3d* x, Eigen::Vector3d* forces) const {
  for (const Anchor& anchor : anchors) {
    forces[anchor.node] += anchor.stiffness * (anchor.point - x[anchor.node]);
  }
  if (params.pressure != 0.0 && triangles != nullptr) {
    for (std::size_t t = 0; t < triangle_count; ++t) {
      if (pressure_mask != nullptr && pressure_mask[t] == 0) continue;
      const auto& c = triangles[t];
      // |cross| = 2·area, so p·cross/6 is a third of the triangle's pressure force.
      const Eigen::Vector3d f = (params.pressure / 6.0) * (x[c[1]] - x[c[0]]).cross(x[c[2]] - x[c[0]]);
      forces[c[0]] += f;
      forces[c[1]] += f;
      forces[c[2]] += f;
    }
  }
}

void ForceModel::compute(const SystemView& system, const Eigen::Vector3d* x, const Eigen::Vector3d* v,
                         Eigen::Vector3d* forces) const {
  // R_i + E_i of eq. 5.1 first, then the Hooke terms H_ij (eq. 5.2) in spring order.
  bodyForces(system, v, forces);
  const std::size_t m = system.spring_count;
  // One vectorised pass with the scatter fused where AVX2 is there; else two sweeps: the per-spring forces vectorise
  // (no scatter), the scatter then only adds. The same forces either way.
  const bool fused = params.single_precision_springs
                         ? kernels::hookeForcesScatteredSingle(m, system.springs, x, system.stiffnesses,
                                                               system.rest_lengths, forces, capture_)
                         : kernels::hookeForcesScattered(m, system.springs, x, system.stiffnesses, system.rest_lengths,
                                                         forces, capture_);
  if (fused) {
    capture_ = nullptr;
  } else {
    scatterInTwoPasses(system, x, forces);
  }
  addAnchorAndPressureForces(x, forces);
}

void ForceModel::computeExceptSprings(const SystemView& system, const Eigen::Vector3d* x, const Eigen::Vector3d* v,
                                      Eigen::Vector3d* forces) const {
  bodyForces(system, v, forces);
  addAnchorAndPressureForces(x, forces);
}

double ForceModel::potentialEnergy(const SystemView& system, const Eigen::Vector3d* x) const {
  double energy = 0.0;
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    const auto& ends = system.springs[s];
    const double stretch = (x[ends[1]] - x[ends[0]]).norm() - system.rest_lengths[s];
    energy += 0.5 * system.stiffnesses[s] * stretch * stretch;
  }
  for (const Anchor& anchor : anchors) {
    energy += 0.5 * anchor.stiffness * (x[anchor.node] - anchor.point).squaredNorm();
  }
  for (std::size_t i = 0; i < system.node_count; ++i) {
    if (system.isFree(i)) energy -= system.masses[i] * params.gravity.dot(x[i]);
  }
  return energy;
}

double kineticEnergy(const SystemView& system) {
  double energy = 0.0;
  for (std::size_t i = 0; i < system.node_count; ++i) {
    if (system.isFree(i)) energy += 0.5 * system.masses[i] * system.velocities[i].squaredNorm();
  }
  return energy;
}

double maxStrain(const SystemView& system) { return kernels::maxStrain(system, system.positions); }

}  // namespace tissue
}  // namespace vrm_sim
