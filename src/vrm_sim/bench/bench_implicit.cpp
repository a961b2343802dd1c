// Implicit Euler benchmark (issue 15 §1): the matrix-free implicit step at 10k nodes, its CG preconditioners (none,
// Jacobi, block-Jacobi) and warm start, on the grasp-and-pull membrane of bench_tissue.
//  - solver rows drive the integrator directly through makeIntegrator + SystemView/ForceModel (no strain limit, no
//    watchdog, no contacts): ms per step, CG iterations, the relative residual reached, once to a fixed residual
//    (1e-6, at most 200 iterations) and once at a fixed 10 iterations; error = final positions against a converged
//    solve of the same linear systems (cg_tolerance 1e-12, 500 iterations, same dt), i.e. the CG error alone.
//  - "implicit_before" is the implementation this benchmark replaced (scatter product over packed springs, Jacobi
//    only), copied below so that before/after come from one run.
//  - full_step rows time TissueSimulator::advance (forces, solve, Provot, grasp) with the watchdog off: the watchdog
//    is the same for every integrator and its rollbacks would mix a second, halved step into some frames.
// Usage: bench_implicit [--quick] [--out FILE]
#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "tissue_bench_scene.h"
#include "vrm_sim/tissue/integrator.h"
#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/system.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace before {
using vrm_sim::tissue::Anchor;
using vrm_sim::tissue::ForceModel;
using vrm_sim::tissue::Integrator;
using vrm_sim::tissue::IntegratorOptions;
using vrm_sim::tissue::kMinSpringLength;
using vrm_sim::tissue::SystemView;

template <typename T>
T* ensureSize(std::vector<T>& buffer, std::size_t size) {
  if (buffer.size() < size) buffer.resize(size);
  return buffer.data();
}

// ---- src/core/tissue/implicit_euler.cpp as of commit 52c78ae, unchanged but for the class name and lastResidual()
// ---- Implicit (backward) Euler, eqs. 5.7-5.10, linearised as in Baraff & Witkin (1998):
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
          double tolerance, double* residual) {
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
  *residual = b_norm2 > 0.0 ? std::sqrt(r_norm2 / b_norm2) : 0.0;
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

class ImplicitEulerBefore : public Integrator {
 public:
  explicit ImplicitEulerBefore(const IntegratorOptions& options) : options_(options) {}
  const char* name() const override { return "implicit_before"; }
  int lastIterations() const override { return iterations_; }
  double lastResidual() const override { return residual_; }

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
                        options_.cg_tolerance, &residual_);

    applyStep(n, free_mask, dv, h, system.velocities, system.positions);
  }

 private:
  IntegratorOptions options_;
  int iterations_ = 0;
  double residual_ = 0.0;
  std::vector<Eigen::Vector3d> forces_;
  std::vector<double> r_, p_, q_, dv_, inverse_diagonal_;  // 4 doubles per node
  std::vector<double> node_term_;                          // m_i + h·c + h²·k_anchor,i
  std::vector<double> free_mask_;                          // 1 free, 0 constrained
  std::vector<PackedSpring> packed_;
};

}  // namespace before

namespace {

using vrm_sim::tissue::ForceModel;
using vrm_sim::tissue::InstrumentInput;
using vrm_sim::tissue::Integrator;
using vrm_sim::tissue::IntegratorOptions;
using vrm_sim::tissue::SystemView;
using vrm_sim::tissue::TissueConfig;
using vrm_sim::tissue::TissueSimulator;

// bench_tissue's grasp-and-pull scene: 5 mm membrane, k = 2 N/m, total mass of the 22×22 thesis mesh at every
// resolution, damping 2e-3 N s/m, the centre grasped (3e-4 m radius) and pulled up at 20 mm/s.
using vrm_sim::bench::forcepsAt;
using vrm_sim::bench::medianOf;
using vrm_sim::bench::wallClock;
constexpr double kSize = vrm_sim::bench::kMembraneSize;
constexpr double kStiffness = vrm_sim::bench::kSpringStiffness;
constexpr double kDamping = 2e-3;
constexpr double kGraspRadius = 3e-4;
constexpr double kLiftSpeed = 0.02;

double nodeMass(int cells) { return vrm_sim::bench::gridNodeMass(cells); }

double mean(const std::vector<double>& values) {
  return values.empty() ? NAN : std::accumulate(values.begin(), values.end(), 0.0) / values.size();
}

struct Run {
  std::vector<Eigen::Vector3d> final_positions;
  std::vector<double> step_ms;
  std::vector<double> iterations;
  std::vector<double> residuals;
  std::size_t nodes = 0, springs = 0;
  bool finite = true;
};

using IntegratorFactory = std::function<std::unique_ptr<Integrator>()>;

// The solver alone: the grasped nodes are constrained and moved kinematically, everything else is the integrator.
Run runSolver(int cells, double dt, double duration, const IntegratorFactory& make) {
  auto membrane = vrm_sim::tissue::makeGridMembrane(cells, kSize, kStiffness, nodeMass(cells));
  const std::size_t n = membrane->nodeCount();
  std::vector<std::uint8_t> constrained(membrane->fixedFlags(), membrane->fixedFlags() + n);
  std::vector<std::size_t> grasped;
  for (std::size_t i = 0; i < n; ++i) {
    if (constrained[i] == 0 && membrane->positions()[i].head<2>().norm() <= kGraspRadius) {
      grasped.push_back(i);
      constrained[i] = 1;
      membrane->velocities()[i] = Eigen::Vector3d(0.0, 0.0, kLiftSpeed);
    }
  }
  ForceModel forces;
  forces.params.damping = kDamping;
  const SystemView system = vrm_sim::tissue::viewOf(*membrane, constrained.data());
  std::unique_ptr<Integrator> integrator = make();
  Run run;
  run.nodes = n;
  run.springs = membrane->springCount();
  const int steps = static_cast<int>(std::lround(duration / dt));
  for (int s = 0; s < steps; ++s) {
    for (std::size_t i : grasped) membrane->positions()[i].z() += kLiftSpeed * dt;
    const double start = wallClock();
    integrator->step(system, forces, dt);
    run.step_ms.push_back(1e3 * (wallClock() - start));
    run.iterations.push_back(integrator->lastIterations());
    run.residuals.push_back(integrator->lastResidual());
  }
  run.final_positions.assign(membrane->positions(), membrane->positions() + n);
  for (const auto& x : run.final_positions) run.finite = run.finite && x.allFinite();
  return run;
}

// The whole TissueSimulator step (forces, implicit solve, Provot strain limit, grasp) in 1 ms frames.
Run runFullStep(int cells, double dt, double duration, const IntegratorOptions& options) {
  auto membrane = vrm_sim::tissue::makeGridMembrane(cells, kSize, kStiffness, nodeMass(cells));
  TissueConfig config;
  config.integrator = "implicit_euler";
  config.integrator_options = options;
  config.dt = dt;
  config.strain_limit = 1.1;
  config.time_budget_ms = 1e9;
  config.max_steps_per_frame = 1 << 20;
  config.forces.damping = kDamping;
  config.watchdog.enabled = false;
  TissueSimulator simulator(*membrane, config);
  Run run;
  run.nodes = membrane->nodeCount();
  run.springs = membrane->springCount();
  const double frame = 1e-3;
  const int frames = static_cast<int>(std::lround(duration / frame));
  Eigen::Vector3d tip(0.0, 0.0, -2e-4);
  simulator.setInstruments({forcepsAt(tip)});
  for (int f = 0; f < frames; ++f) {
    tip.z() += kLiftSpeed * frame;
    simulator.setInstruments({forcepsAt(tip)});
    const double start = wallClock();
    const auto report = simulator.advance(frame, wallClock);
    const double elapsed = wallClock() - start;
    if (report.steps == 0) continue;
    for (int s = 0; s < report.steps; ++s) run.step_ms.push_back(1e3 * elapsed / report.steps);
    run.iterations.push_back(simulator.integrator().lastIterations());
    run.residuals.push_back(simulator.integrator().lastResidual());
  }
  run.final_positions.assign(membrane->positions(), membrane->positions() + membrane->nodeCount());
  for (const auto& x : run.final_positions) run.finite = run.finite && x.allFinite();
  return run;
}

std::string number(double value) {
  if (!std::isfinite(value)) return "null";
  std::ostringstream out;
  out.precision(6);
  out << value;
  return out.str();
}

struct Row {
  std::string scene, integrator, preconditioner, stop, kind;
  bool warm_start = false;
  std::size_t nodes = 0, springs = 0;
  double dt = 0.0;
  double iterations = NAN, residual = NAN, residual_max = NAN;
  double ms_per_step = NAN, ms_per_step_median = NAN;
  // Spread (issue 19): each repetition's median ms per step; the row's ms_min/ms_max are their extremes.
  double ms_min = NAN, ms_max = NAN;
  int repetitions = 0;
  double error_rms = NAN, error_max = NAN;
  bool stable = false;
  int steps = 0;

  std::string json() const {
    std::ostringstream out;
    out << "{\"suite\": \"implicit\", \"scene\": \"" << scene << "\", \"kind\": \"" << kind << "\", \"integrator\": \""
        << integrator << "\", \"preconditioner\": \"" << preconditioner
        << "\", \"warm_start\": " << (warm_start ? "true" : "false") << ", \"cg_stop\": \"" << stop
        << "\", \"nodes\": " << nodes << ", \"springs\": " << springs << ", \"dt\": " << number(dt)
        << ", \"iterations\": " << number(iterations) << ", \"residual\": " << number(residual)
        << ", \"residual_max\": " << number(residual_max) << ", \"ms_per_step\": " << number(ms_per_step)
        << ", \"ms_per_step_median\": " << number(ms_per_step_median) << ", \"ms_min\": " << number(ms_min)
        << ", \"ms_max\": " << number(ms_max) << ", \"repetitions\": " << repetitions
        << ", \"error_rms\": " << number(error_rms) << ", \"error_max\": " << number(error_max)
        << ", \"error_unit\": \"m\", \"stable\": " << (stable ? "true" : "false") << ", \"steps\": " << steps
        << ", \"peer\": \"ours\"}";
    return out.str();
  }
};

void printHeader() {
  std::printf("%-18s %-10s %-16s %-13s %-4s %-12s %7s %8s %9s %9s %10s %10s %-3s\n", "scene", "kind", "integrator",
              "precond", "warm", "stop", "dt", "iter", "residual", "ms/step", "median", "err_rms_m", "ok");
}

void printRow(const Row& row) {
  std::printf("%-18s %-10s %-16s %-13s %-4s %-12s %7.1e %8.2f %9.2e %9.4f %10.4f %10.3e %-3s\n", row.scene.c_str(),
              row.kind.c_str(), row.integrator.c_str(), row.preconditioner.c_str(), row.warm_start ? "on" : "off",
              row.stop.c_str(), row.dt, row.iterations, row.residual, row.ms_per_step, row.ms_per_step_median,
              row.error_rms, row.stable ? "yes" : "no");
  std::fflush(stdout);
}

void setError(Row& row, const Run& run, const Run& reference) {
  double sum2 = 0.0, worst = 0.0;
  for (std::size_t i = 0; i < run.final_positions.size(); ++i) {
    const double e = (run.final_positions[i] - reference.final_positions[i]).norm();
    sum2 += e * e;
    worst = std::max(worst, e);
  }
  row.error_rms = std::sqrt(sum2 / std::max<std::size_t>(run.final_positions.size(), 1));
  row.error_max = worst;
}

// Pooled over repetitions: per-step times, iterations and residuals of every repetition.
Row summarise(const std::vector<Run>& runs, const Run& reference) {
  Row row;
  std::vector<double> ms, iterations, residuals;
  bool finite = true;
  for (const Run& run : runs) {
    const double rep_median = medianOf(run.step_ms);
    row.ms_min = std::isfinite(row.ms_min) ? std::min(row.ms_min, rep_median) : rep_median;
    row.ms_max = std::isfinite(row.ms_max) ? std::max(row.ms_max, rep_median) : rep_median;
    ms.insert(ms.end(), run.step_ms.begin(), run.step_ms.end());
    iterations.insert(iterations.end(), run.iterations.begin(), run.iterations.end());
    residuals.insert(residuals.end(), run.residuals.begin(), run.residuals.end());
    finite = finite && run.finite;
  }
  row.repetitions = static_cast<int>(runs.size());
  row.nodes = runs.front().nodes;
  row.springs = runs.front().springs;
  row.steps = static_cast<int>(runs.front().step_ms.size());
  row.ms_per_step = mean(ms);
  row.ms_per_step_median = medianOf(ms);
  row.iterations = mean(iterations);
  row.residual = mean(residuals);
  row.residual_max = residuals.empty() ? NAN : *std::max_element(residuals.begin(), residuals.end());
  row.stable = finite;
  setError(row, runs.front(), reference);
  return row;
}

struct Variant {
  std::string integrator;  // implicit_euler or implicit_before
  std::string preconditioner;
  bool warm_start;
  int max_iterations;
  double tolerance;
  std::string stop;
};

IntegratorFactory factoryOf(const Variant& variant) {
  IntegratorOptions options;
  options.cg_preconditioner = variant.preconditioner;
  options.cg_warm_start = variant.warm_start;
  options.cg_max_iterations = variant.max_iterations;
  options.cg_tolerance = variant.tolerance;
  if (variant.integrator == "implicit_before") {
    return [options] { return std::make_unique<before::ImplicitEulerBefore>(options); };
  }
  return [options] { return vrm_sim::tissue::makeIntegrator("implicit_euler", options); };
}

}  // namespace

int main(int argc, char** argv) {
  vrm_sim::bench::BenchArgs bench_args;
  if (const auto status = vrm_sim::bench::parseBenchArgs(
          argc, argv, "bench_implicit", "The matrix-free implicit Euler step, its CG preconditioners and warm start.",
          "", &bench_args)) {
    return *status;
  }
  const vrm_sim::bench::BenchArgs* args = &bench_args;
  const bool quick = args->quick;
  const std::vector<int> sizes = quick ? std::vector<int>{22} : std::vector<int>{22, 100};
  const std::vector<double> dts{1e-3, 2.5e-4};
  const double duration = quick ? 0.01 : 0.05;
  const int repetitions = quick ? 1 : 5;  // issue 19: spreads from >= 5 repetitions in one run
  // A residual of 0 never stops CG early, so these runs do exactly 10 iterations.
  constexpr double kFixed = 0.0;
  std::vector<Variant> variants;
  for (const std::string stop : {"iterations_10", "residual_1e-6"}) {
    const int max_iterations = stop == "iterations_10" ? 10 : 200;
    const double tolerance = stop == "iterations_10" ? kFixed : 1e-6;
    variants.push_back({"implicit_before", "jacobi", false, max_iterations, tolerance, stop});
    for (const std::string preconditioner : {"none", "jacobi", "block_jacobi"}) {
      for (bool warm : {false, true}) {
        variants.push_back({"implicit_euler", preconditioner, warm, max_iterations, tolerance, stop});
      }
    }
  }

  std::vector<Row> rows;
  printHeader();
  for (int cells : sizes) {
    const std::string scene = "grasp_pull_" + std::to_string(cells) + "x" + std::to_string(cells);
    for (double dt : dts) {
      const Variant converged{"implicit_euler", "jacobi", false, 500, 1e-12, "residual_1e-12"};
      const Run reference = runSolver(cells, dt, duration, factoryOf(converged));
      // Repetitions interleaved across variants, so a burst of load from the other workers hits all of them alike.
      std::vector<std::vector<Run>> runs(variants.size());
      for (int rep = 0; rep < repetitions; ++rep) {
        for (std::size_t v = 0; v < variants.size(); ++v) {
          runs[v].push_back(runSolver(cells, dt, duration, factoryOf(variants[v])));
        }
      }
      for (std::size_t v = 0; v < variants.size(); ++v) {
        Row row = summarise(runs[v], reference);
        row.scene = scene;
        row.kind = "solver";
        row.integrator = variants[v].integrator;
        row.preconditioner = variants[v].preconditioner;
        row.warm_start = variants[v].warm_start;
        row.stop = variants[v].stop;
        row.dt = dt;
        printRow(row);
        rows.push_back(row);
      }

      // Full TissueSimulator steps at 10 CG iterations; error against the same simulation solved to 1e-12.
      IntegratorOptions reference_options;
      reference_options.cg_max_iterations = 500;
      reference_options.cg_tolerance = 1e-12;
      const Run full_reference = runFullStep(cells, dt, duration, reference_options);
      for (const std::string preconditioner : {"none", "jacobi", "block_jacobi"}) {
        IntegratorOptions options;
        options.cg_preconditioner = preconditioner;
        options.cg_max_iterations = 10;
        options.cg_tolerance = kFixed;
        std::vector<Run> full_runs;
        for (int rep = 0; rep < repetitions; ++rep) full_runs.push_back(runFullStep(cells, dt, duration, options));
        Row row = summarise(full_runs, full_reference);
        row.scene = scene;
        row.kind = "full_step";
        row.integrator = "implicit_euler";
        row.preconditioner = preconditioner;
        row.stop = "iterations_10";
        row.dt = dt;
        printRow(row);
        rows.push_back(row);
      }
    }
  }

  if (!args->out_path.empty()) {
    std::ostringstream command;
    for (int i = 0; i < argc; ++i) command << (i ? " " : "") << argv[i];
    std::ofstream out(args->out_path);
    out << "{\"suite\": \"implicit\", \"command\": \"" << command.str() << "\", \"rows\": [\n";
    for (std::size_t i = 0; i < rows.size(); ++i) out << "  " << rows[i].json() << (i + 1 < rows.size() ? ",\n" : "\n");
    out << "]}\n";
    std::printf("wrote %zu rows to %s\n", rows.size(), args->out_path.c_str());
  }
  return 0;
}
