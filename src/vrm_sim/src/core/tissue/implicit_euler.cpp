#include <Eigen/Core>
#include <cmath>

#include "integrators_impl.h"
#include "spring_kernels.h"

namespace vrm_sim {
namespace tissue {
namespace {

// Implicit (backward) Euler, eqs. 5.7-5.10, linearised as in Baraff & Witkin (1998):
//   (M + Δt·c·I + Δt²·S) Δv = Δt·(F⁰ − Δt·S v⁰),   x += Δt (v⁰ + Δv)
// with S = −∂F/∂x, solved by Jacobi-preconditioned conjugate gradients, matrix-free. Per step:
//  1. one pass over the springs computes each spring's 3×3 block B_s = Δt²k(t·I + (1 − t)·uuᵀ) (t = max(0,
//     1 − l/|d|)) as its direction u and two scalars, packs them with the spring's ends into one 56-byte record
//     (read by every CG sweep), scatters the blocks' diagonals into the Jacobi preconditioner and forms Δt²·S v⁰
//     for the right-hand side;
//  2. each CG iteration is one sweep over the packed springs, t_s = B_s (p_a − p_b) added to a and subtracted from b,
//     on top of the per-node term (M + Δt·c + Δt²·k_anchor)·p. The sweep also accumulates p·Ap as
//     Σ_i m'_i|p_i|² + Σ_s w_sᵀB_s w_s (w_s = p_a − p_b), so an iteration touches the node vectors in two loops.
// The CG vectors are 4 doubles per node (the 4th is 0), so a node is one 256-bit load/store with AVX2; with that
// and the packed records a sweep took ~0.6× the time of the previous 3-double/separate-array form in a micro
// benchmark at 10k nodes (30k springs). Tried there and not faster: gather-only products (CSR/ELL rows per node,
// no scatter), single-precision records, interleaved spring order (to break store-to-load chains), 4 springs per
// AVX2 register with transposes — the sweep is bound by its per-spring gathers and read-modify-write scatters.
// Constrained nodes (pinned or grasped) are handled by the filtered CG of Baraff & Witkin §5.3: their Δv
// components are projected to zero in every iterate (zero preconditioner entries keep p and Δv at zero there, the
// residual is filtered), which is the "infinite mass" of the thesis without ill-conditioning. The transverse part
// of a compressed spring's block is dropped (clamped at zero) so the system stays positive definite — CG needs that,
// and it only removes buckling stiffness. A step allocates nothing once the buffers have their size.

// Built for AVX2 and the baseline and picked at load time, like spring_kernels.cpp. The two builds may round
// differently (vector vs scalar sums); the implicit solve is iterative and not part of any bit-exact contract.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define VRM_IMPLICIT_KERNEL __attribute__((target_clones("avx2", "default")))
#else
#define VRM_IMPLICIT_KERNEL
#endif

// One node's vector (x, y, z, 0) in a GCC/Clang vector register; unaligned, aliases double.
typedef double Vec4 __attribute__((vector_size(32), aligned(8), may_alias));

inline Vec4& at(double* base, std::size_t i) { return *reinterpret_cast<Vec4*>(base + 4 * i); }
inline const Vec4& at(const double* base, std::size_t i) { return *reinterpret_cast<const Vec4*>(base + 4 * i); }
inline double sum3(const Vec4& v) { return v[0] + v[1] + v[2]; }

struct PackedSpring {
  double u[4];  // direction, u[3] = 0
  double isotropic, axial;
  std::uint32_t a, b;
};

// q += Σ_s ±B_s (in_a − in_b); returns Σ_s w_sᵀ B_s w_s.
inline double addSpringProduct(std::size_t m, const PackedSpring* springs, const double* in, double* out) {
  Vec4 energy = {0.0, 0.0, 0.0, 0.0};  // w_sᵀ t_s summed per lane, one horizontal sum at the end
  for (std::size_t s = 0; s < m; ++s) {
    const PackedSpring& spring = springs[s];
    const Vec4 u = *reinterpret_cast<const Vec4*>(spring.u);
    const Vec4 w = at(in, spring.a) - at(in, spring.b);
    const double along = sum3(u * w);
    const double axial_along = spring.axial * along;
    const Vec4 t = spring.isotropic * w + axial_along * u;
    energy += w * t;
    at(out, spring.a) += t;
    at(out, spring.b) -= t;
  }
  return sum3(energy);
}

// Computes and packs the blocks B_s = scale·k(t·I + (1 − t)·uuᵀ) from the positions (t = max(0, 1 − l/|d|), zero
// block for springs shorter than kMinSpringLength), adds their diagonals to `diagonal` and Σ_s ±B_s (in_a − in_b)
// to `out`. One pass: at 10k nodes the step is limited by memory traffic, not by the square roots.
VRM_IMPLICIT_KERNEL
void packBlocks(std::size_t m, const std::array<std::uint32_t, 2>* ends, const Eigen::Vector3d* x,
                const double* stiffnesses, const double* rest_lengths, double scale, PackedSpring* packed,
                const double* in, double* diagonal, double* out) {
  for (std::size_t s = 0; s < m; ++s) {
    const std::uint32_t a = ends[s][0];
    const std::uint32_t b = ends[s][1];
    const Vec4 d = Vec4{x[b].x(), x[b].y(), x[b].z(), 0.0} - Vec4{x[a].x(), x[a].y(), x[a].z(), 0.0};
    const double length = std::sqrt(sum3(d * d));
    const bool degenerate = length < kMinSpringLength;
    const double inverse_length = 1.0 / (degenerate ? kMinSpringLength : length);
    const double transverse = std::max(0.0, 1.0 - rest_lengths[s] * inverse_length);
    const double k = degenerate ? 0.0 : scale * stiffnesses[s];
    const Vec4 u = d * (degenerate ? 0.0 : inverse_length);
    PackedSpring& spring = packed[s];
    *reinterpret_cast<Vec4*>(spring.u) = u;
    spring.isotropic = k * transverse;
    spring.axial = k * (1.0 - transverse);
    spring.a = a;
    spring.b = b;
    Vec4 block_diagonal = spring.isotropic + spring.axial * (u * u);
    block_diagonal[3] = 0.0;
    at(diagonal, a) += block_diagonal;
    at(diagonal, b) += block_diagonal;
    const Vec4 w = at(in, a) - at(in, b);
    const double axial_along = spring.axial * sum3(u * w);
    const Vec4 t = spring.isotropic * w + axial_along * u;
    at(out, a) += t;
    at(out, b) -= t;
  }
}

// Filtered Jacobi-preconditioned CG from Δv = 0. On entry r = b (filtered), inverse_diagonal filtered (0 on
// constrained nodes and in the 4th lane). Returns the iterations done; dv holds the solution.
VRM_IMPLICIT_KERNEL
int solve(std::size_t n, std::size_t m, const PackedSpring* springs, const double* node_term, const double* free_mask,
          const double* inverse_diagonal, double* r, double* p, double* q, double* dv, int max_iterations,
          double tolerance) {
  constexpr Vec4 kZero = {0.0, 0.0, 0.0, 0.0};
  // Dot products are summed per lane (4th lane 0) with one horizontal sum per loop.
  Vec4 b_norm2_lanes = kZero;
  Vec4 rz_lanes = kZero;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec4 ri = at(r, i);
    const Vec4 zi = ri * at(inverse_diagonal, i);
    at(p, i) = zi;
    at(dv, i) = kZero;
    b_norm2_lanes += ri * ri;
    rz_lanes += ri * zi;
  }
  const double b_norm2 = sum3(b_norm2_lanes);
  double rz = sum3(rz_lanes);
  const double tolerance2 = tolerance * tolerance * b_norm2;
  int iterations = 0;
  double r_norm2 = b_norm2;
  double beta = 0.0;
  while (iterations < max_iterations && r_norm2 > tolerance2 && b_norm2 > 0.0) {
    // p = z + β·p (on the first iteration p already holds z), q = A·p, pq = p·A·p.
    Vec4 pq_lanes = kZero;
    if (iterations > 0) {
      for (std::size_t i = 0; i < n; ++i) {
        const Vec4 pi = at(r, i) * at(inverse_diagonal, i) + beta * at(p, i);
        at(p, i) = pi;
        at(q, i) = node_term[i] * pi;
        pq_lanes += pi * at(q, i);
      }
    } else {
      for (std::size_t i = 0; i < n; ++i) {
        const Vec4 pi = at(p, i);
        at(q, i) = node_term[i] * pi;
        pq_lanes += pi * at(q, i);
      }
    }
    const double pq = sum3(pq_lanes) + addSpringProduct(m, springs, p, q);
    if (!(pq > 0.0)) break;
    const double alpha = rz / pq;
    Vec4 rz_new_lanes = kZero;
    Vec4 r_norm2_lanes = kZero;
    for (std::size_t i = 0; i < n; ++i) {
      at(dv, i) += alpha * at(p, i);
      const Vec4 ri = at(r, i) - (alpha * free_mask[i]) * at(q, i);
      at(r, i) = ri;
      rz_new_lanes += ri * ri * at(inverse_diagonal, i);
      r_norm2_lanes += ri * ri;
    }
    const double rz_new = sum3(rz_new_lanes);
    r_norm2 = sum3(r_norm2_lanes);
    beta = rz_new / rz;
    rz = rz_new;
    ++iterations;
  }
  return iterations;
}

// The per-node terms: p = v⁰, q = anchor_term·v⁰ (the anchors' part of h²·S v⁰), node_term = m + h·c + anchor_term
// (node_term holds h²·k_anchor on entry), the diagonal initialised to node_term, free_mask = 1 on free nodes.
VRM_IMPLICIT_KERNEL
void prepareNodes(std::size_t n, const Eigen::Vector3d* velocities, const double* masses,
                  const std::uint8_t* constrained, double mass_offset, double* node_term, double* free_mask, double* p,
                  double* q, double* diagonal) {
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& v = velocities[i];
    const Vec4 vi = {v.x(), v.y(), v.z(), 0.0};
    at(p, i) = vi;
    at(q, i) = node_term[i] * vi;
    const double term = node_term[i] + masses[i] + mass_offset;
    node_term[i] = term;
    at(diagonal, i) = Vec4{term, term, term, 0.0};
    free_mask[i] = constrained == nullptr || constrained[i] == 0 ? 1.0 : 0.0;
  }
}

// r = b = h·F⁰ − h²·S v⁰ (q holds h²·S v⁰) on free nodes; the diagonal becomes the filtered Jacobi preconditioner.
VRM_IMPLICIT_KERNEL
void rightHandSide(std::size_t n, const Eigen::Vector3d* forces, double h, const double* free_mask, const double* q,
                   double* inverse_diagonal, double* r) {
  for (std::size_t i = 0; i < n; ++i) {
    const Vec4 d = at(inverse_diagonal, i);
    const double mask = free_mask[i];
    at(inverse_diagonal, i) = Vec4{mask / d[0], mask / d[1], mask / d[2], 0.0};
    const Eigen::Vector3d& f = forces[i];
    at(r, i) = mask * (h * Vec4{f.x(), f.y(), f.z(), 0.0} - at(q, i));
  }
}

// v += Δv, x += h·v on free nodes.
VRM_IMPLICIT_KERNEL
void applyStep(std::size_t n, const double* free_mask, const double* dv, double h, Eigen::Vector3d* velocities,
               Eigen::Vector3d* positions) {
  for (std::size_t i = 0; i < n; ++i) {
    if (free_mask[i] == 0.0) continue;
    const Vec4 dvi = at(dv, i);
    Eigen::Vector3d& v = velocities[i];
    v += Eigen::Vector3d(dvi[0], dvi[1], dvi[2]);
    positions[i] += h * v;
  }
}

class ImplicitEuler : public Integrator {
 public:
  explicit ImplicitEuler(const IntegratorOptions& options) : options_(options) {}
  const char* name() const override { return "implicit_euler"; }
  int lastIterations() const override { return iterations_; }

  void step(const SystemView& system, const ForceModel& forces, double dt) override {
    const std::size_t n = system.node_count;
    const std::size_t m = system.spring_count;
    Eigen::Vector3d* f = ensureSize(forces_, n);
    double* r = ensureSize(r_, 4 * n);
    double* p = ensureSize(p_, 4 * n);
    double* q = ensureSize(q_, 4 * n);
    double* dv = ensureSize(dv_, 4 * n);
    double* inverse_diagonal = ensureSize(inverse_diagonal_, 4 * n);
    double* node_term = ensureSize(node_term_, n);
    double* free_mask = ensureSize(free_mask_, n);
    PackedSpring* packed = ensureSize(packed_, m);
    const double h = dt;
    const double h2 = dt * dt;

    forces.compute(system, system.positions, system.velocities, f);
    for (std::size_t i = 0; i < n; ++i) node_term[i] = 0.0;
    for (const Anchor& anchor : forces.anchors) node_term[anchor.node] += h2 * anchor.stiffness;
    prepareNodes(n, system.velocities, system.masses, system.constrained, h * forces.params.damping, node_term,
                 free_mask, p, q, inverse_diagonal);
    packBlocks(m, system.springs, system.positions, system.stiffnesses, system.rest_lengths, h2, packed, p,
               inverse_diagonal, q);
    rightHandSide(n, f, h, free_mask, q, inverse_diagonal, r);
    iterations_ = solve(n, m, packed, node_term, free_mask, inverse_diagonal, r, p, q, dv, options_.cg_max_iterations,
                        options_.cg_tolerance);

    applyStep(n, free_mask, dv, h, system.velocities, system.positions);
  }

 private:
  IntegratorOptions options_;
  int iterations_ = 0;
  std::vector<Eigen::Vector3d> forces_;
  std::vector<double> r_, p_, q_, dv_, inverse_diagonal_;  // 4 doubles per node
  std::vector<double> node_term_;                          // m_i + h·c + h²·k_anchor,i
  std::vector<double> free_mask_;                          // 1 free, 0 constrained
  std::vector<PackedSpring> packed_;
};

}  // namespace

std::unique_ptr<Integrator> makeImplicitEuler(const IntegratorOptions& options) {
  return std::make_unique<ImplicitEuler>(options);
}

}  // namespace tissue
}  // namespace vrm_sim
