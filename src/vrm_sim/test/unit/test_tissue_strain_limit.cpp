// Provot strain limiting (Alg. 5.1) and BFS spring sorting (Alg. 5.2).
#include <gtest/gtest.h>

#include <random>
#include <set>

#include "vrm_sim/mge/labels.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/mge/neighbour_slots.h"
#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/strain_limit.h"

namespace vrm_sim {
namespace tissue {
namespace {

std::vector<std::uint8_t> fixedFlags(const mge::Membrane& membrane) {
  return std::vector<std::uint8_t>(membrane.fixedFlags(), membrane.fixedFlags() + membrane.nodeCount());
}

double maxFreeStrain(const SystemView& system) {
  double strain = 0.0;
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    const auto& e = system.springs[s];
    if (!system.isFree(e[0]) && !system.isFree(e[1])) continue;
    strain = std::max(strain, (system.positions[e[1]] - system.positions[e[0]]).norm() / system.rest_lengths[s]);
  }
  return strain;
}

TEST(TissueStrainLimit, PostconditionNoSpringAboveLimitExceptBetweenFixedNodes) {
  auto membrane = makeGridMembrane(16, 0.005, 2.0, 1e-5);
  std::mt19937 random(3);
  std::uniform_real_distribution<double> noise(-2e-4, 2e-4);
  auto constrained = fixedFlags(*membrane);
  // Random large deformation of the free nodes; one fixed corner pulled out so springs between two fixed nodes are
  // over-stretched too (and must be left alone).
  for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
    if (!constrained[i]) membrane->positions()[i] += Eigen::Vector3d(noise(random), noise(random), 3.0 * noise(random));
  }
  membrane->positions()[0] += Eigen::Vector3d(-1e-4, -1e-4, 0.0);
  const SystemView system = viewOf(*membrane, constrained.data());
  const double tau = 1.1;
  ASSERT_GT(maxFreeStrain(system), 1.5);
  int passes = 0;
  ProvotStatistics stats;
  do {
    stats = provotPass(system, tau);
    ++passes;
  } while (stats.corrected > 0 && passes < 500);
  EXPECT_LT(passes, 500);
  EXPECT_GT(stats.skipped_fixed, 0u);
  EXPECT_LE(maxFreeStrain(system), tau + 1e-9);
  for (std::size_t i = 0; i < system.node_count; ++i) ASSERT_TRUE(system.positions[i].allFinite());
}

TEST(TissueStrainLimit, FixedEndDoesNotMoveAndFreeEndIsPulledIn) {
  auto chain = makeChain(1, 1.0, 1e-3, 0.01);
  chain->positions()[1].x() = 0.02;
  auto constrained = fixedFlags(*chain);
  provotPass(viewOf(*chain, constrained.data()), 1.1);
  EXPECT_DOUBLE_EQ(chain->positions()[0].x(), 0.0);
  EXPECT_NEAR(chain->positions()[1].x(), 0.011, 1e-12);
}

// Provot (1995) makes the velocities agree with the corrected positions. Without it a node the pass pulled back keeps
// the velocity that over-stretched the spring, the next integration throws it out again, and an instability grows under
// the limit where the energy watchdog does not see it (issue 40: the shipped peel's slow pull tore with explicit Euler
// and XPBD). A corrected node loses the velocity component against its correction, nothing else.
TEST(TissueStrainLimit, CorrectionStopsTheVelocityAgainstIt) {
  auto chain = makeChain(1, 1.0, 1e-3, 0.01);
  chain->positions()[1].x() = 0.02;
  chain->velocities()[1] = Eigen::Vector3d(0.3, 0.2, 0.0);  // outwards along the spring, and sideways
  auto constrained = fixedFlags(*chain);
  provotPass(viewOf(*chain, constrained.data()), 1.1, nullptr, false, chain->velocities());
  EXPECT_NEAR(chain->positions()[1].x(), 0.011, 1e-12);
  EXPECT_DOUBLE_EQ(chain->velocities()[1].x(), 0.0);
  EXPECT_DOUBLE_EQ(chain->velocities()[1].y(), 0.2);
  // A node already moving along its correction keeps its velocity (the stop never adds energy).
  chain->positions()[1].x() = 0.02;
  chain->velocities()[1] = Eigen::Vector3d(-0.3, 0.0, 0.0);
  provotPass(viewOf(*chain, constrained.data()), 1.1, nullptr, false, chain->velocities());
  EXPECT_DOUBLE_EQ(chain->velocities()[1].x(), -0.3);
  // Without velocities the pass is the positional Alg. 5.1 (the test above).
  chain->positions()[1].x() = 0.02;
  chain->velocities()[1] = Eigen::Vector3d(0.3, 0.0, 0.0);
  provotPass(viewOf(*chain, constrained.data()), 1.1);
  EXPECT_DOUBLE_EQ(chain->velocities()[1].x(), 0.3);
}

// Pulling the end of a long chain: one pass in BFS order from the pulled node propagates the deformation along the
// whole chain (ChainMail-like), whereas one pass in array order does not.
TEST(TissueStrainLimit, SortedPassPropagatesInOnePass) {
  const int springs = 50;
  for (bool sorted : {true, false}) {
    auto chain = makeChain(springs, 1.0, 1e-3, 0.001);
    std::vector<std::uint8_t> constrained(springs + 1, 0);
    constrained[springs] = 1;  // the grasped end; node 0 free
    chain->positions()[springs].x() += 0.05;
    const SystemView system = viewOf(*chain, constrained.data());
    SpringSorter sorter;
    sorter.rebuild(system);
    sorter.sort(system, {static_cast<std::uint32_t>(springs)});
    provotPass(system, 1.1, sorted ? &sorter : nullptr, /*outer_only=*/true);
    if (sorted) {
      EXPECT_LE(maxFreeStrain(system), 1.1 + 1e-9);
    } else {
      EXPECT_GT(maxFreeStrain(system), 1.5);
    }
  }
}

TEST(TissueStrainLimit, SortingSetsAreDisjointCompleteAndOrderedByDistance) {
  auto membrane = makeGridMembrane(24, 0.005, 2.0, 1e-5, true, 0.1);
  auto constrained = fixedFlags(*membrane);
  const SystemView system = viewOf(*membrane, constrained.data());
  SpringSorter sorter;
  sorter.rebuild(system);
  const std::vector<std::uint32_t> seeds{300, 301, 325};
  sorter.sort(system, seeds);
  const auto& order = sorter.order();
  const auto& offsets = sorter.levelOffsets();
  const auto& distance = sorter.nodeDistances();
  ASSERT_EQ(order.size(), system.spring_count);
  EXPECT_EQ(std::set<std::uint32_t>(order.begin(), order.end()).size(), system.spring_count);  // each spring once
  EXPECT_EQ(offsets.front(), 0u);
  EXPECT_EQ(offsets.back(), system.spring_count);
  for (std::uint32_t seed : seeds) EXPECT_EQ(distance[seed], 0);
  for (std::size_t level = 0; level + 1 < offsets.size(); ++level) {
    for (std::size_t k = offsets[level]; k < offsets[level + 1]; ++k) {
      const auto& e = system.springs[order[k]];
      const int nearer = std::min(distance[e[0]], distance[e[1]]);
      ASSERT_EQ(nearer, static_cast<int>(level));  // the grid is connected: no unreachable set
      const int inner = sorter.innerIsSecond()[k] ? distance[e[1]] : distance[e[0]];
      EXPECT_EQ(inner, nearer);
      // BFS distances of neighbours differ by at most one.
      EXPECT_LE(std::abs(distance[e[0]] - distance[e[1]]), 1);
    }
  }
  // Sorting again with other seeds reuses the buffers (O(n) per sort, no growth).
  sorter.sort(system, {0});
  EXPECT_EQ(sorter.order().size(), system.spring_count);
}

TEST(TissueStrainLimit, UnreachableSpringsFormTheLastSet) {
  auto chain = makeChain(3, 1.0, 1e-3, 0.001);
  mge::Node& a = chain->addNode(Eigen::Vector3d(1, 1, 1), 1e-3);
  mge::Node& b = chain->addNode(Eigen::Vector3d(1, 1, 1.001), 1e-3);
  chain->addSpring(a, b, 1.0);
  std::vector<std::uint8_t> constrained(chain->nodeCount(), 0);
  const SystemView system = viewOf(*chain, constrained.data());
  SpringSorter sorter;
  sorter.rebuild(system);
  sorter.sort(system, {0});
  const auto& offsets = sorter.levelOffsets();
  EXPECT_EQ(offsets[offsets.size() - 1] - offsets[offsets.size() - 2], 1u);
  EXPECT_EQ(sorter.order().back(), 3u);
}

// The simulator's node → spring adjacency comes from the MGE (NeighbourSlots in slot order); it must equal the one the
// spring arrays give (ascending spring index per node, the order every sorter and the bound solver saw before issue
// 40), on a membrane with bending springs and after cuts that renumber nodes and springs.
TEST(TissueNodeSpringAdjacency, TheGraphsViewEqualsTheSpringArraysAcrossCuts) {
  auto membrane = makeGridMembrane(20, 0.005, 2.0, 1e-5, /*bending=*/true, 0.1);
  using NodeSprings = mge::NeighbourSlots<mge::Node, mge::Spring>;
  NodeSprings view(membrane->tissue(), mge::labels::kNodeList, {mge::referenceLabel(mge::labels::kSpringNodes)},
                   NodeSprings::Layout::kSlotOrder);
  std::mt19937 random(40);
  for (int cut = 0; cut < 12; ++cut) {
    std::vector<std::uint8_t> constrained = fixedFlags(*membrane);
    const SystemView system = viewOf(*membrane, constrained.data());
    ASSERT_TRUE(view.refresh(membrane->graph(), membrane->nodeArrays(), membrane->springArrays()));
    NodeSpringAdjacency from_graph, from_arrays;
    from_graph.adopt(system, view.offsets(), view.neighbourSlots());
    from_arrays.build(system);
    ASSERT_EQ(from_graph.nodeCount(), system.node_count);
    const std::size_t entries = from_arrays.offsets()[system.node_count];
    ASSERT_EQ(entries, 2 * system.spring_count);
    ASSERT_EQ(std::vector<std::uint32_t>(from_graph.offsets(), from_graph.offsets() + system.node_count + 1),
              std::vector<std::uint32_t>(from_arrays.offsets(), from_arrays.offsets() + system.node_count + 1));
    ASSERT_EQ(std::vector<std::uint32_t>(from_graph.springs(), from_graph.springs() + entries),
              std::vector<std::uint32_t>(from_arrays.springs(), from_arrays.springs() + entries));
    ASSERT_EQ(std::vector<std::uint32_t>(from_graph.others(), from_graph.others() + entries),
              std::vector<std::uint32_t>(from_arrays.others(), from_arrays.others() + entries));
    // A cut: a few triangles, a spring and a node, anywhere (removal moves the last slots into the holes).
    std::vector<mge::Triangle*> triangles;
    for (int k = 0; k < 3; ++k) {
      triangles.push_back(&membrane->triangleAtSlot(random() % membrane->triangleCount()));
    }
    std::vector<mge::Spring*> springs{&membrane->springAtSlot(random() % membrane->springCount())};
    std::vector<mge::Node*> nodes{&membrane->nodeAtSlot(random() % membrane->nodeCount())};
    ASSERT_TRUE(membrane->removeElements(triangles, springs, nodes).any());
  }
  EXPECT_TRUE(view.refresh(membrane->graph(), membrane->nodeArrays(), membrane->springArrays()));
  EXPECT_FALSE(view.refresh(membrane->graph(), membrane->nodeArrays(), membrane->springArrays()));  // unchanged
}

}  // namespace
}  // namespace tissue
}  // namespace vrm_sim
