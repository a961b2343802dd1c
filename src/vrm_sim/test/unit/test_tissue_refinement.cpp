// Local refinement at the interaction (thesis §5.2.4): element counts of eqs. 5.16–5.18, mass conservation (5.19),
// virtual nodes on the border, the element budget with LRU coarsening, exact restoration of the coarse topology, the
// static sag of a refined pinned membrane against the unrefined one, and the simulator hook.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/refinement.h"
#include "vrm_sim/tissue/tissue_simulator.h"
#include "vrm_sim/tissue/topology.h"

namespace vrm_sim {
namespace tissue {
namespace {

double totalMass(const mge::Membrane& membrane) {
  double mass = 0.0;
  for (std::size_t i = 0; i < membrane.nodeCount(); ++i) mass += membrane.masses()[i];
  return mass;
}

void expectValid(const mge::Membrane& membrane) {
  const mge::InvariantReport report = checkTopology(membrane);
  ASSERT_TRUE(report.ok()) << report.summary();
}

// The topology by node identity: triangles (rotated to the smallest id first), springs with their parameters, node
// masses and fixed flags.
struct Snapshot {
  std::multiset<std::array<std::uint64_t, 3>> triangles;
  std::multiset<std::tuple<std::uint64_t, std::uint64_t, double, double>> springs;
  std::map<std::uint64_t, std::pair<double, bool>> nodes;
  bool operator==(const Snapshot& other) const {
    return triangles == other.triangles && springs == other.springs && nodes == other.nodes;
  }
};

Snapshot snapshot(const mge::Membrane& membrane) {
  Snapshot result;
  auto id = [&](std::uint32_t slot) { return membrane.nodeAtSlot(slot).id(); };
  for (std::size_t t = 0; t < membrane.triangleCount(); ++t) {
    const auto& c = membrane.triangleNodeSlots()[t];
    std::array<std::uint64_t, 3> ids{id(c[0]), id(c[1]), id(c[2])};
    std::rotate(ids.begin(), std::min_element(ids.begin(), ids.end()), ids.end());
    result.triangles.insert(ids);
  }
  for (std::size_t s = 0; s < membrane.springCount(); ++s) {
    const auto& e = membrane.springNodeSlots()[s];
    const std::uint64_t a = id(e[0]), b = id(e[1]);
    const double rest = membrane.springAtSlot(s).restLength();
    result.springs.insert({std::min(a, b), std::max(a, b), rest, membrane.springAtSlot(s).stiffness()});
  }
  for (std::size_t i = 0; i < membrane.nodeCount(); ++i) {
    result.nodes[id(static_cast<std::uint32_t>(i))] = {membrane.masses()[i], membrane.fixedFlags()[i] != 0};
  }
  return result;
}

TEST(Refinement, CountsFollowEquations516To518) {
  EXPECT_EQ(LocalRefinement::nodesPerTriangle(0), 3u);
  EXPECT_EQ(LocalRefinement::springsPerTriangle(0), 3u);
  EXPECT_EQ(LocalRefinement::trianglesPerTriangle(0), 1u);
  for (int n = 1; n <= 3; ++n) {
    SCOPED_TRACE(n);
    // One isolated triangle: all of its edges are boundary edges, so the counts are exactly eqs. 5.16–5.18.
    TriangleMesh mesh;
    mesh.vertices = {{0.0, 0.0, 0.0}, {1e-3, 0.0, 0.0}, {0.0, 1e-3, 0.0}};
    mesh.triangles = {{0, 1, 2}};
    mge::MembraneOptions options;
    options.total_mass = 3e-5;
    auto membrane = mge::buildMembrane(mesh, options);
    RefinementConfig config;
    config.levels = n;
    LocalRefinement refinement(*membrane, config);
    ASSERT_TRUE(refinement.refineAt(Eigen::Vector3d(3e-4, 3e-4, 0.0), 1));
    const std::size_t s = std::size_t{1} << n;
    EXPECT_EQ(membrane->nodeCount(), (s + 1) * (s + 2) / 2);
    EXPECT_EQ(membrane->springCount(), 3 * s * (s + 1) / 2);
    EXPECT_EQ(membrane->triangleCount(), s * s);
    EXPECT_EQ(refinement.virtualNodeCount(), 0u);
    EXPECT_NEAR(totalMass(*membrane), 3e-5, 1e-18);
    expectValid(*membrane);
    // Rest lengths l0/2ⁿ (eq. 5.15) along the coarse edges.
    for (std::size_t k = 0; k < membrane->springCount(); ++k) {
      const double rest = membrane->restLengths()[k];
      EXPECT_TRUE(std::abs(rest - 1e-3 / s) < 1e-15 || std::abs(rest - std::sqrt(2.0) * 1e-3 / s) < 1e-15) << rest;
    }
  }
}

TEST(Refinement, CoarseningRestoresTheOriginalTopologyExactly) {
  for (int levels : {1, 2}) {
    SCOPED_TRACE(levels);
    auto membrane = makeGridMembrane(8, 8e-3, 2.0, 1e-5, true);
    const Snapshot original = snapshot(*membrane);
    const double mass = totalMass(*membrane);
    RefinementConfig config;
    config.levels = levels;
    config.radius = 1.2e-3;
    config.element_budget = 100000;
    LocalRefinement refinement(*membrane, config);
    std::uint64_t time = 1;
    for (const Eigen::Vector3d& point : {Eigen::Vector3d(0.0, 0.0, 0.0), Eigen::Vector3d(1e-3, 0.5e-3, 0.0),
                                         Eigen::Vector3d(-2.5e-3, 2e-3, 0.0), Eigen::Vector3d(3.5e-3, 3.5e-3, 0.0)}) {
      ASSERT_TRUE(refinement.refineAt(point, time++));
      expectValid(*membrane);
      EXPECT_NEAR(totalMass(*membrane), mass, 1e-15);
      EXPECT_GT(refinement.virtualNodeCount(), 0u);
      EXPECT_EQ(refinement.fineSpringsInUse(),
                refinement.refinedTriangleCount() * LocalRefinement::springsPerTriangle(levels));
    }
    EXPECT_GT(membrane->triangleCount(), 128u);
    // Virtual nodes follow their coarse spring.
    for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
      if (!membrane->fixedFlags()[i])
        membrane->positions()[i].z() += 1e-4 * std::sin(1e3 * membrane->positions()[i].x());
    }
    refinement.updateVirtualNodes();
    ASSERT_TRUE(refinement.coarsenAll());
    expectValid(*membrane);
    EXPECT_EQ(refinement.virtualNodeCount(), 0u);
    EXPECT_EQ(refinement.fineSpringsInUse(), 0u);
    EXPECT_TRUE(snapshot(*membrane) == original);
    EXPECT_EQ(membrane->triangleCount(), 128u);
  }
}

TEST(Refinement, BudgetCoarsensTheLeastRecentlyUsedRegion) {
  auto membrane = makeGridMembrane(8, 8e-3, 2.0, 1e-5, true);
  RefinementConfig config;
  config.levels = 1;
  config.radius = 0.6e-3;  // the two triangles of one cell
  config.element_budget = 4 * LocalRefinement::springsPerTriangle(1);
  LocalRefinement refinement(*membrane, config);
  const Eigen::Vector3d a(-2.5e-3, -2.5e-3, 0.0), b(2.5e-3, -2.5e-3, 0.0), c(2.5e-3, 2.5e-3, 0.0),
      d(-2.5e-3, 2.5e-3, 0.0);
  ASSERT_TRUE(refinement.refineAt(a, 1));
  ASSERT_TRUE(refinement.refineAt(b, 2));
  EXPECT_EQ(refinement.refinedTriangleCount(), 4u);
  EXPECT_EQ(refinement.regionCount(), 2u);
  // Full: refining at c coarsens a (oldest), not b.
  ASSERT_TRUE(refinement.refineAt(c, 3));
  EXPECT_EQ(refinement.regionCount(), 2u);
  EXPECT_LE(refinement.fineSpringsInUse(), config.element_budget);
  // Touching b again makes c the oldest.
  EXPECT_FALSE(refinement.refineAt(b, 4));
  ASSERT_TRUE(refinement.refineAt(d, 5));
  expectValid(*membrane);
  // The refined regions are now b and d: a fine node exists near b and d, none near a and c.
  // A refined cell has a node at the midpoint of its lower edge.
  auto fineNear = [&](const Eigen::Vector3d& point) {
    const Eigen::Vector3d midpoint = point - Eigen::Vector3d(0.0, 0.5e-3, 0.0);
    for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
      if ((membrane->positions()[i] - midpoint).norm() < 1e-9) return true;
    }
    return false;
  };
  EXPECT_TRUE(fineNear(b));
  EXPECT_TRUE(fineNear(d));
  EXPECT_FALSE(fineNear(a));
  EXPECT_FALSE(fineNear(c));
}

TEST(Refinement, RejectsWhatItCannotDo) {
  RefinementConfig config;
  config.levels = 5;
  auto membrane = makeGridMembrane(4, 4e-3, 2.0, 1e-5);
  EXPECT_THROW(LocalRefinement(*membrane, config), std::invalid_argument);
  config.levels = 1;
  config.radius = std::nan("");
  EXPECT_THROW(LocalRefinement(*membrane, config), std::invalid_argument);
  config.radius = 1e-3;
  auto bending = makeGridMembrane(4, 4e-3, 2.0, 1e-5, true, 0.1);
  EXPECT_THROW(LocalRefinement(*bending, config), std::invalid_argument);
  LocalRefinement refinement(*membrane, config);
  EXPECT_FALSE(refinement.refineAt(Eigen::Vector3d(std::nan(""), 0.0, 0.0), 1));
  EXPECT_FALSE(refinement.refineAt(Eigen::Vector3d(1.0, 1.0, 1.0), 1));  // nothing there
}

// Random refinements (with LRU coarsening under a small budget), cuts through refined and coarse regions and full
// coarsening, each followed by the invariant checker.
TEST(Refinement, RandomRefineCutCoarsenSequencesKeepInvariants) {
  std::mt19937 random(5);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int round = 0; round < 4; ++round) {
    auto membrane = makeGridMembrane(8, 8e-3, 2.0, 1e-5, round % 2 == 0);
    RefinementConfig config;
    config.levels = 1 + round % 2;
    config.radius = 1.3e-3;
    config.element_budget = 12 * LocalRefinement::springsPerTriangle(config.levels);
    LocalRefinement refinement(*membrane, config);
    for (int op = 0; op < 100; ++op) {
      const Eigen::Vector3d point = 4e-3 * Eigen::Vector3d(unit(random), unit(random), 0.0);
      const int kind = static_cast<int>(random() % 10);
      if (kind < 7) {
        refinement.refineAt(point, static_cast<std::uint64_t>(op + 1));
      } else if (kind < 9) {
        Capsule cut;
        cut.a = cut.b = point;
        cut.radius = 0.6e-3 * std::abs(unit(random));
        if (cutCapsule(*membrane, cut).any()) refinement.onTopologyChanged();
      } else {
        refinement.coarsenAll();
      }
      ASSERT_LE(refinement.fineSpringsInUse(), config.element_budget);
      const mge::InvariantReport report = checkTopology(*membrane, {true});
      ASSERT_TRUE(report.ok()) << "round " << round << " op " << op << ": " << report.summary();
      for (std::size_t i = 0; i < membrane->nodeCount(); ++i) ASSERT_TRUE(membrane->masses()[i] >= 0.0);
    }
    refinement.coarsenAll();
    EXPECT_EQ(refinement.virtualNodeCount(), 0u);
    EXPECT_EQ(refinement.refinedTriangleCount(), 0u);
    expectValid(*membrane);
  }
}

// Static sag of a pinned membrane under gravity, refined around the centre vs unrefined.
double centreSag(const RefinementConfig& refinement_config, std::size_t* refined_triangles = nullptr) {
  const int cells = 8;
  auto membrane = makeGridMembrane(cells, 8e-3, 2.0, 1e-5, true);
  const std::uint64_t centre_id = membrane->nodeAtSlot((cells / 2) * (cells + 2)).id();
  TissueConfig config;
  config.integrator = "implicit_euler";
  config.integrator_options.cg_max_iterations = 200;
  config.integrator_options.cg_tolerance = 1e-12;
  config.dt = 2e-3;
  config.forces.damping = 5e-3;
  config.forces.gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
  config.strain_limit = 0.0;
  config.refinement = refinement_config;
  TissueSimulator simulator(*membrane, config);
  InstrumentInput marker;  // a non-colliding instrument above the centre: the interaction point
  marker.collides = false;
  marker.pose.translation() = Eigen::Vector3d(0.0, 0.0, 0.0);
  simulator.setInstruments({marker});
  for (int step = 0; step < 3000; ++step) simulator.step();
  double max_speed = 0.0;  // static: converged
  for (std::size_t i = 0; i < membrane->nodeCount(); ++i)
    max_speed = std::max(max_speed, membrane->velocities()[i].norm());
  EXPECT_LT(max_speed, 1e-5);
  if (refined_triangles != nullptr) {
    *refined_triangles = simulator.refinement() ? simulator.refinement()->refinedTriangleCount() : 0;
  }
  expectValid(*membrane);
  for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
    if (membrane->nodeAtSlot(i).id() == centre_id) return -membrane->positions()[i].z();
  }
  ADD_FAILURE() << "centre node lost";
  return 0.0;
}

TEST(Refinement, RefinedMembraneSagsLikeTheCoarseOne) {
  const double coarse = centreSag(RefinementConfig{});
  ASSERT_GT(coarse, 1e-5);
  RefinementConfig config;
  config.levels = 1;
  config.radius = 2.1e-3;
  config.element_budget = 100000;
  std::size_t refined = 0;
  const double fine = centreSag(config, &refined);
  EXPECT_GT(refined, 8u);
  config.chain_stiffness_scaling = true;
  const double chain_scaled = centreSag(config);
  std::printf(
      "centre sag: coarse %.4e m, refined (D(n) = D) %.4e m (%+.1f %%), refined (D(n) = 2^n D, eq. 5.14) "
      "%.4e m (%+.1f %%)\n",
      coarse, fine, 100.0 * (fine / coarse - 1.0), chain_scaled, 100.0 * (chain_scaled / coarse - 1.0));
  EXPECT_NEAR(fine / coarse, 1.0, 0.05);  // tolerance: 5 %
  EXPECT_LT(chain_scaled, fine);          // 5.14 stiffens a triangulated sheet
}

// The simulator refines where the forceps grasp, keeps the grasp across refinements, and the virtual nodes stay on
// their coarse springs while the membrane is pulled.
TEST(Refinement, SimulatorRefinesAtTheGraspAndPulls) {
  auto membrane = makeGridMembrane(8, 8e-3, 2.0, 1e-5, true);
  TissueConfig config;
  config.integrator = "quasi_static_euler";
  config.forces.damping = 2e-3;
  config.refinement.levels = 1;
  config.refinement.radius = 1.5e-3;
  TissueSimulator simulator(*membrane, config);
  InstrumentInput forceps;
  forceps.pose.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  forceps.pose.translation() = Eigen::Vector3d(0.0, 0.0, -0.5e-3);
  forceps.can_grasp = true;
  forceps.collides = false;
  forceps.jaw_angle = 0.0;
  forceps.jaw_length = 1e-3;
  const Clock clock = [] { return 0.0; };
  simulator.setInstruments({forceps});
  simulator.advance(0.001, clock);
  ASSERT_NE(simulator.refinement(), nullptr);
  EXPECT_GT(simulator.refinement()->refinedTriangleCount(), 0u);
  EXPECT_GE(simulator.topologyChanges(), 1u);
  ASSERT_FALSE(simulator.graspedNodes().empty());
  for (int frame = 1; frame <= 20; ++frame) {
    forceps.pose.translation().z() = -0.5e-3 + 5e-5 * frame;
    simulator.setInstruments({forceps});
    simulator.advance(0.002, clock);
  }
  expectValid(*membrane);
  for (std::uint32_t node : simulator.graspedNodes()) EXPECT_NEAR(membrane->positions()[node].z(), 1e-3, 1e-9);
  // Every fixed node that is not on the pinned border is a virtual node: on the segment of its coarse spring.
  std::size_t checked = 0;
  for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
    ASSERT_TRUE(membrane->positions()[i].allFinite());
    if (!membrane->fixedFlags()[i] || membrane->positions()[i].head<2>().lpNorm<Eigen::Infinity>() > 3.99e-3) continue;
    bool on_spring = false;
    for (std::size_t s = 0; s < membrane->springCount() && !on_spring; ++s) {
      const auto& e = membrane->springNodeSlots()[s];
      if (e[0] == i || e[1] == i) continue;
      on_spring =
          segmentDistance(membrane->positions()[i], membrane->positions()[e[0]], membrane->positions()[e[1]]) < 1e-12 &&
          membrane->fixedFlags()[e[0]] == 0;
    }
    EXPECT_TRUE(on_spring) << i;
    ++checked;
  }
  EXPECT_GT(checked, 0u);
}

}  // namespace
}  // namespace tissue
}  // namespace vrm_sim
