#pragma once
// The mass-spring system of thesis §5.1 as seen by the solvers: raw views of the membrane's contiguous arrays
// (MGE §3.3.2) plus the force model F_i = Σ_j H_ij + R_i(v_i) + E_i (eq. 5.1). Solvers never touch the graph, so a
// step is a sweep over arrays; the views are refreshed after every topology change (the array pointers move).

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace mge {
class Membrane;
}

namespace tissue {

struct SystemView {
  std::size_t node_count = 0;
  Eigen::Vector3d* positions = nullptr;
  Eigen::Vector3d* velocities = nullptr;
  const double* masses = nullptr;
  // 1 = not integrated: pinned (MGE fixed flag) or kinematically driven (grasped). Integrators leave such nodes'
  // positions and velocities untouched.
  const std::uint8_t* constrained = nullptr;
  std::size_t spring_count = 0;
  const std::array<std::uint32_t, 2>* springs = nullptr;
  const double* rest_lengths = nullptr;
  const double* stiffnesses = nullptr;

  bool isFree(std::size_t node) const { return constrained == nullptr || constrained[node] == 0; }
};

// A view of `membrane`'s arrays with the given per-node constraint flags (size nodeCount()).
SystemView viewOf(mge::Membrane& membrane, const std::uint8_t* constrained);

// A zero-rest-length spring from a node to a point fixed in space: adhesion of the membrane to the retina
// (scene `adhesion_stiffness`) instead of an infinitely stiff pin.
struct Anchor {
  std::uint32_t node = 0;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double stiffness = 0.0;       // N/m
  double overloaded_for = 0.0;  // s it has carried more than the break force (TissueConfig::adhesion_release_time)
  void transferState(StateArchive& archive) { archive(node)(point)(stiffness)(overloaded_for); }
};

struct ForceParameters {
  double damping = 0.0;                               // N s/m, velocity damping R_i = -c v_i (eq. 5.1)
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();  // m/s^2
  // Pa on the triangles along their normals (corner order), a third of each triangle's force on each corner.
  double pressure = 0.0;
  // Issue 40 §3, opt-in: the Hooke terms' square roots and divisions in single precision (8 lanes), the spring
  // vectors and the forces in double. Changes every result by about 1e-7 relative (BENCHMARKS.md: the error against
  // the double run and the reference); off, the forces are bit for bit the double ones.
  bool single_precision_springs = false;
};

// Springs shorter than this are treated as having no direction (zero-length springs in degenerate input).
constexpr double kMinSpringLength = 1e-12;

class ForceModel {
 public:
  ForceParameters params;
  std::vector<Anchor> anchors;
  // Optional per-node external forces E_i [N] (size node_count or empty).
  std::vector<Eigen::Vector3d> external;
  // Triangles for the pressure term (only read when params.pressure != 0).
  const std::array<std::uint32_t, 3>* triangles = nullptr;
  std::size_t triangle_count = 0;
  // Optional, per triangle: 0 = the pressure does not act on it (fluid that has not reached it). Null: all.
  const std::uint8_t* pressure_mask = nullptr;

  // forces[i] = F_i(x, v) for every node (also constrained ones; callers ignore those).
  void compute(const SystemView& system, const Eigen::Vector3d* x, const Eigen::Vector3d* v,
               Eigen::Vector3d* forces) const;
  // Spring and anchor potential plus gravity potential of the free nodes [J].
  double potentialEnergy(const SystemView& system, const Eigen::Vector3d* x) const;

  // The watchdog's energy balance: the next compute() also sums the springs' potential energy at its x (at almost no
  // cost: the lengths are at hand) into *spring_energy, then disarms. Integrators evaluate the forces at the start
  // state first, so this is the start energy of the integration.
  void captureSpringEnergy(double* spring_energy) const { capture_ = spring_energy; }

  // For an integrator that sums the Hooke terms in its own sweep over the springs: compute() without them, and the
  // armed capture (null if none), which it then fills; taking it disarms it.
  void computeExceptSprings(const SystemView& system, const Eigen::Vector3d* x, const Eigen::Vector3d* v,
                            Eigen::Vector3d* forces) const;
  double* takeSpringEnergyCapture() const { return std::exchange(capture_, nullptr); }

 private:
  // R_i + E_i of eq. 5.1 (damping, gravity, external), and the anchors and the pressure after the Hooke terms.
  void bodyForces(const SystemView& system, const Eigen::Vector3d* v, Eigen::Vector3d* forces) const;
  void addAnchorAndPressureForces(const Eigen::Vector3d* x, Eigen::Vector3d* forces) const;
  // The Hooke terms without AVX2: per-spring forces into spring_forces_, then the scatter.
  void scatterInTwoPasses(const SystemView& system, const Eigen::Vector3d* x, Eigen::Vector3d* forces) const;
  // Per-spring forces of the last two-pass compute() (structure of arrays), kept between steps so a step allocates
  // nothing; grows only after a topology change. One ForceModel therefore serves one thread at a time.
  mutable std::vector<double> spring_forces_;
  mutable double* capture_ = nullptr;
};

double kineticEnergy(const SystemView& system);
// max over springs with a non-zero rest length of |d| / l (1 = at rest).
double maxStrain(const SystemView& system);

}  // namespace tissue
}  // namespace vrm_sim
