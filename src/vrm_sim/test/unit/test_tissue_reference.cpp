// The benchmark's static reference solver (bench/tissue_reference.h, issue 19) against closed-form equilibria.
#include <gtest/gtest.h>

#include "../../bench/tissue_reference.h"

namespace {

using vrm_sim::bench::SpringNetwork;
using vrm_sim::bench::solveStatic;

// A vertical chain of n springs hanging from a pinned top node, each free node of mass m under gravity g: spring j
// (counted from the top, 1-based) carries the weight of the n − j + 1 nodes below it, so its length is
// l + (n − j + 1) m g / k and the bottom node hangs at −(n l + m g n(n + 1) / (2k)).
TEST(TissueReference, HangingChainMatchesClosedForm) {
  const int n = 20;
  const double k = 2.0, l = 2.5e-4, m = 1e-5, g = 9.81;
  SpringNetwork net;
  for (int i = 0; i <= n; ++i) {
    // Initial guess: the chain laid out sideways and bent, far from the answer.
    net.positions.emplace_back(0.3 * l * i, 0.0, -0.5 * l * i);
    net.fixed.push_back(i == 0);
    net.loads.emplace_back(0.0, 0.0, i == 0 ? 0.0 : -m * g);
  }
  for (int i = 0; i < n; ++i) {
    net.springs.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(i + 1)});
    net.stiffness.push_back(k);
    net.rest_length.push_back(l);
  }
  const auto solution = solveStatic(net, 1e-14);
  ASSERT_TRUE(solution.converged) << "residual " << solution.residual;
  double z = 0.0;
  for (int j = 1; j <= n; ++j) {
    z -= l + (n - j + 1) * m * g / k;
    EXPECT_NEAR(solution.positions[j].z(), z, 1e-12) << "node " << j;
    EXPECT_NEAR(solution.positions[j].x(), 0.0, 1e-12);
  }
  EXPECT_NEAR(solution.positions[n].z(), -(n * l + m * g * n * (n + 1) / (2 * k)), 1e-12);
}

// A string pinned at both ends, loaded at its midpoint by a force F: with two springs of rest length l between
// anchors 2a apart, the midpoint sags by h where 2 k (L − l) h / L = F, L = √(a² + h²).
TEST(TissueReference, LoadedStringMatchesClosedForm) {
  const double k = 2.0, l = 1e-3, a = 1e-3, force = 1e-3;
  SpringNetwork net;
  net.positions = {{-a, 0, 0}, {0, 0, -1e-4}, {a, 0, 0}};
  net.fixed = {1, 0, 1};
  net.loads = {{0, 0, 0}, {0, 0, -force}, {0, 0, 0}};
  net.springs = {{0, 1}, {1, 2}};
  net.stiffness = {k, k};
  net.rest_length = {l, l};
  const auto solution = solveStatic(net, 1e-15);
  ASSERT_TRUE(solution.converged);
  const double h = -solution.positions[1].z();
  const double length = std::hypot(a, h);
  EXPECT_NEAR(2.0 * k * (length - l) * h / length, force, 1e-13);
  EXPECT_GT(h, 0.0);
}

}  // namespace
