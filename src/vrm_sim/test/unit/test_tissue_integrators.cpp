// Integrators against exact solutions (issue 3, "Correctness"): oscillator period and energy, chain wave speed,
// the explicit stability bound (eq. 5.6), static sag, measured convergence order.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <random>

#include "vrm_sim/tissue/integrator.h"
#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {
namespace {

struct Oscillator {
  static constexpr double kStiffness = 4.0;  // N/m
  static constexpr double kMass = 1e-3;      // kg -> ω = 63.2 rad/s, T ≈ 0.0993 s
  static constexpr double kRest = 0.01;
  static constexpr double kAmplitude = 0.002;
  std::unique_ptr<mge::Membrane> chain = makeChain(1, kStiffness, kMass, kRest);
  std::vector<std::uint8_t> constrained{1, 0};
  ForceModel forces;
  Oscillator() { chain->positions()[1].x() = kRest + kAmplitude; }
  SystemView view() { return viewOf(*chain, constrained.data()); }
  double x() { return chain->positions()[1].x() - kRest; }
  double omega() const { return std::sqrt(kStiffness / kMass); }
  double exact(double t) const { return kAmplitude * std::cos(omega() * t); }
  double energy() {
    const SystemView system = view();
    return kineticEnergy(system) + forces.potentialEnergy(system, system.positions);
  }
};

TEST(TissueIntegrators, NamesAreKnownAndUnknownNameThrows) {
  for (const auto& name : integratorNames()) EXPECT_EQ(makeIntegrator(name)->name(), name);
  EXPECT_THROW(makeIntegrator("rk4_typo"), std::invalid_argument);
}

TEST(TissueIntegrators, OscillatorPeriodAndEnergy) {
  for (const char* name : {"rk2", "symplectic_euler", "implicit_euler"}) {
    Oscillator oscillator;
    auto integrator = makeIntegrator(name);
    const double dt = 1e-5;
    const double energy0 = oscillator.energy();
    // Period from the first two upward zero crossings (linear interpolation between steps).
    std::vector<double> crossings;
    double previous = oscillator.x();
    double max_energy_error = 0.0;
    for (int step = 1; step <= 25000 && crossings.size() < 2; ++step) {
      integrator->step(oscillator.view(), oscillator.forces, dt);
      const double current = oscillator.x();
      if (previous < 0.0 && current >= 0.0) crossings.push_back((step - 1 + previous / (previous - current)) * dt);
      previous = current;
      max_energy_error = std::max(max_energy_error, std::abs(oscillator.energy() - energy0) / energy0);
    }
    ASSERT_EQ(crossings.size(), 2u) << name;
    const double period = 2.0 * M_PI / oscillator.omega();
    EXPECT_NEAR(crossings[1] - crossings[0], period, 1e-3 * period) << name;
    // Implicit Euler dissipates (first order); the others conserve energy to O(ω·dt).
    EXPECT_LT(max_energy_error, std::string(name) == "implicit_euler" ? 0.03 : 2e-3) << name;
  }
}

// Error at t_end against the exact cosine, for dt and dt/2: order = log2(e(dt) / e(dt/2)).
double measuredOrder(const std::string& name, double dt) {
  auto error = [&](double step) {
    Oscillator oscillator;
    IntegratorOptions options;
    options.cg_tolerance = 1e-14;
    auto integrator = makeIntegrator(name, options);
    const int steps = static_cast<int>(std::lround(0.2 / step));
    for (int i = 0; i < steps; ++i) integrator->step(oscillator.view(), oscillator.forces, step);
    // Phase-space error (position and velocity / ω), so a zero crossing of one part cannot fake an order.
    const double t = steps * step;
    const double w = oscillator.omega();
    const double velocity_error = oscillator.chain->velocities()[1].x() + Oscillator::kAmplitude * w * std::sin(w * t);
    return std::hypot(oscillator.x() - oscillator.exact(t), velocity_error / w);
  };
  return std::log2(error(dt) / error(dt / 2.0));
}

TEST(TissueIntegrators, ConvergenceOrder) {
  EXPECT_NEAR(measuredOrder("explicit_euler", 1e-4), 1.0, 0.15);
  EXPECT_NEAR(measuredOrder("implicit_euler", 1e-4), 1.0, 0.15);
  EXPECT_NEAR(measuredOrder("symplectic_euler", 1e-4), 1.0, 0.15);
  EXPECT_NEAR(measuredOrder("rk2", 1e-4), 2.0, 0.15);
}

// A velocity step at node 0 travels down the chain at c = l·sqrt(k/m) (thesis §5.2.1).
TEST(TissueIntegrators, ChainWaveSpeed) {
  const int springs = 80;
  const double k = 10.0, m = 1e-4, l = 1e-3;
  auto chain = makeChain(springs, k, m, l);
  std::vector<std::uint8_t> constrained(springs + 1, 0);
  constrained[0] = 1;
  ForceModel forces;
  auto integrator = makeIntegrator("symplectic_euler");
  const double dt = 0.02 * std::sqrt(m / k);
  const double push_speed = 1e-3;
  const int probe = 60;
  double arrival = -1.0;
  for (int step = 1; step < 200000 && arrival < 0.0; ++step) {
    chain->positions()[0].x() = -push_speed * step * dt;
    integrator->step(viewOf(*chain, constrained.data()), forces, dt);
    if (chain->velocities()[probe].x() < -0.5 * push_speed) arrival = step * dt;
  }
  const double expected = probe / std::sqrt(k / m);  // probe springs at sqrt(k/m) springs per second
  EXPECT_NEAR(arrival, expected, 0.08 * expected);
}

// Largest eigen-frequency of the fixed-free chain (exact linear analysis).
double maxOmega(int springs, double k, double m) {
  Eigen::MatrixXd stiffness = Eigen::MatrixXd::Zero(springs, springs);
  for (int i = 0; i < springs; ++i) {
    stiffness(i, i) = (i + 1 < springs) ? 2.0 : 1.0;
    if (i > 0) stiffness(i, i - 1) = stiffness(i - 1, i) = -1.0;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(stiffness * (k / m));
  return std::sqrt(solver.eigenvalues().maxCoeff());
}

// Max displacement from rest after `steps` steps from a small random perturbation.
double growth(const std::string& name, int springs, double k, double m, double damping, double dt, int steps) {
  auto chain = makeChain(springs, k, m, 1e-3);
  std::vector<std::uint8_t> constrained(springs + 1, 0);
  constrained[0] = 1;
  std::mt19937 random(7);
  std::uniform_real_distribution<double> noise(-1e-6, 1e-6);
  for (int i = 1; i <= springs; ++i) chain->positions()[i].x() += noise(random);
  ForceModel forces;
  forces.params.damping = damping;
  auto integrator = makeIntegrator(name);
  for (int s = 0; s < steps; ++s) integrator->step(viewOf(*chain, constrained.data()), forces, dt);
  double max_offset = 0.0;
  for (int i = 1; i <= springs; ++i) {
    const double offset = std::abs(chain->positions()[i].x() - i * 1e-3);
    if (!std::isfinite(offset)) return std::numeric_limits<double>::infinity();
    max_offset = std::max(max_offset, offset);
  }
  return std::isfinite(max_offset) ? max_offset / 1e-6 : std::numeric_limits<double>::infinity();
}

// Eq. 5.6: explicit steps blow up just above the stability bound and not below. The bound of each explicit scheme is
// computed exactly for the chain; the thesis' estimate Δt ≤ (l/2S)·sqrt(m/k) (l = S rest lengths) must lie below it.
TEST(TissueIntegrators, ExplicitStabilityBound) {
  const int springs = 20;
  const double k = 10.0, m = 1e-4;
  const double omega = maxOmega(springs, k, m);
  const double thesis_bound = 0.5 * std::sqrt(m / k);

  // Symplectic Euler, undamped: |trace| of the step matrix <= 2  <=>  Δt <= 2/ω_max.
  const double symplectic_bound = 2.0 / omega;
  EXPECT_LT(thesis_bound, symplectic_bound);
  EXPECT_LT(growth("symplectic_euler", springs, k, m, 0.0, 0.98 * symplectic_bound, 3000), 10.0);
  EXPECT_GT(growth("symplectic_euler", springs, k, m, 0.0, 1.02 * symplectic_bound, 3000), 1e3);

  // Explicit Euler (eq. 5.4) needs damping: |1 + λΔt| <= 1 for λ = −γ/2 ± i·sqrt(ω² − γ²/4) <=> Δt <= γ/ω².
  // With γ = c/m = ω_max the bound is 1/ω_max, again above the thesis' estimate.
  const double damping = omega * m;
  const double euler_bound = 1.0 / omega;
  EXPECT_LT(thesis_bound, euler_bound);
  EXPECT_LT(growth("explicit_euler", springs, k, m, damping, 0.95 * euler_bound, 6000), 10.0);
  EXPECT_GT(growth("explicit_euler", springs, k, m, damping, 1.05 * euler_bound, 6000), 1e3);
  // The implicit integrators do not care (10× the bound).
  EXPECT_LT(growth("implicit_euler", springs, k, m, 0.0, 10.0 * symplectic_bound, 3000), 10.0);
}

// Static sag of a pinned membrane under gravity: every integrator comes to rest at the converged reference
// (implicit Euler with large steps ≈ Newton's method on the equilibrium).
TEST(TissueIntegrators, StaticSagMatchesConvergedReference) {
  const int cells = 10;
  const double k = 2.0, node_mass = 1e-5, size = 0.005;
  auto sag = [&](const std::string& name, double dt, int steps, double damping) {
    auto membrane = makeGridMembrane(cells, size, k, node_mass);
    TissueConfig config;
    config.integrator = name;
    config.dt = dt;
    config.strain_limit = 0.0;
    config.forces.gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
    config.forces.damping = damping;
    config.integrator_options.cg_max_iterations = 200;
    config.integrator_options.cg_tolerance = 1e-12;
    TissueSimulator simulator(*membrane, config);
    for (int s = 0; s < steps; ++s) simulator.step();
    const int centre = (cells / 2) * (cells + 2);
    return -membrane->positions()[centre].z();
  };
  const double reference = sag("implicit_euler", 0.05, 400, 1e-3);
  EXPECT_GT(reference, 1e-5);
  EXPECT_NEAR(sag("implicit_euler", 1e-3, 3000, 2e-3), reference, 0.01 * reference);
  EXPECT_NEAR(sag("quasi_static_euler", 1e-3, 6000, 0.0), reference, 0.01 * reference);
  EXPECT_NEAR(sag("symplectic_euler", 5e-4, 8000, 2e-3), reference, 0.01 * reference);
  EXPECT_NEAR(sag("rk2", 5e-4, 8000, 2e-3), reference, 0.01 * reference);
  EXPECT_NEAR(sag("explicit_euler", 2e-4, 20000, 5e-3), reference, 0.01 * reference);
  EXPECT_NEAR(sag("xpbd", 1e-3, 3000, 2e-3), reference, 0.03 * reference);
}

// The matrix-free filtered CG of implicit Euler, run to convergence, must give the Baraff–Witkin step solved
// directly: (M + Δt·c + Δt²·S) Δv = Δt·(F − Δt·S v) on the free nodes, with S assembled densely from the spring
// blocks k(t·I + (1 − t)·uuᵀ), t = max(0, 1 − l/|d|), and the anchors. Stretched and compressed springs, damping,
// gravity, an anchor and pinned nodes all enter.
TEST(TissueIntegrators, ImplicitEulerMatchesTheDenseBaraffWitkinSolve) {
  auto membrane = makeGridMembrane(4, 0.005, 2.0, 1e-5);
  const std::size_t n = membrane->nodeCount();
  std::vector<std::uint8_t> constrained(membrane->fixedFlags(), membrane->fixedFlags() + n);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-1.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector3d& x = membrane->positions()[i];
    x.x() *= 1.08;  // x springs stretched, y springs compressed
    x.y() *= 0.95;
    if (constrained[i] == 0) {
      x.z() += 2e-4 * jitter(rng);
      membrane->velocities()[i] = 1e-2 * Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
    }
  }
  ForceModel forces;
  forces.params.damping = 2e-3;
  forces.params.gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
  std::uint32_t anchored = 0;
  while (constrained[anchored] != 0) ++anchored;
  forces.anchors.push_back({anchored, membrane->positions()[anchored] + Eigen::Vector3d(0.0, 0.0, 1e-4), 5.0});
  const SystemView system = viewOf(*membrane, constrained.data());
  const double h = 2e-3;

  // Dense reference.
  std::vector<int> index(n, -1);
  int free_count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (constrained[i] == 0) index[i] = free_count++;
  }
  const int dim = 3 * free_count;
  Eigen::MatrixXd stiffness = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  int compressed = 0;
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    const auto& ends = system.springs[s];
    const Eigen::Vector3d d = system.positions[ends[1]] - system.positions[ends[0]];
    const Eigen::Vector3d u = d.normalized();
    const double t = std::max(0.0, 1.0 - system.rest_lengths[s] / d.norm());
    compressed += t == 0.0 ? 1 : 0;
    const Eigen::Matrix3d block =
        system.stiffnesses[s] * (t * Eigen::Matrix3d::Identity() + (1.0 - t) * u * u.transpose());
    for (int r = 0; r < 2; ++r) {
      for (int c = 0; c < 2; ++c) {
        stiffness.block<3, 3>(3 * ends[r], 3 * ends[c]) += (r == c ? 1.0 : -1.0) * block;
      }
    }
  }
  ASSERT_GT(compressed, 0);
  stiffness.block<3, 3>(3 * anchored, 3 * anchored) += 5.0 * Eigen::Matrix3d::Identity();
  std::vector<Eigen::Vector3d> force(n);
  forces.compute(system, system.positions, system.velocities, force.data());
  Eigen::VectorXd velocity(3 * n);
  for (std::size_t i = 0; i < n; ++i) velocity.segment<3>(3 * i) = system.velocities[i];
  const Eigen::VectorXd stiffness_velocity = stiffness * velocity;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(dim, dim);
  Eigen::VectorXd b(dim);
  for (std::size_t i = 0; i < n; ++i) {
    if (index[i] < 0) continue;
    b.segment<3>(3 * index[i]) = h * (force[i] - h * stiffness_velocity.segment<3>(3 * i));
    for (std::size_t j = 0; j < n; ++j) {
      if (index[j] < 0) continue;
      a.block<3, 3>(3 * index[i], 3 * index[j]) = h * h * stiffness.block<3, 3>(3 * i, 3 * j);
    }
    a.block<3, 3>(3 * index[i], 3 * index[i]) +=
        (system.masses[i] + h * forces.params.damping) * Eigen::Matrix3d::Identity();
  }
  const Eigen::VectorXd dv = a.ldlt().solve(b);
  std::vector<Eigen::Vector3d> expected_x(system.positions, system.positions + n);
  std::vector<Eigen::Vector3d> expected_v(system.velocities, system.velocities + n);
  for (std::size_t i = 0; i < n; ++i) {
    if (index[i] < 0) continue;
    expected_v[i] += dv.segment<3>(3 * index[i]);
    expected_x[i] += h * expected_v[i];
  }

  IntegratorOptions options;
  options.cg_max_iterations = 500;
  options.cg_tolerance = 1e-13;
  auto integrator = makeIntegrator("implicit_euler", options);
  const std::vector<Eigen::Vector3d> pinned_before(system.positions, system.positions + n);
  integrator->step(system, forces, h);
  EXPECT_LT(integrator->lastIterations(), 500);
  double dv_scale = dv.cwiseAbs().maxCoeff();
  ASSERT_GT(dv_scale, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    if (index[i] < 0) {
      EXPECT_EQ(system.positions[i], pinned_before[i]) << i;
      continue;
    }
    EXPECT_LT((system.velocities[i] - expected_v[i]).norm(), 1e-9 * dv_scale) << i;
    EXPECT_LT((system.positions[i] - expected_x[i]).norm(), 1e-9 * h * dv_scale) << i;
  }
}

}  // namespace
}  // namespace tissue
}  // namespace vrm_sim
