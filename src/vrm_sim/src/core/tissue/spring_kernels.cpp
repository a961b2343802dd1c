#include "spring_kernels.h"

#include <algorithm>
#include <cmath>

// Built twice, for AVX2 (4 doubles per instruction) and for the baseline x86-64 SSE2, and picked at load time.
// AVX2 without FMA on purpose: FMA contraction would round differently from the baseline and the Eigen loops.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define VRM_TISSUE_KERNEL __attribute__((target_clones("avx2", "default")))
#else
#define VRM_TISSUE_KERNEL
#endif

namespace vrm_sim {
namespace tissue {
namespace kernels {

namespace {

// d_s = x_b − x_a into dx/dy/dz: the gather (scalar), so that the arithmetic after it reads contiguous arrays.
inline void gatherSpringVectors(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs,
                                const Eigen::Vector3d* x, double* __restrict dx, double* __restrict dy,
                                double* __restrict dz) {
  for (std::size_t s = 0; s < spring_count; ++s) {
    const Eigen::Vector3d& a = x[springs[s][0]];
    const Eigen::Vector3d& b = x[springs[s][1]];
    dx[s] = b.x() - a.x();
    dy[s] = b.y() - a.y();
    dz[s] = b.z() - a.z();
  }
}

// Eq. 5.2 on the gathered vectors, in place: the square roots and divisions fill whole SIMD registers. With kEnergy
// also ½ k (|d| − l)² per spring (the same operations for the forces either way, so the same forces).
template <bool kEnergy>
inline void hookeOnVectors(std::size_t spring_count, const double* __restrict stiffnesses,
                           const double* __restrict rest_lengths, double* __restrict fx, double* __restrict fy,
                           double* __restrict fz, double* __restrict energies) {
  for (std::size_t s = 0; s < spring_count; ++s) {
    const double dx = fx[s];
    const double dy = fy[s];
    const double dz = fz[s];
    const double length = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double stretch = length - rest_lengths[s];
    // A zero-length spring has no direction to push along. The division runs on a safe length in every lane and
    // the result is selected afterwards, so the loop has no branch.
    const double scale = stiffnesses[s] * stretch / std::max(length, kMinSpringLength);
    const double used = length < kMinSpringLength ? 0.0 : scale;
    fx[s] = used * dx;
    fy[s] = used * dy;
    fz[s] = used * dz;
    if (kEnergy) energies[s] = 0.5 * stiffnesses[s] * stretch * stretch;
  }
}

// ½ k (|d| − l)² per spring from the gathered vectors, into dx.
inline void energyOnVectors(std::size_t spring_count, const double* __restrict stiffnesses,
                            const double* __restrict rest_lengths, double* __restrict dx, const double* __restrict dy,
                            const double* __restrict dz) {
  for (std::size_t s = 0; s < spring_count; ++s) {
    const double stretch = std::sqrt(dx[s] * dx[s] + dy[s] * dy[s] + dz[s] * dz[s]) - rest_lengths[s];
    dx[s] = 0.5 * stiffnesses[s] * stretch * stretch;
  }
}

}  // namespace

VRM_TISSUE_KERNEL
void hookeForces(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs, const Eigen::Vector3d* x,
                 const double* stiffnesses, const double* rest_lengths, double* fx, double* fy, double* fz) {
  gatherSpringVectors(spring_count, springs, x, fx, fy, fz);
  hookeOnVectors<false>(spring_count, stiffnesses, rest_lengths, fx, fy, fz, nullptr);
}

VRM_TISSUE_KERNEL
void hookeForcesAndEnergy(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs,
                          const Eigen::Vector3d* x, const double* stiffnesses, const double* rest_lengths, double* fx,
                          double* fy, double* fz, double* energies) {
  gatherSpringVectors(spring_count, springs, x, fx, fy, fz);
  hookeOnVectors<true>(spring_count, stiffnesses, rest_lengths, fx, fy, fz, energies);
}

VRM_TISSUE_KERNEL
double springEnergy(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs, const Eigen::Vector3d* x,
                    const double* stiffnesses, const double* rest_lengths, double* dx, double* dy, double* dz) {
  gatherSpringVectors(spring_count, springs, x, dx, dy, dz);
  energyOnVectors(spring_count, stiffnesses, rest_lengths, dx, dy, dz);
  return sumOf(dx, spring_count);
}

VRM_TISSUE_KERNEL
double sumOf(const double* values, std::size_t count) {
  // Four interleaved partial sums: a strict-IEEE reduction into one accumulator would not vectorise.
  double lanes[4] = {0.0, 0.0, 0.0, 0.0};
  const std::size_t blocks = count / 4 * 4;
  for (std::size_t s = 0; s < blocks; s += 4) {
    lanes[0] += values[s];
    lanes[1] += values[s + 1];
    lanes[2] += values[s + 2];
    lanes[3] += values[s + 3];
  }
  double sum = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
  for (std::size_t s = blocks; s < count; ++s) sum += values[s];
  return sum;
}

void scatterSpringForces(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs, const double* fx,
                         const double* fy, const double* fz, Eigen::Vector3d* forces) {
  for (std::size_t s = 0; s < spring_count; ++s) {
    const Eigen::Vector3d f(fx[s], fy[s], fz[s]);
    forces[springs[s][0]] += f;
    forces[springs[s][1]] -= f;
  }
}

double maxStrain(const SystemView& system, const Eigen::Vector3d* x) {
  // |d|² <= bound·l² means |d|/l <= the maximum so far (to 1e-12 relative), so the spring cannot change it. The
  // slack lets the many springs at exactly the maximum (e.g. 1 at rest) skip too.
  constexpr double kMargin = 1.0 + 1e-12;
  double maximum = 0.0;
  double bound = 0.0;
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    const auto& ends = system.springs[s];
    const double rest = system.rest_lengths[s];
    const double length2 = (x[ends[1]] - x[ends[0]]).squaredNorm();
    if (length2 <= bound * (rest * rest)) continue;
    if (rest < kMinSpringLength) continue;
    const double strain = std::sqrt(length2) / rest;
    if (strain > maximum) {
      maximum = strain;
      bound = strain * strain * kMargin;
    }
  }
  return maximum;
}

}  // namespace kernels
}  // namespace tissue
}  // namespace vrm_sim
