#pragma once
// The grasp-and-pull scene bench_tissue and bench_implicit share: a 5 mm pinned membrane, k = 2 N/m per spring, the
// total mass of the 22×22 thesis mesh (1e-5 kg per node there) at every resolution, grasped at the centre by forceps
// pointing down.
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <vector>

#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace bench {

constexpr double kMembraneSize = 0.005;   // m
constexpr double kSpringStiffness = 2.0;  // N/m
constexpr double kThesisNodeMass = 1e-5;  // kg per node at 22 cells

inline double gridNodeMass(int cells) { return kThesisNodeMass * (22.0 / cells) * (22.0 / cells); }

// The median of `values` (NaN for none): timings on a shared machine, robust against the odd slow step.
inline double medianOf(std::vector<double> values) {
  if (values.empty()) return NAN;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

inline double wallClock() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// CPU time of the calling thread (s): what a computation cost, without the time the thread waited for a core. On a
// shared machine it compares integrators far more steadily than the wall clock (issue 40 §2: instruction counters
// are not available in this VM).
inline double threadCpuClock() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

// Closed forceps pointing down (−z world = +z instrument) with the tip at `tip`: grasps what lies between its jaws.
inline tissue::InstrumentInput forcepsAt(const Eigen::Vector3d& tip) {
  tissue::InstrumentInput forceps;
  forceps.pose.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  forceps.pose.translation() = tip;
  forceps.can_grasp = true;
  forceps.collides = false;
  forceps.jaw_angle = 0.0;
  forceps.jaw_length = 1e-3;
  return forceps;
}

}  // namespace bench
}  // namespace vrm_sim
