#pragma once
// Reference solutions for the tissue benchmark that no integrator under test produced (issue 19).
// Static sag: the equilibrium of a Hooke spring network (eq. 5.2) with pinned nodes under per-node loads, found by a
// Newton solve of the potential energy's stationarity (sparse LDLᵀ on the free degrees of freedom, backtracking on
// the energy). It shares the force law with the simulator, nothing else: no time stepping, no damping, no integrator.
#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace vrm_sim {
namespace bench {

struct SpringNetwork {
  std::vector<Eigen::Vector3d> positions;  // initial guess on input (pinned nodes keep theirs)
  std::vector<std::uint8_t> fixed;
  std::vector<std::array<std::uint32_t, 2>> springs;
  std::vector<double> stiffness, rest_length;
  std::vector<Eigen::Vector3d> loads;  // N per node (gravity: m_i g)
};

struct StaticSolution {
  std::vector<Eigen::Vector3d> positions;
  int iterations = 0;
  double residual = NAN;  // N: the largest net force on a free node at the solution
  bool converged = false;
};

// Net force (springs + loads) on every node; energy = spring energy − load work.
inline double networkForces(const SpringNetwork& net, const std::vector<Eigen::Vector3d>& x,
                            std::vector<Eigen::Vector3d>& force) {
  force = net.loads;
  double energy = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) energy -= net.loads[i].dot(x[i]);
  for (std::size_t s = 0; s < net.springs.size(); ++s) {
    const auto [a, b] = net.springs[s];
    const Eigen::Vector3d d = x[b] - x[a];
    const double length = d.norm();
    const double stretch = length - net.rest_length[s];
    energy += 0.5 * net.stiffness[s] * stretch * stretch;
    if (length < 1e-15) continue;
    const Eigen::Vector3d f = net.stiffness[s] * stretch / length * d;  // pulls a towards b when stretched
    force[a] += f;
    force[b] -= f;
  }
  return energy;
}

// Newton on the free nodes with the spring Hessian k[nnᵀ + (1 − l/L)(I − nnᵀ)]; for a compressed spring the
// transverse term takes |1 − l/L| (a positive-definite surrogate while the guess is slack). Near a taut equilibrium
// it is the exact Hessian, so the last iterations converge quadratically.
inline StaticSolution solveStatic(const SpringNetwork& net, double force_tolerance, int max_iterations = 200) {
  const std::size_t n = net.positions.size();
  std::vector<int> dof(n, -1);
  int free_count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!net.fixed[i]) dof[i] = free_count++;
  }
  StaticSolution solution;
  solution.positions = net.positions;
  std::vector<Eigen::Vector3d>& x = solution.positions;
  std::vector<Eigen::Vector3d> force;
  double energy = networkForces(net, x, force);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    double worst = 0.0;
    Eigen::VectorXd rhs(3 * free_count);
    for (std::size_t i = 0; i < n; ++i) {
      if (dof[i] < 0) continue;
      rhs.segment<3>(3 * dof[i]) = force[i];
      worst = std::max(worst, force[i].norm());
    }
    solution.residual = worst;
    solution.iterations = iteration;
    if (worst <= force_tolerance) {
      solution.converged = true;
      return solution;
    }
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(net.springs.size() * 36);
    for (std::size_t s = 0; s < net.springs.size(); ++s) {
      const auto [a, b] = net.springs[s];
      const Eigen::Vector3d d = x[b] - x[a];
      const double length = d.norm();
      if (length < 1e-15) continue;
      const Eigen::Vector3d u = d / length;
      const double transverse = std::max(std::abs(1.0 - net.rest_length[s] / length), 1e-9);
      const Eigen::Matrix3d block =
          net.stiffness[s] * (u * u.transpose() + transverse * (Eigen::Matrix3d::Identity() - u * u.transpose()));
      const int ends[2] = {dof[a], dof[b]};
      for (int p = 0; p < 2; ++p) {
        for (int q = 0; q < 2; ++q) {
          if (ends[p] < 0 || ends[q] < 0) continue;
          const double sign = p == q ? 1.0 : -1.0;
          for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) triplets.emplace_back(3 * ends[p] + r, 3 * ends[q] + c, sign * block(r, c));
          }
        }
      }
    }
    Eigen::SparseMatrix<double> hessian(3 * free_count, 3 * free_count);
    hessian.setFromTriplets(triplets.begin(), triplets.end());
    solver.compute(hessian);
    if (solver.info() != Eigen::Success) return solution;
    const Eigen::VectorXd step = solver.solve(rhs);
    // Backtracking on the energy (a full Newton step from a poor guess can overshoot the cable-like sag).
    double alpha = 1.0;
    std::vector<Eigen::Vector3d> trial(n);
    std::vector<Eigen::Vector3d> trial_force;
    for (int halving = 0; halving < 40; ++halving, alpha *= 0.5) {
      for (std::size_t i = 0; i < n; ++i) trial[i] = dof[i] < 0 ? x[i] : x[i] + alpha * step.segment<3>(3 * dof[i]);
      const double trial_energy = networkForces(net, trial, trial_force);
      // Near the solution the energy changes below its rounding: there a smaller net force decides.
      double trial_worst = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        if (dof[i] >= 0) trial_worst = std::max(trial_worst, trial_force[i].norm());
      }
      if (trial_energy < energy || trial_worst < worst || halving == 39) {
        x = trial;
        force = trial_force;
        energy = trial_energy;
        break;
      }
    }
  }
  return solution;
}

}  // namespace bench
}  // namespace vrm_sim
