#pragma once
// The inner loops over springs that every step runs (forces, strain measurement), written on raw arrays so the
// compiler can vectorise them. Each kernel gives bit for bit the result of the straightforward Eigen loop it
// replaces (same operations in the same order, no FMA contraction), so the speed-up does not change the physics;
// maxStrain() says where it differs.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "vrm_sim/tissue/system.h"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#include <immintrin.h>
#define VRM_TISSUE_AVX2_GATHER 1
#endif

namespace vrm_sim {
namespace tissue {
namespace kernels {

// Hooke forces of eq. 5.2 per spring: f_s = k_s (|d_s| − l_s)/|d_s| · d_s with d_s = x_b − x_a (zero for springs
// shorter than kMinSpringLength), written structure-of-arrays to fx/fy/fz (spring_count each). No scatter, so the
// square roots and divisions of neighbouring springs run side by side in SIMD lanes.
void hookeForces(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs, const Eigen::Vector3d* x,
                 const double* stiffnesses, const double* rest_lengths, double* fx, double* fy, double* fz);

// hookeForces() (+ hookeForcesAndEnergy()'s energies summed as sumOf() sums them, when energy != nullptr) and
// scatterSpringForces() in one pass, without the per-spring arrays: the same forces, added in the same order. Only
// with AVX2 (false, nothing done, without it: the caller runs the two passes).
bool hookeForcesScattered(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs,
                          const Eigen::Vector3d* x, const double* stiffnesses, const double* rest_lengths,
                          Eigen::Vector3d* forces, double* energy);

// hookeForcesScattered() with |d|, the stretch, the scale k (|d| − l)/|d| and the energies in single precision, eight
// springs per instruction (d = x_b − x_a and the forces k·…·d stay double). Not bit-identical to the double kernels:
// relative errors of about 1e-7 in each spring force. Only with AVX2 (false, nothing done, without it).
bool hookeForcesScatteredSingle(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs,
                                const Eigen::Vector3d* x, const double* stiffnesses, const double* rest_lengths,
                                Eigen::Vector3d* forces, double* energy);

// forces[a] += f_s, forces[b] −= f_s in spring order (the order of the fused loop, hence the same sums).
void scatterSpringForces(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs, const double* fx,
                         const double* fy, const double* fz, Eigen::Vector3d* forces);

// The springs' potential energy Σ ½ k_s (|d_s| − l_s)² for the watchdog's energy balance: like hookeForces() in two
// loops (a scalar gather of d into dx/dy/dz, spring_count each, then the arithmetic on contiguous arrays), summed by
// sumOf(), so it vectorises and gives the same sum on every run.
double springEnergy(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs, const Eigen::Vector3d* x,
                    const double* stiffnesses, const double* rest_lengths, double* dx, double* dy, double* dz);

// hookeForces() (bit for bit the same forces) that also writes each spring's ½ k (|d| − l)² to energies.
void hookeForcesAndEnergy(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs,
                          const Eigen::Vector3d* x, const double* stiffnesses, const double* rest_lengths, double* fx,
                          double* fy, double* fz, double* energies);

// Σ values in four interleaved partial sums (vectorises; a fixed order, so deterministic).
double sumOf(const double* values, std::size_t count);

// Appends to `out`, in spring order, the springs with l >= kMinSpringLength whose |d|² is not <= factor²·l² (beyond
// factor·l, or a non-finite length): what a sweep of squared lengths would find, without a square root.
void springsBeyond(const SystemView& system, double factor, std::vector<std::uint32_t>& out);

// max |d|/l over springs with l >= kMinSpringLength, without a square root per spring: a spring is measured exactly
// (sqrt, division) only when |d|² exceeds the running maximum's bound, which after the first few springs is rare. A
// spring within 5e-13 (relative) of the running maximum may be skipped, so the maximum is exact to that.
double maxStrain(const SystemView& system, const Eigen::Vector3d* x);

#ifdef VRM_TISSUE_AVX2_GATHER
// Explicit AVX2 (issue 40 §3). Every lane runs the operations of the scalar loops in the same order (IEEE sqrt and
// division are exact in SIMD; AVX2 without FMA, nothing contracts), so the results are bit for bit those of the SSE2
// baseline.
bool haveAvx2();

struct SpringQuad {
  __m256d dx, dy, dz;
};

// d = x_b − x_a of four consecutive (a, b) pairs. Offsets of doubles in 64-bit lanes: any node index is in range.
__attribute__((target("avx2"))) inline SpringQuad gatherQuad(const std::array<std::uint32_t, 2>* springs,
                                                             const double* base) {
  // a0 b0 a1 b1 a2 b2 a3 b3 -> (a0 a1 a2 a3 | b0 b1 b2 b3), widened to 64 bits, × 3 doubles per node.
  const __m256i pairs = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(springs));
  const __m256i split = _mm256_permutevar8x32_epi32(pairs, _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7));
  const __m256i a = _mm256_cvtepu32_epi64(_mm256_castsi256_si128(split));
  const __m256i b = _mm256_cvtepu32_epi64(_mm256_extracti128_si256(split, 1));
  const __m256i ia = _mm256_add_epi64(a, _mm256_slli_epi64(a, 1));
  const __m256i ib = _mm256_add_epi64(b, _mm256_slli_epi64(b, 1));
  SpringQuad q;
  q.dx = _mm256_sub_pd(_mm256_i64gather_pd(base, ib, 8), _mm256_i64gather_pd(base, ia, 8));
  q.dy = _mm256_sub_pd(_mm256_i64gather_pd(base + 1, ib, 8), _mm256_i64gather_pd(base + 1, ia, 8));
  q.dz = _mm256_sub_pd(_mm256_i64gather_pd(base + 2, ib, 8), _mm256_i64gather_pd(base + 2, ia, 8));
  return q;
}

// (dx² + dy²) + dz², the order of the scalar loops and of Eigen's squaredNorm().
__attribute__((target("avx2"))) inline __m256d squaredLengths(const SpringQuad& q) {
  return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(q.dx, q.dx), _mm256_mul_pd(q.dy, q.dy)), _mm256_mul_pd(q.dz, q.dz));
}
#endif

}  // namespace kernels
}  // namespace tissue
}  // namespace vrm_sim
