// The linear solve inside implicit Euler (issue 15): every CG preconditioner must reach the Δv of a dense solve of
// the same Baraff–Witkin system, block-Jacobi must pay off on anisotropic blocks, warm start must save iterations on
// a smooth trajectory, and poisoned input must end the solve instead of spinning.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "vrm_sim/tissue/integrator.h"
#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/system.h"

namespace vrm_sim {
namespace tissue {
namespace {

// (M + h·c + h²·S) Δv = h·(F − h·S v) on the free nodes, S assembled densely from the spring blocks
// k(t·I + (1 − t)·uuᵀ), t = max(0, 1 − l/|d|), and the anchors; Δv per node (zero on constrained nodes).
std::vector<Eigen::Vector3d> denseVelocityChange(const SystemView& system, const ForceModel& forces, double h) {
  const std::size_t n = system.node_count;
  std::vector<int> index(n, -1);
  int free_count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (system.isFree(i)) index[i] = free_count++;
  }
  Eigen::MatrixXd stiffness = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    const auto& ends = system.springs[s];
    const Eigen::Vector3d d = system.positions[ends[1]] - system.positions[ends[0]];
    const Eigen::Vector3d u = d.normalized();
    const double t = std::max(0.0, 1.0 - system.rest_lengths[s] / d.norm());
    const Eigen::Matrix3d block =
        system.stiffnesses[s] * (t * Eigen::Matrix3d::Identity() + (1.0 - t) * u * u.transpose());
    for (int r = 0; r < 2; ++r) {
      for (int c = 0; c < 2; ++c) {
        stiffness.block<3, 3>(3 * ends[r], 3 * ends[c]) += (r == c ? 1.0 : -1.0) * block;
      }
    }
  }
  for (const Anchor& anchor : forces.anchors) {
    stiffness.block<3, 3>(3 * anchor.node, 3 * anchor.node) += anchor.stiffness * Eigen::Matrix3d::Identity();
  }
  std::vector<Eigen::Vector3d> force(n);
  forces.compute(system, system.positions, system.velocities, force.data());
  Eigen::VectorXd velocity(3 * n);
  for (std::size_t i = 0; i < n; ++i) velocity.segment<3>(3 * i) = system.velocities[i];
  const Eigen::VectorXd stiffness_velocity = stiffness * velocity;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(3 * free_count, 3 * free_count);
  Eigen::VectorXd b(3 * free_count);
  for (std::size_t i = 0; i < n; ++i) {
    if (index[i] < 0) continue;
    b.segment<3>(3 * index[i]) = h * (force[i] - h * stiffness_velocity.segment<3>(3 * i));
    for (std::size_t j = 0; j < n; ++j) {
      if (index[j] >= 0) a.block<3, 3>(3 * index[i], 3 * index[j]) = h * h * stiffness.block<3, 3>(3 * i, 3 * j);
    }
    a.block<3, 3>(3 * index[i], 3 * index[i]) +=
        (system.masses[i] + h * forces.params.damping) * Eigen::Matrix3d::Identity();
  }
  const Eigen::VectorXd dv = a.ldlt().solve(b);
  std::vector<Eigen::Vector3d> result(n, Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < n; ++i) {
    if (index[i] >= 0) result[i] = dv.segment<3>(3 * index[i]);
  }
  return result;
}

// A membrane with stretched (x) and compressed (y) springs, out-of-plane jitter and velocities, rotated about z by
// `angle` so that the anisotropy is not aligned with the axes; the border pinned.
struct Patch {
  std::unique_ptr<mge::Membrane> membrane;
  std::vector<std::uint8_t> constrained;
  ForceModel forces;
  SystemView system;

  Patch(int cells, double stretch_x, double stretch_y, double angle) {
    membrane = makeGridMembrane(cells, 0.005, 2.0, 1e-5);
    const std::size_t n = membrane->nodeCount();
    constrained.assign(membrane->fixedFlags(), membrane->fixedFlags() + n);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> jitter(-1.0, 1.0);
    const Eigen::Matrix3d rotation = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (std::size_t i = 0; i < n; ++i) {
      Eigen::Vector3d& x = membrane->positions()[i];
      x.x() *= stretch_x;
      x.y() *= stretch_y;
      x = rotation * x;
      if (constrained[i] == 0) {
        x.z() += 2e-4 * jitter(rng);
        membrane->velocities()[i] = 1e-2 * Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
      }
    }
    forces.params.damping = 2e-3;
    forces.params.gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
    std::uint32_t anchored = 0;
    while (constrained[anchored] != 0) ++anchored;
    forces.anchors.push_back({anchored, membrane->positions()[anchored] + Eigen::Vector3d(0.0, 0.0, 1e-4), 5.0});
    system = viewOf(*membrane, constrained.data());
  }
};

std::unique_ptr<Integrator> implicitEuler(const std::string& preconditioner, int max_iterations, double tolerance,
                                          bool warm_start = false) {
  IntegratorOptions options;
  options.cg_preconditioner = preconditioner;
  options.cg_max_iterations = max_iterations;
  options.cg_tolerance = tolerance;
  options.cg_warm_start = warm_start;
  return makeIntegrator("implicit_euler", options);
}

TEST(ImplicitSolver, EveryPreconditionerReachesTheDenseSolve) {
  const double h = 2e-3;
  for (const char* preconditioner : {"none", "jacobi", "block_jacobi"}) {
    Patch patch(5, 1.08, 0.95, 0.4);
    const std::size_t n = patch.system.node_count;
    const std::vector<Eigen::Vector3d> expected = denseVelocityChange(patch.system, patch.forces, h);
    const std::vector<Eigen::Vector3d> v0(patch.system.velocities, patch.system.velocities + n);
    const std::vector<Eigen::Vector3d> x0(patch.system.positions, patch.system.positions + n);
    double scale = 0.0;
    for (const auto& dv : expected) scale = std::max(scale, dv.norm());
    ASSERT_GT(scale, 0.0);

    auto integrator = implicitEuler(preconditioner, 500, 1e-14);
    integrator->step(patch.system, patch.forces, h);
    EXPECT_LT(integrator->lastIterations(), 500) << preconditioner;
    EXPECT_LE(integrator->lastResidual(), 1e-14) << preconditioner;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d dv = patch.system.velocities[i] - v0[i];
      EXPECT_LT((dv - expected[i]).norm(), 1e-10 * scale) << preconditioner << " node " << i;
      const Eigen::Vector3d expected_x = patch.constrained[i] ? x0[i] : Eigen::Vector3d(x0[i] + h * (v0[i] + dv));
      EXPECT_LT((patch.system.positions[i] - expected_x).norm(), 1e-12 * h * scale) << preconditioner << " " << i;
    }
  }
}

// Iterations to a relative residual of 1e-10 on the same system.
int iterationsToConverge(const std::string& preconditioner, double stretch_x, double stretch_y, double angle) {
  Patch patch(12, stretch_x, stretch_y, angle);
  auto integrator = implicitEuler(preconditioner, 1000, 1e-10);
  integrator->step(patch.system, patch.forces, 5e-3);
  EXPECT_LE(integrator->lastResidual(), 1e-10) << preconditioner;
  return integrator->lastIterations();
}

TEST(ImplicitSolver, BlockJacobiNeedsNoMoreIterationsThanJacobiOnAnisotropicBlocks) {
  // Strongly stretched along a diagonal direction: each node's 3×3 block has large off-diagonal entries, which the
  // Jacobi diagonal ignores.
  const int none = iterationsToConverge("none", 1.6, 1.0, M_PI / 4);
  const int jacobi = iterationsToConverge("jacobi", 1.6, 1.0, M_PI / 4);
  const int block_jacobi = iterationsToConverge("block_jacobi", 1.6, 1.0, M_PI / 4);
  EXPECT_LE(block_jacobi, jacobi);
  EXPECT_LE(jacobi, none);
  EXPECT_GT(none, 0);
  RecordProperty("iterations_none", none);
  RecordProperty("iterations_jacobi", jacobi);
  RecordProperty("iterations_block_jacobi", block_jacobi);
}

// Grasp-and-pull: the centre pulled up steadily, the solve to a fixed residual; returns the iterations over all
// steps after the start-up transient (the first 20) and the final positions.
std::pair<int, std::vector<Eigen::Vector3d>> pull(bool warm_start, const std::string& preconditioner) {
  auto membrane = makeGridMembrane(22, 0.005, 2.0, 1e-5);
  const std::size_t n = membrane->nodeCount();
  std::vector<std::uint8_t> constrained(membrane->fixedFlags(), membrane->fixedFlags() + n);
  std::vector<std::size_t> grasped;
  for (std::size_t i = 0; i < n; ++i) {
    if (constrained[i] == 0 && membrane->positions()[i].head<2>().norm() <= 3e-4) {
      grasped.push_back(i);
      constrained[i] = 1;
      membrane->velocities()[i] = Eigen::Vector3d(0.0, 0.0, 0.02);
    }
  }
  ForceModel forces;
  forces.params.damping = 2e-3;
  const SystemView system = viewOf(*membrane, constrained.data());
  auto integrator = implicitEuler(preconditioner, 200, 1e-8, warm_start);
  int iterations = 0;
  for (int step = 0; step < 60; ++step) {
    for (std::size_t i : grasped) membrane->positions()[i].z() += 0.02 * 1e-3;
    integrator->step(system, forces, 1e-3);
    EXPECT_LE(integrator->lastResidual(), 1e-8);
    if (step >= 20) iterations += integrator->lastIterations();
  }
  return {iterations, std::vector<Eigen::Vector3d>(membrane->positions(), membrane->positions() + n)};
}

TEST(ImplicitSolver, WarmStartSavesIterationsOnASmoothTrajectory) {
  // Measured: about 9 % fewer iterations (Jacobi 398 against 435, block-Jacobi 362 against 400); Δv follows the
  // membrane's oscillation, so the last step's Δv is a fair but not a close first guess.
  for (const char* preconditioner : {"jacobi", "block_jacobi"}) {
    const auto cold = pull(false, preconditioner);
    const auto warm = pull(true, preconditioner);
    EXPECT_LT(warm.first, 0.95 * cold.first) << preconditioner << ": warm " << warm.first << ", cold " << cold.first;
    // Both solve to the same residual, so the trajectories agree far below the 0.2 mm pull.
    double worst = 0.0;
    for (std::size_t i = 0; i < cold.second.size(); ++i) {
      worst = std::max(worst, (cold.second[i] - warm.second[i]).norm());
    }
    EXPECT_LT(worst, 1e-9) << preconditioner;
  }
}

TEST(ImplicitSolver, WarmStartRestartsAfterATopologyChange) {
  // One integrator on two different membranes: after the switch it must behave like a fresh one (no stale Δv).
  auto shared = implicitEuler("jacobi", 30, 1e-8, true);
  Patch first(6, 1.05, 1.0, 0.0);
  shared->step(first.system, first.forces, 1e-3);
  Patch second(7, 1.05, 1.0, 0.0);
  Patch reference(7, 1.05, 1.0, 0.0);
  shared->step(second.system, second.forces, 1e-3);
  auto fresh = implicitEuler("jacobi", 30, 1e-8, true);
  fresh->step(reference.system, reference.forces, 1e-3);
  EXPECT_EQ(shared->lastIterations(), fresh->lastIterations());
  for (std::size_t i = 0; i < second.system.node_count; ++i) {
    EXPECT_EQ(second.system.positions[i], reference.system.positions[i]) << i;
  }
}

TEST(ImplicitSolver, NanInputEndsTheSolve) {
  for (const char* preconditioner : {"none", "jacobi", "block_jacobi"}) {
    for (bool warm_start : {false, true}) {
      Patch patch(5, 1.0, 1.0, 0.0);
      auto integrator = implicitEuler(preconditioner, 1000000, 0.0, warm_start);
      integrator->step(patch.system, patch.forces, 1e-3);  // a finite step first, so warm start has a Δv
      std::size_t free_node = 0;
      while (patch.constrained[free_node] != 0) ++free_node;
      patch.system.positions[free_node].x() = std::numeric_limits<double>::quiet_NaN();
      integrator->step(patch.system, patch.forces, 1e-3);
      EXPECT_EQ(integrator->lastIterations(), 0) << preconditioner;
      EXPECT_TRUE(std::isnan(integrator->lastResidual())) << preconditioner;
    }
  }
}

TEST(ImplicitSolver, UnknownPreconditionerIsRejected) {
  IntegratorOptions options;
  options.cg_preconditioner = "incomplete_cholesky";
  EXPECT_THROW(makeIntegrator("implicit_euler", options), std::invalid_argument);
  options.cg_preconditioner = "block_jacobi";
  EXPECT_NO_THROW(makeIntegrator("implicit_euler", options));
}

}  // namespace
}  // namespace tissue
}  // namespace vrm_sim
