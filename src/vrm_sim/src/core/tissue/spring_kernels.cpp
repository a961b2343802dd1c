#include "spring_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstring>

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

#ifdef VRM_TISSUE_AVX2_GATHER
// The gather and the arithmetic in one pass, four springs per iteration (gatherQuad()), so the spring vectors never
// go through memory; the lanes compute what the scalar loops above compute (see spring_kernels.h).
template <bool kEnergy>
__attribute__((target("avx2"))) void hookeAvx2(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs,
                                               const Eigen::Vector3d* x, const double* __restrict stiffnesses,
                                               const double* __restrict rest_lengths, double* __restrict fx,
                                               double* __restrict fy, double* __restrict fz,
                                               double* __restrict energies) {
  const double* base = x->data();
  const __m256d min_length = _mm256_set1_pd(kMinSpringLength);
  const __m256d half = _mm256_set1_pd(0.5);
  const std::size_t blocks = spring_count / 4 * 4;
  for (std::size_t s = 0; s < blocks; s += 4) {
    const SpringQuad q = gatherQuad(springs + s, base);
    const __m256d length = _mm256_sqrt_pd(squaredLengths(q));
    const __m256d k = _mm256_loadu_pd(stiffnesses + s);
    const __m256d stretch = _mm256_sub_pd(length, _mm256_loadu_pd(rest_lengths + s));
    // std::max(length, kMinSpringLength) with its NaN behaviour (NaN stays NaN): max_pd returns its second operand
    // unless the first is greater.
    const __m256d scale = _mm256_div_pd(_mm256_mul_pd(k, stretch), _mm256_max_pd(min_length, length));
    const __m256d used = _mm256_blendv_pd(scale, _mm256_setzero_pd(), _mm256_cmp_pd(length, min_length, _CMP_LT_OQ));
    _mm256_storeu_pd(fx + s, _mm256_mul_pd(used, q.dx));
    _mm256_storeu_pd(fy + s, _mm256_mul_pd(used, q.dy));
    _mm256_storeu_pd(fz + s, _mm256_mul_pd(used, q.dz));
    if (kEnergy) {
      _mm256_storeu_pd(energies + s, _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(half, k), stretch), stretch));
    }
  }
  const std::size_t rest = spring_count - blocks;
  gatherSpringVectors(rest, springs + blocks, x, fx + blocks, fy + blocks, fz + blocks);
  hookeOnVectors<kEnergy>(rest, stiffnesses + blocks, rest_lengths + blocks, fx + blocks, fy + blocks, fz + blocks,
                          kEnergy ? energies + blocks : nullptr);
}

// hookeAvx2() with the scatter in the same loop (issue 40 §3, fused): each quad's forces go from registers to the
// nodes, spring by spring in spring order — the additions scatterSpringForces() makes, in its order — and the
// energies into sumOf()'s four partial sums. No per-spring arrays at all.
__attribute__((target("avx2"))) void hookeScatterAvx2(std::size_t spring_count,
                                                      const std::array<std::uint32_t, 2>* springs,
                                                      const Eigen::Vector3d* x, const double* __restrict stiffnesses,
                                                      const double* __restrict rest_lengths,
                                                      Eigen::Vector3d* __restrict forces, double* energy) {
  const double* base = x->data();
  const __m256d min_length = _mm256_set1_pd(kMinSpringLength);
  const __m256d half = _mm256_set1_pd(0.5);
  __m256d lanes = _mm256_setzero_pd();
  alignas(32) double f[3][4];
  const std::size_t blocks = spring_count / 4 * 4;
  for (std::size_t s = 0; s < blocks; s += 4) {
    const SpringQuad q = gatherQuad(springs + s, base);
    const __m256d length = _mm256_sqrt_pd(squaredLengths(q));
    const __m256d k = _mm256_loadu_pd(stiffnesses + s);
    const __m256d stretch = _mm256_sub_pd(length, _mm256_loadu_pd(rest_lengths + s));
    const __m256d scale = _mm256_div_pd(_mm256_mul_pd(k, stretch), _mm256_max_pd(min_length, length));
    const __m256d used = _mm256_blendv_pd(scale, _mm256_setzero_pd(), _mm256_cmp_pd(length, min_length, _CMP_LT_OQ));
    _mm256_store_pd(f[0], _mm256_mul_pd(used, q.dx));
    _mm256_store_pd(f[1], _mm256_mul_pd(used, q.dy));
    _mm256_store_pd(f[2], _mm256_mul_pd(used, q.dz));
    if (energy != nullptr) {
      lanes = _mm256_add_pd(lanes, _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(half, k), stretch), stretch));
    }
    for (int j = 0; j < 4; ++j) {
      const Eigen::Vector3d fs(f[0][j], f[1][j], f[2][j]);
      forces[springs[s + j][0]] += fs;
      forces[springs[s + j][1]] -= fs;
    }
  }
  double lane[4];
  _mm256_storeu_pd(lane, lanes);
  double sum = (lane[0] + lane[1]) + (lane[2] + lane[3]);
  for (std::size_t s = blocks; s < spring_count; ++s) {
    double fx, fy, fz, e;
    gatherSpringVectors(1, springs + s, x, &fx, &fy, &fz);
    hookeOnVectors<true>(1, stiffnesses + s, rest_lengths + s, &fx, &fy, &fz, &e);
    const Eigen::Vector3d fs(fx, fy, fz);
    forces[springs[s][0]] += fs;
    forces[springs[s][1]] -= fs;
    sum += e;
  }
  if (energy != nullptr) *energy = sum;
}

// Two quads of doubles rounded into one register of eight floats (low quad first).
__attribute__((target("avx2"))) inline __m256 pack(__m256d low, __m256d high) {
  return _mm256_set_m128(_mm256_cvtpd_ps(high), _mm256_cvtpd_ps(low));
}

// hookeScatterAvx2() with the square roots, divisions and energies in single precision: two quads of springs
// packed into one register of eight floats (the throughput of vsqrtps/vdivps per value is twice that of the double
// forms), the spring vectors gathered and subtracted in double first, so only |d|, l and k are rounded to float.
__attribute__((target("avx2"))) void hookeScatterSingleAvx2(std::size_t spring_count,
                                                            const std::array<std::uint32_t, 2>* springs,
                                                            const Eigen::Vector3d* x,
                                                            const double* __restrict stiffnesses,
                                                            const double* __restrict rest_lengths,
                                                            Eigen::Vector3d* __restrict forces, double* energy) {
  const double* base = x->data();
  const __m256 min_length = _mm256_set1_ps(static_cast<float>(kMinSpringLength));
  const __m256 half = _mm256_set1_ps(0.5f);
  __m256d lanes = _mm256_setzero_pd();
  alignas(32) double f[3][8];
  const std::size_t blocks = spring_count / 8 * 8;
  for (std::size_t s = 0; s < blocks; s += 8) {
    const SpringQuad q0 = gatherQuad(springs + s, base);
    const SpringQuad q1 = gatherQuad(springs + s + 4, base);
    const __m256 dx = pack(q0.dx, q1.dx), dy = pack(q0.dy, q1.dy), dz = pack(q0.dz, q1.dz);
    const __m256 length = _mm256_sqrt_ps(
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)), _mm256_mul_ps(dz, dz)));
    const __m256 k = pack(_mm256_loadu_pd(stiffnesses + s), _mm256_loadu_pd(stiffnesses + s + 4));
    const __m256 stretch =
        _mm256_sub_ps(length, pack(_mm256_loadu_pd(rest_lengths + s), _mm256_loadu_pd(rest_lengths + s + 4)));
    const __m256 scale = _mm256_div_ps(_mm256_mul_ps(k, stretch), _mm256_max_ps(min_length, length));
    const __m256 used = _mm256_blendv_ps(scale, _mm256_setzero_ps(), _mm256_cmp_ps(length, min_length, _CMP_LT_OQ));
    const __m256d used0 = _mm256_cvtps_pd(_mm256_castps256_ps128(used));
    const __m256d used1 = _mm256_cvtps_pd(_mm256_extractf128_ps(used, 1));
    _mm256_store_pd(f[0], _mm256_mul_pd(used0, q0.dx));
    _mm256_store_pd(f[0] + 4, _mm256_mul_pd(used1, q1.dx));
    _mm256_store_pd(f[1], _mm256_mul_pd(used0, q0.dy));
    _mm256_store_pd(f[1] + 4, _mm256_mul_pd(used1, q1.dy));
    _mm256_store_pd(f[2], _mm256_mul_pd(used0, q0.dz));
    _mm256_store_pd(f[2] + 4, _mm256_mul_pd(used1, q1.dz));
    if (energy != nullptr) {
      const __m256 e = _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(half, k), stretch), stretch);
      lanes = _mm256_add_pd(lanes, _mm256_add_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(e)),
                                                 _mm256_cvtps_pd(_mm256_extractf128_ps(e, 1))));
    }
    for (int j = 0; j < 8; ++j) {
      const Eigen::Vector3d fs(f[0][j], f[1][j], f[2][j]);
      forces[springs[s + j][0]] += fs;
      forces[springs[s + j][1]] -= fs;
    }
  }
  double lane[4];
  _mm256_storeu_pd(lane, lanes);
  double sum = (lane[0] + lane[1]) + (lane[2] + lane[3]);
  for (std::size_t s = blocks; s < spring_count; ++s) {
    double fx, fy, fz, e;
    gatherSpringVectors(1, springs + s, x, &fx, &fy, &fz);
    hookeOnVectors<true>(1, stiffnesses + s, rest_lengths + s, &fx, &fy, &fz, &e);
    const Eigen::Vector3d fs(fx, fy, fz);
    forces[springs[s][0]] += fs;
    forces[springs[s][1]] -= fs;
    sum += e;
  }
  if (energy != nullptr) *energy = sum;
}

// Σ ½ k (|d| − l)² in the four interleaved partial sums of sumOf() (lane j = springs j, j + 4, ...).
__attribute__((target("avx2"))) double springEnergyAvx2(std::size_t spring_count,
                                                        const std::array<std::uint32_t, 2>* springs,
                                                        const Eigen::Vector3d* x, const double* stiffnesses,
                                                        const double* rest_lengths) {
  const double* base = x->data();
  const __m256d half = _mm256_set1_pd(0.5);
  __m256d lanes = _mm256_setzero_pd();
  const std::size_t blocks = spring_count / 4 * 4;
  for (std::size_t s = 0; s < blocks; s += 4) {
    const SpringQuad q = gatherQuad(springs + s, base);
    const __m256d stretch = _mm256_sub_pd(_mm256_sqrt_pd(squaredLengths(q)), _mm256_loadu_pd(rest_lengths + s));
    const __m256d energy =
        _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(half, _mm256_loadu_pd(stiffnesses + s)), stretch), stretch);
    lanes = _mm256_add_pd(lanes, energy);
  }
  double lane[4];
  _mm256_storeu_pd(lane, lanes);
  double sum = (lane[0] + lane[1]) + (lane[2] + lane[3]);
  for (std::size_t s = blocks; s < spring_count; ++s) {
    const auto& ends = springs[s];
    const double dx = x[ends[1]].x() - x[ends[0]].x();
    const double dy = x[ends[1]].y() - x[ends[0]].y();
    const double dz = x[ends[1]].z() - x[ends[0]].z();
    const double stretch = std::sqrt(dx * dx + dy * dy + dz * dz) - rest_lengths[s];
    sum += 0.5 * stiffnesses[s] * stretch * stretch;
  }
  return sum;
}

// Appends to `out`, in spring order, every spring with rest >= kMinSpringLength and !(|d|² <= factor²·l²) (a
// non-finite length counts).
__attribute__((target("avx2"))) void springsBeyondAvx2(std::size_t spring_count,
                                                       const std::array<std::uint32_t, 2>* springs,
                                                       const Eigen::Vector3d* x, const double* rest_lengths,
                                                       double factor2, std::vector<std::uint32_t>& out) {
  const double* base = x->data();
  const __m256d f2 = _mm256_set1_pd(factor2);
  const __m256d min_length = _mm256_set1_pd(kMinSpringLength);
  const std::size_t blocks = spring_count / 4 * 4;
  for (std::size_t s = 0; s < blocks; s += 4) {
    const SpringQuad q = gatherQuad(springs + s, base);
    const __m256d rest = _mm256_loadu_pd(rest_lengths + s);
    const __m256d within = _mm256_cmp_pd(squaredLengths(q), _mm256_mul_pd(f2, _mm256_mul_pd(rest, rest)), _CMP_LE_OQ);
    const __m256d measurable = _mm256_cmp_pd(rest, min_length, _CMP_GE_OQ);
    int mask = _mm256_movemask_pd(_mm256_andnot_pd(within, measurable));
    while (mask != 0) {
      const int lane = __builtin_ctz(static_cast<unsigned>(mask));
      out.push_back(static_cast<std::uint32_t>(s + lane));
      mask &= mask - 1;
    }
  }
  for (std::size_t s = blocks; s < spring_count; ++s) {
    const double rest = rest_lengths[s];
    const double length2 = (x[springs[s][1]] - x[springs[s][0]]).squaredNorm();
    if (!(length2 <= factor2 * (rest * rest)) && rest >= kMinSpringLength) out.push_back(static_cast<std::uint32_t>(s));
  }
}
#endif

}  // namespace

VRM_TISSUE_KERNEL
void hookeForces(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs, const Eigen::Vector3d* x,
                 const double* stiffnesses, const double* rest_lengths, double* fx, double* fy, double* fz) {
#ifdef VRM_TISSUE_AVX2_GATHER
  if (haveAvx2()) return hookeAvx2<false>(spring_count, springs, x, stiffnesses, rest_lengths, fx, fy, fz, nullptr);
#endif
  gatherSpringVectors(spring_count, springs, x, fx, fy, fz);
  hookeOnVectors<false>(spring_count, stiffnesses, rest_lengths, fx, fy, fz, nullptr);
}

VRM_TISSUE_KERNEL
void hookeForcesAndEnergy(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs,
                          const Eigen::Vector3d* x, const double* stiffnesses, const double* rest_lengths, double* fx,
                          double* fy, double* fz, double* energies) {
#ifdef VRM_TISSUE_AVX2_GATHER
  if (haveAvx2()) return hookeAvx2<true>(spring_count, springs, x, stiffnesses, rest_lengths, fx, fy, fz, energies);
#endif
  gatherSpringVectors(spring_count, springs, x, fx, fy, fz);
  hookeOnVectors<true>(spring_count, stiffnesses, rest_lengths, fx, fy, fz, energies);
}

VRM_TISSUE_KERNEL
double springEnergy(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs, const Eigen::Vector3d* x,
                    const double* stiffnesses, const double* rest_lengths, double* dx, double* dy, double* dz) {
#ifdef VRM_TISSUE_AVX2_GATHER
  if (haveAvx2()) return springEnergyAvx2(spring_count, springs, x, stiffnesses, rest_lengths);
#endif
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

#ifdef VRM_TISSUE_AVX2_GATHER
bool haveAvx2() {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  return avx2;
}
#endif

bool hookeForcesScattered(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs,
                          const Eigen::Vector3d* x, const double* stiffnesses, const double* rest_lengths,
                          Eigen::Vector3d* forces, double* energy) {
#ifdef VRM_TISSUE_AVX2_GATHER
  if (haveAvx2()) {
    hookeScatterAvx2(spring_count, springs, x, stiffnesses, rest_lengths, forces, energy);
    return true;
  }
#endif
  return false;
}

bool hookeForcesScatteredSingle(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs,
                                const Eigen::Vector3d* x, const double* stiffnesses, const double* rest_lengths,
                                Eigen::Vector3d* forces, double* energy) {
#ifdef VRM_TISSUE_AVX2_GATHER
  if (haveAvx2()) {
    hookeScatterSingleAvx2(spring_count, springs, x, stiffnesses, rest_lengths, forces, energy);
    return true;
  }
#endif
  return false;
}

void scatterSpringForces(std::size_t spring_count, const std::array<std::uint32_t, 2>* springs, const double* fx,
                         const double* fy, const double* fz, Eigen::Vector3d* forces) {
  for (std::size_t s = 0; s < spring_count; ++s) {
    const Eigen::Vector3d f(fx[s], fy[s], fz[s]);
    forces[springs[s][0]] += f;
    forces[springs[s][1]] -= f;
  }
}

void springsBeyond(const SystemView& system, double factor, std::vector<std::uint32_t>& out) {
  const double factor2 = factor * factor;
#ifdef VRM_TISSUE_AVX2_GATHER
  if (haveAvx2()) {
    springsBeyondAvx2(system.spring_count, system.springs, system.positions, system.rest_lengths, factor2, out);
    return;
  }
#endif
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    const double rest = system.rest_lengths[s];
    const auto& ends = system.springs[s];
    const double length2 = (system.positions[ends[1]] - system.positions[ends[0]]).squaredNorm();
    if (!(length2 <= factor2 * (rest * rest)) && rest >= kMinSpringLength) out.push_back(static_cast<std::uint32_t>(s));
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
