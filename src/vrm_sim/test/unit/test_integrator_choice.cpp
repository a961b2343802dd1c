// `integrator: auto` (issue 15 §3): the choice follows the stiffness, masses, damping and dt of the membrane, is made
// again when a grasp changes the free nodes, and the chosen integrator runs the scene without a watchdog fallback.
#include <gtest/gtest.h>

#include <cmath>

#include "vrm_sim/tissue/integrator_choice.h"
#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {
namespace {

constexpr double kSize = 0.005;
constexpr double kStiffness = 2.0;
constexpr double kNodeMass = 1e-5;

IntegratorChoice choiceFor(mge::Membrane& membrane, double dt, double damping = 0.0) {
  std::vector<std::uint8_t> fixed(membrane.fixedFlags(), membrane.fixedFlags() + membrane.nodeCount());
  ForceModel forces;
  forces.params.damping = damping;
  return chooseIntegrator(viewOf(membrane, fixed.data()), forces, dt);
}

TEST(IntegratorChoice, UndampedBoundIsEquation56PerNode) {
  auto membrane = makeGridMembrane(22, kSize, kStiffness, kNodeMass);
  std::vector<std::uint8_t> fixed(membrane->fixedFlags(), membrane->fixedFlags() + membrane->nodeCount());
  const SystemView system = viewOf(*membrane, fixed.data());
  // Uniform masses and stiffnesses: the per-node bound is the thesis' global one.
  EXPECT_NEAR(dampedExplicitBound(system, ForceModel{}), explicitStabilityBound(system, ForceModel{}), 1e-15);
  EXPECT_NEAR(quasiStaticBound(system, ForceModel{}), explicitStabilityBound(system, ForceModel{}), 1e-15);
  // Damping only lowers the symplectic bound; with no spring at all it is 2m/c.
  ForceModel damped;
  damped.params.damping = 2e-3;
  EXPECT_LT(dampedExplicitBound(system, damped), dampedExplicitBound(system, ForceModel{}));
  EXPECT_EQ(quasiStaticBound(system, damped), quasiStaticBound(system, ForceModel{}));
}

TEST(IntegratorChoice, FollowsStiffnessMassDampingAndDt) {
  // The thesis' membrane at 1 ms: explicit, one step.
  auto thesis = makeGridMembrane(22, kSize, kStiffness, kNodeMass);
  IntegratorChoice choice = choiceFor(*thesis, 1e-3);
  EXPECT_EQ(choice.integrator, "symplectic_euler");
  EXPECT_EQ(choice.substeps, 1);
  EXPECT_FALSE(choice.reason.empty());
  // 100×100 (same total mass; lightest free node 3.3e-7 kg): the bound (0.51 ms × 0.8) needs three substeps of
  // 1 ms, more than one implicit Euler step costs; two substeps of 0.8 ms are cheaper.
  auto fine = makeGridMembrane(100, kSize, kStiffness, kNodeMass * std::pow(22.0 / 100.0, 2));
  choice = choiceFor(*fine, 1e-3);
  EXPECT_EQ(choice.integrator, "implicit_euler");
  EXPECT_LT(choice.bound, 1e-3);
  choice = choiceFor(*fine, 8e-4);
  EXPECT_EQ(choice.integrator, "symplectic_euler");
  EXPECT_EQ(choice.substeps, 2);
  // A stiff membrane (×10⁵): hundreds of substeps; implicit Euler.
  auto stiff = makeGridMembrane(22, kSize, kStiffness * 1e5, kNodeMass);
  EXPECT_EQ(choiceFor(*stiff, 1e-3).integrator, "implicit_euler");
  // Light nodes, heavy damping: symplectic Euler's velocity damping overshoots (c·dt/m ≫ 2), quasi-static Euler
  // (velocities reset) is still stable in one step.
  auto light = makeGridMembrane(22, kSize, kStiffness * 1e-2, kNodeMass * 1e-2);
  choice = choiceFor(*light, 1e-3, 2e-3);
  EXPECT_EQ(choice.integrator, "quasi_static_euler");
  EXPECT_EQ(choice.substeps, 1);
  // A larger dt needs more substeps of the same integrator, until implicit Euler is cheaper.
  EXPECT_EQ(choiceFor(*thesis, 3e-3).substeps, 2);  // bound 2.4 ms × 0.8
  EXPECT_EQ(choiceFor(*thesis, 2e-2).integrator, "implicit_euler");
}

TissueConfig autoConfig(double dt) {
  TissueConfig config;
  config.integrator = kAutoIntegrator;
  config.dt = dt;
  config.forces.damping = 2e-3;
  config.integrator_options.cg_max_iterations = 20;
  return config;
}

InstrumentInput forcepsAt(const Eigen::Vector3d& tip, double jaw_angle) {
  InstrumentInput instrument;
  instrument.pose.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  instrument.pose.translation() = tip;
  instrument.can_grasp = true;
  instrument.collides = false;
  instrument.jaw_angle = jaw_angle;
  instrument.jaw_length = 1e-3;
  return instrument;
}

TEST(IntegratorChoice, SimulatorChoosesOnceAndAgainWhenTheFreeNodesChange) {
  auto membrane = makeGridMembrane(40, kSize, kStiffness, kNodeMass * std::pow(22.0 / 40.0, 2));
  TissueSimulator simulator(*membrane, autoConfig(1e-3));
  EXPECT_EQ(simulator.integratorChoiceChanges(), 1u);
  const std::string before = simulator.integratorLabel();
  Eigen::Vector3d tip(0.0, 0.0, -2e-4);
  simulator.setInstruments({forcepsAt(tip, 0.0)});
  for (int frame = 0; frame < 30; ++frame) {
    tip.z() += 2e-5;  // 20 mm/s
    simulator.setInstruments({forcepsAt(tip, 0.0)});
    simulator.advance(1e-3, [] { return 0.0; });
  }
  ASSERT_FALSE(simulator.graspedNodes().empty());
  // Grasped nodes are no longer integrated; the uniform grid keeps its bound, so the choice and its count stay.
  EXPECT_EQ(simulator.integratorLabel(), before);
  EXPECT_EQ(simulator.integratorChoiceChanges(), 1u);
  EXPECT_EQ(simulator.statistics().fallbacks, 0u)
      << simulator.integratorLabel() << ": energy growth " << simulator.statistics().energy_growth << ", over bound "
      << simulator.statistics().over_bound << ", too fast " << simulator.statistics().too_fast;
  // Heavier nodes make the explicit bound larger: a new topology is decided afresh (and counted).
  for (std::size_t i = 0; i < membrane->nodeCount(); ++i) membrane->nodeAtSlot(i).mass() *= 100.0;
  simulator.onTopologyChanged();
  EXPECT_EQ(simulator.integratorChoice().substeps, 1);
}

// The hard cases of bench_tissue that make fixed explicit integrators fall back hundreds of times: `auto` runs them
// without a fallback.
TEST(IntegratorChoice, HardCasesRunWithoutFallback) {
  struct Case {
    const char* name;
    double stiffness, mass, damping, dt;
  };
  for (const Case& c : {Case{"stiff", 2000.0, kNodeMass, 2e-3, 1e-3}, Case{"light_damped", 2.0, 1e-8, 2e-3, 1e-3},
                        Case{"thesis", 2.0, kNodeMass, 2e-3, 1e-3}}) {
    auto membrane = makeGridMembrane(16, kSize, c.stiffness, c.mass);
    TissueConfig config = autoConfig(c.dt);
    config.forces.damping = c.damping;
    TissueSimulator simulator(*membrane, config);
    Eigen::Vector3d tip(0.0, 0.0, -2e-4);
    for (int frame = 0; frame < 40; ++frame) {
      tip.z() += 1e-5;
      simulator.setInstruments({forcepsAt(tip, 0.0)});
      simulator.advance(c.dt, [] { return 0.0; });
    }
    EXPECT_EQ(simulator.statistics().fallbacks, 0u) << c.name << ": " << simulator.integratorChoice().reason;
    EXPECT_EQ(simulator.statistics().unrecovered, 0u) << c.name;
    EXPECT_LT(simulator.maxStrain(), 3.0) << c.name;
  }
}

}  // namespace
}  // namespace tissue
}  // namespace vrm_sim
