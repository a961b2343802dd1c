// The tissue simulator: time budget, collision response (ε-shell, eq. 5.12), grasping, plasticity, adhesion,
// watchdog, and the hard-case suite of issue 3 for every integrator.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <functional>
#include <new>

#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/tissue_simulator.h"

// Counts heap allocations (replaces the global operator new of this test binary) for the no-allocation test.
static long g_allocations = 0;
void* operator new(std::size_t size) {
  ++g_allocations;
  if (void* p = std::malloc(size > 0 ? size : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
// Every other form too: under ASan an operator left to the runtime (std::stable_sort's nothrow new, new[]) allocates
// with ASan's own and is then freed by ours, an alloc-dealloc mismatch. In a plain build they call the ones above.
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  ++g_allocations;
  return std::malloc(size > 0 ? size : 1);
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new[](std::size_t size, const std::nothrow_t& tag) noexcept { return operator new(size, tag); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

namespace vrm_sim {
namespace tissue {
namespace {

constexpr double kSize = 0.005;  // the thesis' membrane: 5 mm, k = 2 N/m, 1e-5 kg per node
constexpr double kStiffness = 2.0;
constexpr double kNodeMass = 1e-5;

double zeroClock() { return 0.0; }

TissueConfig defaultConfig(const std::string& integrator) {
  TissueConfig config;
  config.integrator = integrator;
  config.dt = 1e-3;
  config.forces.damping = 2e-3;
  config.integrator_options.cg_max_iterations = 20;
  return config;
}

InstrumentInput sphereAt(const Eigen::Vector3d& tip, double radius = 3e-4) {
  InstrumentInput instrument;
  instrument.pose.translation() = tip;
  instrument.radius = radius;
  instrument.length = 0.0;
  return instrument;
}

// Forceps pointing down (-z world = +z instrument), tip at `tip`.
InstrumentInput forcepsAt(const Eigen::Vector3d& tip, double jaw_angle) {
  InstrumentInput instrument;
  instrument.pose.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  instrument.pose.translation() = tip;
  instrument.radius = 3e-4;
  instrument.length = 0.01;
  instrument.can_grasp = true;
  instrument.collides = false;  // the forceps' shaft is above the membrane; the jaws grasp
  instrument.jaw_angle = jaw_angle;
  instrument.jaw_length = 1e-3;
  return instrument;
}

bool allFinite(mge::Membrane& membrane) {
  for (std::size_t i = 0; i < membrane.nodeCount(); ++i) {
    if (!membrane.positions()[i].allFinite() || !membrane.velocities()[i].allFinite()) return false;
  }
  return true;
}

std::size_t centreNode(int cells) { return static_cast<std::size_t>(cells / 2) * (cells + 2); }

TEST(TissueSimulator, RejectsBadConfiguration) {
  auto membrane = makeGridMembrane(4, kSize, kStiffness, kNodeMass);
  TissueConfig config = defaultConfig("no_such_integrator");
  EXPECT_THROW(TissueSimulator(*membrane, config), std::invalid_argument);
  config = defaultConfig("rk2");
  config.dt = 0.0;
  EXPECT_THROW(TissueSimulator(*membrane, config), std::invalid_argument);
  membrane->positions()[7].x() = std::nan("");
  EXPECT_THROW(TissueSimulator(*membrane, defaultConfig("rk2")), std::invalid_argument);
}

TEST(TissueSimulator, TimeBudgetLimitsStepsAndReportsSimulatedTime) {
  auto membrane = makeGridMembrane(8, kSize, kStiffness, kNodeMass);
  TissueConfig config = defaultConfig("explicit_euler");
  config.dt = 1e-4;
  config.time_budget_ms = 2.0;
  TissueSimulator simulator(*membrane, config);
  double fake_now = 0.0;
  const Clock clock = [&]() { return fake_now += 4e-4; };  // every reading 0.4 ms later
  const FrameReport limited = simulator.advance(0.01, clock);
  EXPECT_TRUE(limited.budget_exhausted);
  EXPECT_GT(limited.steps, 0);
  EXPECT_LT(limited.steps, 100);
  EXPECT_NEAR(limited.simulated_time, limited.steps * config.dt, 1e-12);
  EXPECT_GE(limited.wall_time, 2e-3);

  const FrameReport unlimited = simulator.advance(0.01, zeroClock);
  EXPECT_FALSE(unlimited.budget_exhausted);
  EXPECT_EQ(unlimited.steps, 100);
  EXPECT_NEAR(unlimited.simulated_time, 0.01, 1e-12);
  // A frame shorter than dt is carried over, not dropped.
  EXPECT_EQ(simulator.advance(0.5e-4, zeroClock).steps, 0);
  EXPECT_EQ(simulator.advance(0.5e-4, zeroClock).steps, 1);
}

TEST(TissueSimulator, DeterministicForTheSameInput) {
  auto run = [] {
    auto membrane = makeGridMembrane(12, kSize, kStiffness, kNodeMass);
    TissueSimulator simulator(*membrane, defaultConfig("quasi_static_euler"));
    for (int frame = 0; frame < 20; ++frame) {
      simulator.setInstruments({sphereAt(Eigen::Vector3d(0.0, 0.0, 6e-4 - frame * 5e-5))});
      simulator.advance(0.005, zeroClock);
    }
    std::vector<double> state;
    for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
      for (int c = 0; c < 3; ++c) state.push_back(membrane->positions()[i][c]);
    }
    return state;
  };
  EXPECT_EQ(run(), run());
}

TEST(TissueContact, VelocityCorrectionEq512) {
  auto chain = makeChain(1, 1.0, 1e-3, 0.01);
  std::vector<std::uint8_t> constrained{1, 0};
  const SystemView system = viewOf(*chain, constrained.data());
  NodeDeformation contact;
  contact.node = 1;
  contact.normal = Eigen::Vector3d::UnitZ();
  contact.instrument_velocity = Eigen::Vector3d(0.1, 0.0, 0.5);  // v_P,E = (0.1, 0, 0)
  // Moving into the instrument: the normal part is removed, friction drags along E.
  chain->velocities()[1] = Eigen::Vector3d(0.0, 0.2, -1.0);
  applyDeformations(system, {contact}, 0.5);
  EXPECT_TRUE(chain->velocities()[1].isApprox(Eigen::Vector3d(0.05, 0.2, 0.0)));
  // Moving away: v + f_R·v_P,E.
  chain->velocities()[1] = Eigen::Vector3d(0.0, 0.0, 1.0);
  applyDeformations(system, {contact}, 0.5);
  EXPECT_TRUE(chain->velocities()[1].isApprox(Eigen::Vector3d(0.05, 0.0, 1.0)));
}

TEST(TissueContact, EpsilonShellDetectsButOnlyPenetrationMoves) {
  auto chain = makeChain(2, 1.0, 1e-3, 0.01);
  std::vector<std::uint8_t> constrained{1, 0, 0};
  const SystemView system = viewOf(*chain, constrained.data());
  Capsule sphere;
  sphere.radius = 0.001;
  sphere.a = sphere.b = Eigen::Vector3d(0.01, 0.0, 0.00103);  // node 1 inside the 1.05 shell, outside the sphere
  chain->positions()[2] = Eigen::Vector3d(0.02, 0.0, 0.0);
  std::vector<NodeDeformation> contacts;
  detectCapsuleContacts(system, sphere, Eigen::Vector3d::Zero(), 1.05, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_EQ(contacts[0].node, 1u);
  EXPECT_EQ(contacts[0].deformation.norm(), 0.0);
  sphere.a = sphere.b = Eigen::Vector3d(0.01, 0.0, 0.0005);
  contacts.clear();
  detectCapsuleContacts(system, sphere, Eigen::Vector3d::Zero(), 1.05, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  applyDeformations(system, contacts, 0.0);
  EXPECT_NEAR((chain->positions()[1] - sphere.a).norm(), 0.001, 1e-12);
}

TEST(TissueSimulator, InstrumentPushesMembraneAndNoNodeStaysInside) {
  const int cells = 16;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueSimulator simulator(*membrane, defaultConfig("quasi_static_euler"));
  const double radius = 4e-4;
  Eigen::Vector3d tip(0.0, 0.0, radius + 1e-4);
  for (int frame = 0; frame < 40; ++frame) {
    tip.z() -= 2e-5;  // 1 mm/s, 0.8 mm down in total
    simulator.setInstruments({sphereAt(tip, radius)});
    simulator.advance(0.02, zeroClock);
    for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
      ASSERT_GE((membrane->positions()[i] - tip).norm(), radius - 1e-9) << "node " << i << " frame " << frame;
    }
  }
  EXPECT_LT(membrane->positions()[centreNode(cells)].z(), -2e-4);
  EXPECT_EQ(simulator.statistics().unrecovered, 0u);
}

TEST(TissueSimulator, GraspPullReleaseReturnsTowardRest) {
  const int cells = 16;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueSimulator simulator(*membrane, defaultConfig("quasi_static_euler"));
  const std::size_t centre = centreNode(cells);
  Eigen::Vector3d tip(0.0, 0.0, -2e-4);  // jaws straddle the membrane plane (jaw centre 0.3 mm above the tip)
  simulator.setInstruments({forcepsAt(tip, 0.5)});
  simulator.advance(0.01, zeroClock);
  EXPECT_TRUE(simulator.graspedNodes().empty());
  simulator.setInstruments({forcepsAt(tip, 0.0)});
  simulator.advance(0.01, zeroClock);
  ASSERT_FALSE(simulator.graspedNodes().empty());
  for (int frame = 0; frame < 50; ++frame) {  // pull up 1 mm at 2 cm/s
    tip.z() += 2e-5;
    simulator.setInstruments({forcepsAt(tip, 0.0)});
    simulator.advance(0.001, zeroClock);
  }
  const double lifted = membrane->positions()[centre].z();
  EXPECT_GT(lifted, 7e-4);
  EXPECT_LE(simulator.maxStrain(), 3.0);
  simulator.setInstruments({forcepsAt(tip, 0.5)});  // release
  simulator.advance(0.01, zeroClock);
  EXPECT_TRUE(simulator.graspedNodes().empty());
  for (int frame = 0; frame < 100; ++frame) simulator.advance(0.01, zeroClock);
  // Near flat the restoring force is only cubic in the sag (no pre-tension), so "toward rest" is slow.
  EXPECT_LT(std::abs(membrane->positions()[centre].z()), 0.5 * lifted);
  EXPECT_TRUE(allFinite(*membrane));
}

TEST(TissueSimulator, GraspedNodesProjectedOntoJawMidPlane) {
  const int cells = 16;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueConfig config = defaultConfig("quasi_static_euler");
  config.grasp_radius = 4e-4;
  TissueSimulator simulator(*membrane, config);
  // Forceps lying in the membrane plane along -y... instrument pointing along +x world, jaws open along ±y local.
  InstrumentInput forceps = forcepsAt(Eigen::Vector3d(0.0, 0.0, -2e-4), 0.1);  // grasps, no projection yet
  simulator.setInstruments({forceps});
  simulator.advance(0.001, zeroClock);
  ASSERT_GT(simulator.graspedNodes().size(), 1u);
  forceps.jaw_angle = 0.0;  // closes fully: nodes pressed onto the mid-plane (instrument xz plane = world y = 0)
  simulator.setInstruments({forceps});
  simulator.advance(0.001, zeroClock);
  for (std::uint32_t node : simulator.graspedNodes()) EXPECT_NEAR(membrane->positions()[node].y(), 0.0, 1e-12);
}

TEST(TissueSimulator, PlasticRestLengthsFollowTheMaximum) {
  const int cells = 8;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueConfig config = defaultConfig("quasi_static_euler");
  config.plastic = true;
  config.strain_limit = 1.2;
  std::vector<double> rest_before(membrane->restLengths(), membrane->restLengths() + membrane->springCount());
  TissueSimulator simulator(*membrane, config);
  for (int frame = 0; frame < 30; ++frame) {
    simulator.setInstruments({sphereAt(Eigen::Vector3d(0.0, 0.0, 7e-4 - frame * 4e-5), 6e-4)});
    simulator.advance(0.01, zeroClock);
  }
  int grown = 0;
  for (std::size_t s = 0; s < membrane->springCount(); ++s) {
    EXPECT_GE(membrane->restLengths()[s], rest_before[s]);
    grown += membrane->restLengths()[s] > rest_before[s] * 1.01;
  }
  EXPECT_GT(grown, 0);
}

TEST(TissueSimulator, AdhesionAnchorsHoldTheFixedNodesElastically) {
  const int cells = 8;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueConfig config = defaultConfig("implicit_euler");
  config.adhesion_stiffness = 5.0;
  config.forces.gravity = Eigen::Vector3d(0.0, 0.0, -9.81 * 10.0);  // a strong load so the anchors give
  TissueSimulator simulator(*membrane, config);
  EXPECT_EQ(simulator.forceModel().anchors.size(), static_cast<std::size_t>(4 * cells));
  for (int frame = 0; frame < 50; ++frame) simulator.advance(0.01, zeroClock);
  EXPECT_LT(membrane->positions()[0].z(), -1e-6);  // a border (adhesion) node moved
  EXPECT_TRUE(allFinite(*membrane));
}

TEST(TissueSimulator, TopologyChangeKeepsSimulating) {
  const int cells = 8;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueSimulator simulator(*membrane, defaultConfig("implicit_euler"));
  simulator.setInstruments({sphereAt(Eigen::Vector3d(0.0, 0.0, 2e-4))});
  simulator.advance(0.01, zeroClock);
  for (int k = 0; k < 6; ++k) membrane->removeTriangle(membrane->triangleAtSlot(membrane->triangleCount() / 2));
  simulator.onTopologyChanged();
  simulator.advance(0.05, zeroClock);
  EXPECT_TRUE(membrane->checkConsistency().ok());
  EXPECT_TRUE(allFinite(*membrane));
}

TEST(TissueSimulator, EarlyStopEndsTheFrameOnceForcesFallBelowTheBound) {
  const int cells = 12;
  auto run = [&](double bound, int frames, const std::function<void(TissueSimulator&, int)>& instruments) {
    auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
    TissueConfig config = defaultConfig("quasi_static_euler");
    config.early_stop_force = bound;
    TissueSimulator simulator(*membrane, config);
    FrameReport report;
    for (int frame = 0; frame < frames; ++frame) {
      instruments(simulator, frame);
      report = simulator.advance(0.02, zeroClock);  // 20 steps planned per frame
    }
    return std::make_pair(report, membrane->positions()[centreNode(cells)]);
  };
  // A sphere pressed 0.2 mm into the membrane from above, then held still (its centre lies `radius` behind the tip).
  const double radius = 4e-4;
  const auto press = [&](TissueSimulator& simulator, int frame) {
    const double depth = std::min(frame, 10) * 2e-5;
    simulator.setInstruments({sphereAt(Eigen::Vector3d(0.0, 0.0, 2.0 * radius - depth), radius)});
  };
  const auto [full, full_centre] = run(0.0, 60, press);
  EXPECT_FALSE(full.early_stopped);
  EXPECT_EQ(full.steps, 20);
  const auto [stopped, stopped_centre] = run(1e-6, 60, press);
  EXPECT_TRUE(stopped.early_stopped);
  EXPECT_LT(stopped.steps, 20);
  EXPECT_NEAR(stopped.simulated_time, stopped.steps * 1e-3, 1e-12);
  // At equilibrium the skipped steps would not have moved it (the contact nodes are held by the sphere).
  EXPECT_NEAR(stopped_centre.z(), full_centre.z(), 1e-6);
  EXPECT_LT(stopped_centre.z(), -1e-4);
  // A moving instrument never stops a frame early: it must reach its end-of-frame pose.
  const auto [moving, moving_centre] = run(1e-6, 20, [&](TissueSimulator& simulator, int frame) {
    simulator.setInstruments({sphereAt(Eigen::Vector3d(1e-5 * frame, 0.0, 2.0 * radius - 2e-4), radius)});
  });
  EXPECT_FALSE(moving.early_stopped);
  EXPECT_EQ(moving.steps, 20);
}

TEST(TissueSimulator, StepsAllocateNothingOnceRunning) {
  // Issue 3: no allocation inside a step. A sphere pressing and forceps holding a grasp, for every integrator.
  for (const std::string& name : integratorNames()) {
    auto membrane = makeGridMembrane(22, kSize, kStiffness, kNodeMass);
    TissueSimulator simulator(*membrane, defaultConfig(name));
    InstrumentInput forceps = forcepsAt(Eigen::Vector3d(1e-3, 0.0, -2e-4), 0.0);
    simulator.setInstruments({sphereAt(Eigen::Vector3d(0.0, 0.0, 6e-4), 4e-4), forceps});
    for (int frame = 0; frame < 20; ++frame) simulator.advance(1e-3, zeroClock);  // grasp, first contacts
    ASSERT_FALSE(simulator.graspedNodes().empty());
    ASSERT_FALSE(simulator.lastContacts().empty());
    const long before = g_allocations;
    for (int frame = 0; frame < 50; ++frame) simulator.advance(1e-3, zeroClock);
    EXPECT_EQ(g_allocations - before, 0) << name;
  }
}

// --- Watchdog ---

TEST(TissueWatchdog, ExplicitEulerFiveTimesTheBoundIsRescued) {
  const int cells = 12;
  for (bool watchdog : {false, true}) {
    auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
    TissueConfig config = defaultConfig("symplectic_euler");
    config.forces.damping = 0.0;
    config.strain_limit = 0.0;
    config.watchdog.enabled = watchdog;
    std::vector<std::uint8_t> fixed(membrane->fixedFlags(), membrane->fixedFlags() + membrane->nodeCount());
    ForceModel none;
    config.dt = 5.0 * explicitStabilityBound(viewOf(*membrane, fixed.data()), none);
    TissueSimulator simulator(*membrane, config);
    membrane->positions()[centreNode(cells)].z() += 1e-4;  // a kick
    for (int frame = 0; frame < 30; ++frame) simulator.advance(5.0 * config.dt, zeroClock);
    if (watchdog) {
      EXPECT_TRUE(allFinite(*membrane));
      EXPECT_GT(simulator.statistics().fallbacks, 0u);
      EXPECT_EQ(simulator.statistics().unrecovered, 0u);
      EXPECT_LT(simulator.maxStrain(), 2.0);
    } else {
      EXPECT_TRUE(!allFinite(*membrane) || simulator.maxStrain() > 10.0);
    }
  }
}

TEST(TissueWatchdog, UnstableStepIsCaughtWithinThreeSteps) {
  // Explicit Euler at 5× the eq. 5.6 bound, no instrument, a kick: the energy balance rejects the step that gains
  // energy nobody gave within 3 steps; the halvings recover it.
  const int cells = 12;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueConfig config = defaultConfig("explicit_euler");
  config.forces.damping = 0.0;
  std::vector<std::uint8_t> fixed(membrane->fixedFlags(), membrane->fixedFlags() + membrane->nodeCount());
  config.dt = 5.0 * explicitStabilityBound(viewOf(*membrane, fixed.data()), ForceModel{});
  TissueSimulator simulator(*membrane, config);
  membrane->positions()[centreNode(cells)].z() += 1e-4;
  int first_rejection = 0;
  for (int step = 1; step <= 30; ++step) {
    simulator.step();
    if (first_rejection == 0 && simulator.statistics().fallbacks > 0) first_rejection = step;
  }
  EXPECT_GE(first_rejection, 1);
  EXPECT_LE(first_rejection, 3);
  EXPECT_GT(simulator.statistics().energy_growth, 0u);
  EXPECT_EQ(simulator.statistics().unrecovered, 0u);
  EXPECT_TRUE(allFinite(*membrane));
  EXPECT_LT(simulator.maxStrain(), 2.0);
}

TEST(TissueWatchdog, GraspAndYankAreNotInstabilities) {
  // Energy put in by the instrument (the grasp pressing nodes onto the jaw plane, a 0.6 m/s yank) is given energy:
  // at a stable dt no integrator falls back.
  for (const std::string& name : integratorNames()) {
    const int cells = 22;
    auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
    TissueSimulator simulator(*membrane, defaultConfig(name));
    Eigen::Vector3d tip(0.0, 0.0, -2e-4);
    simulator.setInstruments({forcepsAt(tip, 0.0)});
    for (int frame = 0; frame < 10; ++frame) {  // grasp and lift at 20 mm/s
      tip.z() += 2e-5;
      simulator.setInstruments({forcepsAt(tip, 0.0)});
      simulator.advance(1e-3, zeroClock);
    }
    ASSERT_FALSE(simulator.graspedNodes().empty()) << name;
    for (int frame = 0; frame < 5; ++frame) {  // the yank: 0.6 m/s sideways and up
      tip += Eigen::Vector3d(4.8e-4, 0.0, 3.6e-4);
      simulator.setInstruments({forcepsAt(tip, 0.0)});
      simulator.advance(1e-3, zeroClock);
    }
    EXPECT_EQ(simulator.statistics().fallbacks, 0u) << name;
    EXPECT_EQ(simulator.statistics().unrecovered, 0u) << name;
    EXPECT_TRUE(allFinite(*membrane)) << name;
  }
}

// --- Hard cases (issue 3), for every integrator ---

class TissueHardCases : public ::testing::TestWithParam<std::string> {};

void expectStable(TissueSimulator& simulator, mge::Membrane& membrane, double max_strain) {
  EXPECT_TRUE(allFinite(membrane));
  EXPECT_EQ(simulator.statistics().unrecovered, 0u);
  EXPECT_LT(simulator.maxStrain(), max_strain);
}

TEST_P(TissueHardCases, StiffnessRatio1e4) {
  const int cells = 16;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  for (std::size_t s = 0; s < membrane->springCount(); ++s) {
    const auto& e = membrane->springNodeSlots()[s];
    if (membrane->positions()[e[0]].x() > 0.0) membrane->stiffnesses()[s] *= 1e4;  // one half 10^4 stiffer
  }
  TissueSimulator simulator(*membrane, defaultConfig(GetParam()));
  for (int frame = 0; frame < 20; ++frame) {
    simulator.setInstruments({sphereAt(Eigen::Vector3d(-1e-3, 0.0, 4e-4 - frame * 3e-5))});
    simulator.advance(0.005, zeroClock);
  }
  expectStable(simulator, *membrane, 3.0);
}

TEST_P(TissueHardCases, MassRatio1To1000) {
  const int cells = 16;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  // Masses are read-only in the array API; the heavy half is set through the MGE nodes.
  for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
    if (membrane->positions()[i].x() > 0.0) membrane->nodeAtSlot(i).mass() *= 1e3;
  }
  TissueSimulator simulator(*membrane, defaultConfig(GetParam()));
  for (int frame = 0; frame < 20; ++frame) {
    simulator.setInstruments({sphereAt(Eigen::Vector3d(-1e-3, 0.0, 4e-4 - frame * 3e-5))});
    simulator.advance(0.005, zeroClock);
  }
  expectStable(simulator, *membrane, 3.0);
}

TEST_P(TissueHardCases, DtFiveTimesTheExplicitBound) {
  const int cells = 12;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueConfig config = defaultConfig(GetParam());
  std::vector<std::uint8_t> fixed(membrane->fixedFlags(), membrane->fixedFlags() + membrane->nodeCount());
  config.dt = 5.0 * explicitStabilityBound(viewOf(*membrane, fixed.data()), ForceModel{});
  TissueSimulator simulator(*membrane, config);
  for (int frame = 0; frame < 20; ++frame) {
    simulator.setInstruments({sphereAt(Eigen::Vector3d(0.0, 0.0, 4e-4 - frame * 3e-5))});
    simulator.advance(config.dt, zeroClock);
  }
  expectStable(simulator, *membrane, 3.0);
}

TEST_P(TissueHardCases, FastGraspAndPull) {
  const int cells = 16;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueSimulator simulator(*membrane, defaultConfig(GetParam()));
  Eigen::Vector3d tip(0.0, 0.0, -2e-4);
  simulator.setInstruments({forcepsAt(tip, 0.0)});
  simulator.advance(0.001, zeroClock);
  ASSERT_FALSE(simulator.graspedNodes().empty());
  for (int frame = 0; frame < 20; ++frame) {  // 0.1 m/s up and sideways for 20 ms (2 mm)
    tip += Eigen::Vector3d(0.5e-4, 0.0, 0.866e-4);
    simulator.setInstruments({forcepsAt(tip, 0.0)});
    simulator.advance(0.001, zeroClock);
  }
  // Strain limiting keeps the far field intact; only springs at the jaws may exceed τ_c.
  expectStable(simulator, *membrane, 4.0);
  simulator.setInstruments({forcepsAt(tip, 0.5)});
  for (int frame = 0; frame < 20; ++frame) simulator.advance(0.005, zeroClock);
  expectStable(simulator, *membrane, 2.0);
}

TEST_P(TissueHardCases, InstrumentPushedThroughTheMembrane) {
  const int cells = 16;
  auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass);
  TissueSimulator simulator(*membrane, defaultConfig(GetParam()));
  for (int frame = 0; frame < 60; ++frame) {  // 6 mm down at 0.1 m/s: far beyond what the membrane can follow
    simulator.setInstruments({sphereAt(Eigen::Vector3d(1e-5, 2e-5, 5e-4 - frame * 1e-4), 3e-4)});
    simulator.advance(0.001, zeroClock);
  }
  for (int frame = 0; frame < 20; ++frame) simulator.advance(0.005, zeroClock);
  expectStable(simulator, *membrane, 2.0);
}

TEST_P(TissueHardCases, DegenerateTrianglesAndZeroLengthSprings) {
  TriangleMesh mesh = makeGridMesh(8, kSize, true);
  // A zero-area sliver (three collinear vertices) and a duplicated vertex (zero-length edge).
  const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
  mesh.vertices.push_back(mesh.vertices[40]);
  mesh.vertices.push_back(0.5 * (mesh.vertices[40] + mesh.vertices[41]));
  mesh.triangles.push_back({40, 41, base + 1});
  mesh.triangles.push_back({40, base, 49});
  mge::MembraneOptions options;
  options.stretch_stiffness = kStiffness;
  options.total_mass = kNodeMass * mesh.vertexCount();
  auto membrane = mge::buildMembrane(mesh, options);
  // The duplicated vertex and the sliver's apex lie only in zero-area triangles: no lumped mass -> clear error ...
  try {
    TissueSimulator rejected(*membrane, defaultConfig(GetParam()));
    ADD_FAILURE() << "massless nodes accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("no positive mass"), std::string::npos);
  }
  // ... or handled on request; the zero-length spring (duplicated vertex) must not produce NaN.
  TissueConfig config = defaultConfig(GetParam());
  config.repair_massless_nodes = true;
  TissueSimulator simulator(*membrane, config);
  for (int frame = 0; frame < 20; ++frame) {
    simulator.setInstruments({sphereAt(Eigen::Vector3d(0.0, 0.0, 4e-4 - frame * 3e-5))});
    simulator.advance(0.005, zeroClock);
  }
  expectStable(simulator, *membrane, 3.0);
}

INSTANTIATE_TEST_SUITE_P(AllIntegrators, TissueHardCases, ::testing::ValuesIn(integratorNames()),
                         [](const ::testing::TestParamInfo<std::string>& info) { return info.param; });

TEST(TissueHardCasesLarge, Membranes64And128) {
  for (int cells : {64, 128}) {
    for (const char* name : {"quasi_static_euler", "implicit_euler"}) {
      auto membrane = makeGridMembrane(cells, kSize, kStiffness, kNodeMass / ((cells / 16.0) * (cells / 16.0)));
      TissueConfig config = defaultConfig(name);
      config.integrator_options.cg_max_iterations = 10;
      // Refinement shrinks the explicit bound (eq. 5.6, 5.20); quasi-static Euler needs Δt below it too.
      std::vector<std::uint8_t> fixed(membrane->fixedFlags(), membrane->fixedFlags() + membrane->nodeCount());
      config.dt = std::min(1e-3, 0.5 * explicitStabilityBound(viewOf(*membrane, fixed.data()), ForceModel{}));
      TissueSimulator simulator(*membrane, config);
      for (int frame = 0; frame < 10; ++frame) {
        simulator.setInstruments({sphereAt(Eigen::Vector3d(0.0, 0.0, 4e-4 - frame * 5e-5))});
        simulator.advance(0.002, zeroClock);
      }
      expectStable(simulator, *membrane, 4.0);
      EXPECT_EQ(simulator.statistics().fallbacks, 0u) << cells << " " << name;
      EXPECT_LT(membrane->positions()[centreNode(cells)].z(), 0.0) << cells << " " << name;
    }
  }
}

}  // namespace
}  // namespace tissue
}  // namespace vrm_sim
