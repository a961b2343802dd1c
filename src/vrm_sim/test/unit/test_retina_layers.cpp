// The retina's layers (issue 38): the subretinal fluid under a retina adhering to the eye wall (its volume against
// the spherical geometry, its spread from the puncture), adhesions that peel over time or tear the retina, the
// vitrector's suction holding the hyaloid, the needle that pierces and slices the retina in the World — and the hard
// cases: injection at full flow, a yank of the needle inside, suction on the retina.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>

#include "../support/instrument_at.h"
#include "vrm_scene/meshes/eye_meshes.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/tissue_simulator.h"
#include "vrm_sim/world/mediator.h"
#include "vrm_sim/world/tissue_setup.h"
#include "vrm_sim/world/world.h"

namespace vrm_sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kEye = 0.012;
constexpr double kHeight = 1.5e-4;
constexpr double kWall = kEye - kHeight;  // the sheet rests on this sphere

scene::MembraneParams patch(int rings, bool everywhere) {
  scene::MembraneParams params;
  params.retina_radius = kEye;
  params.height_above_retina = kHeight;
  params.diameter = 0.006;
  params.ring_count = rings;
  params.adhesion_point_count = everywhere ? 0 : 1;
  params.adhere_everywhere = everywhere;
  return params;
}

std::unique_ptr<mge::Membrane> membraneOf(const TriangleMesh& mesh) {
  scene::TissueParameters parameters;
  parameters.model = "mass_spring";
  return mge::buildMembrane(mesh, world::membraneOptionsFor(parameters, mesh.vertexCount()));
}

tissue::TissueConfig fluidConfig() {
  tissue::TissueConfig config;
  config.integrator = "auto";
  config.dt = 1e-3;
  config.forces.damping = 0.01;
  config.strain_limit = 1.15;
  config.adhesion_stiffness = 5.0;
  config.adhesion_break_force = 2e-4;
  config.fluid_modulus = 2e4;
  config.fluid_wall_radius = kWall;
  config.max_steps_per_frame = 1000;  // every step of a frame runs (as in the World)
  return config;
}

double zeroClock() { return 0.0; }

// The cap of polar angle θ on a sphere of radius r spans the solid angle 2π(1 − cos θ); lifted uniformly to radius
// r − δ, the fluid between fills (Ω/3)(r³ − (r − δ)³).
TEST(SubretinalFluid, EnclosedVolumeOfAUniformlyLiftedCapConvergesToTheSphericalShell) {
  const double lift = 2e-4;
  double previous_error = std::numeric_limits<double>::infinity();
  for (const int rings : {6, 12, 24}) {
    const TriangleMesh mesh = scene::makeMembrane(patch(rings, false));
    auto membrane = membraneOf(mesh);
    tissue::TissueSimulator simulator(*membrane, fluidConfig());
    EXPECT_NEAR(simulator.enclosedVolume(), 0.0, 1e-18) << "at rest nothing is enclosed";
    for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
      Eigen::Vector3d& x = membrane->positions()[i];
      x *= (kWall - lift) / kWall;
    }
    const double theta = 0.5 * 0.006 / kWall;
    const double omega = 2.0 * kPi * (1.0 - std::cos(theta));
    const double exact = omega / 3.0 * (std::pow(kWall, 3) - std::pow(kWall - lift, 3));
    const double error = std::abs(simulator.enclosedVolume() - exact) / exact;
    EXPECT_LT(error, 0.02) << rings << " rings";
    RecordProperty("volume_error_" + std::to_string(rings) + "_rings", std::to_string(error));
    EXPECT_LT(error, previous_error) << "finer rings approximate the cap better";
    previous_error = error;
  }
}

struct Patch {
  std::unique_ptr<mge::Membrane> membrane;
  std::unique_ptr<tissue::TissueSimulator> simulator;
  Eigen::Vector3d centre;
};

Patch adheredPatch(const tissue::TissueConfig& config = fluidConfig()) {
  Patch result;
  const TriangleMesh mesh = scene::makeMembrane(patch(12, true));
  result.membrane = membraneOf(mesh);
  result.simulator = std::make_unique<tissue::TissueSimulator>(*result.membrane, config);
  result.centre = result.membrane->positions()[0];  // the cap's pole vertex
  return result;
}

TEST(SubretinalFluid, InjectedFluidLiftsTheRetinaAroundItsSourceAndFillsItsVolume) {
  Patch p = adheredPatch();
  const double volume = 5e-10;
  p.simulator->setFluidVolume(volume);
  p.simulator->setFluidSource(p.centre, 2.5e-4);
  for (int frame = 0; frame < 100; ++frame) p.simulator->advance(0.02, zeroClock);
  EXPECT_NEAR(p.simulator->enclosedVolume(), volume, 0.1 * volume);
  EXPECT_GT(p.simulator->fluidPressure(), 0.0);
  EXPECT_LE(p.simulator->fluidPressure(), p.simulator->config().fluid_max_pressure);
  // Lifted off the wall round the source; the rim still adheres.
  Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
  double weights = 0.0;
  for (std::size_t i = 0; i < p.membrane->nodeCount(); ++i) {
    const double lift = kWall - p.membrane->positions()[i].norm();
    if (lift > 5e-5) weighted += lift * p.membrane->positions()[i], weights += lift;
  }
  ASSERT_GT(weights, 0.0);
  EXPECT_LT((weighted / weights - p.centre).norm(), 4e-4) << "the bleb is centred on the puncture";
  EXPECT_GT(p.simulator->adhesionPoints(), p.membrane->nodeCount() / 2);
  EXPECT_GT(p.simulator->statistics().released_adhesions, 0u);
}

TEST(SubretinalFluid, WithoutASourceTheFluidReachesNoTriangle) {
  Patch p = adheredPatch();
  p.simulator->setFluidVolume(5e-10);  // counted, but never let in under the retina
  for (int frame = 0; frame < 25; ++frame) p.simulator->advance(0.02, zeroClock);
  double max_lift = 0.0;
  for (std::size_t i = 0; i < p.membrane->nodeCount(); ++i) {
    max_lift = std::max(max_lift, kWall - p.membrane->positions()[i].norm());
  }
  EXPECT_LT(max_lift, 1e-9);
  EXPECT_EQ(p.simulator->statistics().released_adhesions, 0u);
}

TEST(SubretinalFluid, FullFlowIsBoundedByTheMaximumPressureAndStaysFinite) {
  Patch p = adheredPatch();
  p.simulator->setFluidSource(p.centre, 2.5e-4);
  double volume = 0.0;
  for (int frame = 0; frame < 50; ++frame) {
    volume += 1e-6 * 0.02;  // the mediator's largest accepted flow, 1 ml/s, for a second
    p.simulator->setFluidVolume(volume);
    p.simulator->advance(0.02, zeroClock);
    ASSERT_TRUE(std::isfinite(p.simulator->enclosedVolume()));
    EXPECT_LE(p.simulator->fluidPressure(), p.simulator->config().fluid_max_pressure);
  }
  for (std::size_t i = 0; i < p.membrane->nodeCount(); ++i) {
    ASSERT_TRUE(p.membrane->positions()[i].allFinite());
    EXPECT_LT(p.membrane->positions()[i].norm(), kEye) << "nothing is pushed through the wall";
  }
  EXPECT_LT(p.simulator->maxStrain(), 1.6) << "the strain limit holds the inflated retina";
  p.simulator->setFluidVolume(std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(p.simulator->fluidVolume(), 0.0) << "a non-finite volume is no volume";
}

// One adhesion point (the cap's centre), held by a hold without jaws (the suction's) that lifts it along the normal.
struct Pull {
  std::unique_ptr<mge::Membrane> membrane;
  std::unique_ptr<tissue::TissueSimulator> simulator;
  tissue::InstrumentInput hold;
  Eigen::Vector3d anchor, inward;
};

Pull pullSetup(double release_time, double tear_force) {
  Pull pull;
  const TriangleMesh mesh = scene::makeMembrane(patch(8, false));
  pull.membrane = membraneOf(mesh);
  tissue::TissueConfig config = fluidConfig();
  config.fluid_modulus = 0.0;
  config.adhesion_break_force = 1e-3;
  config.adhesion_release_time = release_time;
  config.adhesion_tear_force = tear_force;
  pull.simulator = std::make_unique<tissue::TissueSimulator>(*pull.membrane, config);
  pull.anchor = pull.membrane->positions()[0];
  pull.inward = -pull.anchor.normalized();
  pull.hold.collides = false;
  pull.hold.holds = true;
  pull.hold.hold_radius = 1e-4;  // the centre node only
  pull.hold.pose.translation() = pull.anchor;
  pull.simulator->setInstruments({pull.hold});
  pull.simulator->advance(0.02, zeroClock);  // takes hold of it where it adheres
  return pull;
}

TEST(Adhesion, AnOverloadedAdhesionPeelsOnlyAfterItsReleaseTime) {
  Pull pull = pullSetup(0.25, 0.0);
  ASSERT_EQ(pull.simulator->adhesionPoints(), 1u);
  ASSERT_EQ(pull.simulator->graspedNodes().size(), 1u);
  // 0.3 mm off: 1.5 mN on a 5 N/m adhesion, above its 1 mN break force.
  pull.hold.pose.translation() = pull.anchor + 3e-4 * pull.inward;
  pull.simulator->setInstruments({pull.hold});
  pull.simulator->advance(0.02, zeroClock);  // overloaded from 2/3 of this frame on (past 0.2 mm)
  pull.simulator->advance(0.15, zeroClock);
  EXPECT_EQ(pull.simulator->adhesionPoints(), 1u) << "< 0.17 s overloaded: still holding";
  pull.simulator->advance(0.15, zeroClock);
  EXPECT_EQ(pull.simulator->adhesionPoints(), 0u) << "> 0.3 s overloaded: peeled";
  EXPECT_EQ(pull.simulator->statistics().adhesion_tears, 0u);
}

TEST(Adhesion, AYankPastTheTearForceTearsTheRetinaWhereItAdhered) {
  Pull pull = pullSetup(0.25, 3e-3);
  pull.hold.pose.translation() = pull.anchor + 1e-3 * pull.inward;  // 5 mN in one frame
  pull.simulator->setInstruments({pull.hold});
  pull.simulator->advance(0.02, zeroClock);
  EXPECT_EQ(pull.simulator->adhesionPoints(), 0u);
  EXPECT_EQ(pull.simulator->statistics().adhesion_tears, 1u);
  ASSERT_EQ(pull.simulator->adhesionTearPoints().size(), 1u);
  EXPECT_LT((pull.simulator->adhesionTearPoints()[0] - pull.anchor).norm(), 1e-12);
}

TEST(SuctionHold, HoldsWhatIsWithinItsRadiusAndLetsGoWhenItEnds) {
  Pull pull = pullSetup(0.0, 0.0);
  pull.hold.holds = false;
  pull.hold.pose.translation() = pull.anchor + 1e-3 * pull.inward;  // 1 mm off: nothing within reach
  pull.simulator->setInstruments({pull.hold});
  pull.simulator->advance(0.02, zeroClock);
  ASSERT_TRUE(pull.simulator->graspedNodes().empty());
  pull.hold.holds = true;
  pull.hold.hold_radius = 4e-4;
  pull.simulator->setInstruments({pull.hold});
  pull.simulator->advance(0.02, zeroClock);
  EXPECT_TRUE(pull.simulator->graspedNodes().empty());
  pull.hold.pose.translation() = pull.anchor + 2e-4 * pull.inward;
  pull.simulator->setInstruments({pull.hold});
  pull.simulator->advance(0.02, zeroClock);
  const std::size_t held = pull.simulator->graspedNodes().size();
  EXPECT_GE(held, 1u);
  for (std::uint32_t node : pull.simulator->graspedNodes()) {
    EXPECT_LE((pull.membrane->positions()[node] - pull.hold.pose.translation()).norm(), 4e-4 + 1e-9);
  }
  pull.hold.holds = false;
  pull.simulator->setInstruments({pull.hold});
  pull.simulator->advance(0.02, zeroClock);
  EXPECT_TRUE(pull.simulator->graspedNodes().empty());
}

// ---- in the World: the shipped scenes ----

constexpr world::Stamp kTick = 20000000;  // 20 ms

world::InstrumentState instrumentAt(const scene::SceneDescription& scene, const std::string& slot,
                                    const Eigen::Vector3d& tip, world::Stamp stamp) {
  return testing_support::instrumentAt(scene, slot, tip, 1.0, stamp);
}

class RetinaRelocationWorld : public ::testing::Test {
 protected:
  RetinaRelocationWorld() : world_(scene::loadScene(scene::shippedScenePath("retina_relocation"))) {
    world_.setFrameObserver([this](const world::FrameResult& frame) {
      for (const world::TissueReport& tissue : frame.tissues) {
        if (tissue.object == "retina_patch") last_ = tissue;
      }
    });
    // The expert's puncture: the target site, 4 deg temporal of the posterior pole, along the needle from its trocar.
    const Eigen::Vector3d site = kWall * (scene::posteriorPoleRotation(4.0, 180.0) * Eigen::Vector3d(0.0, 0.0, -1.0));
    axis_ = (site - world_.scene().findTrocar("right")->position_in_eye).normalized();
    site_ = site;
  }

  // One tick: the light pipe far away, the needle at `tip` injecting `flow`.
  void tick(const Eigen::Vector3d& tip, double flow) {
    const world::Stamp stamp = ++ticks_ * kTick;
    world_.handle(instrumentAt(world_.scene(), "left", Eigen::Vector3d(-0.003, 0.003, -0.004), stamp));
    world::InstrumentState needle = instrumentAt(world_.scene(), "right", tip, stamp);
    needle.injection_flow = flow;
    world_.handle(needle);
  }
  Eigen::Vector3d along(double s) const { return site_ + s * axis_; }  // s > 0: behind the retina

  world::World world_;
  world::TissueReport last_;
  Eigen::Vector3d site_, axis_;
  world::Stamp ticks_ = 0;
};

TEST_F(RetinaRelocationWorld, FluidGoesUnderTheRetinaOnlyWithTheTipBehindIt) {
  for (int i = 0; i < 10; ++i) tick(along(-3e-4), 5e-10);  // in front of the retina: into the vitreous
  EXPECT_FALSE(last_.needle_inside);
  EXPECT_EQ(last_.fluid_volume, 0.0);
  EXPECT_GT(last_.injected_outside, 0.0);
  for (int i = 0; i < 10; ++i) tick(along(5.4e-5), 0.0);  // 50 um under it, still
  EXPECT_TRUE(last_.needle_inside);
  for (int i = 0; i < 100; ++i) tick(along(5.4e-5), 5e-10);
  EXPECT_NEAR(last_.fluid_volume, 100 * 0.02 * 5e-10, 1e-13);
  EXPECT_GT(last_.enclosed_volume, 0.5 * last_.fluid_volume) << "the fluid lifted the retina";
  EXPECT_EQ(last_.cut_nodes + last_.torn_springs, 0u) << "a still needle does not tear";
}

TEST_F(RetinaRelocationWorld, AYankOfTheNeedleInsideSlicesTheRetinaAndTheFluidLeaks) {
  for (int i = 0; i < 10; ++i) tick(along(5.4e-5), 0.0);
  for (int i = 0; i < 50; ++i) tick(along(5.4e-5), 5e-10);
  const double before = last_.fluid_volume;
  const Eigen::Vector3d sideways = axis_.cross(site_.normalized()).normalized();
  tick(along(5.4e-5) + 2e-3 * sideways, 0.0);  // 2 mm in one frame: 0.1 m/s
  for (int i = 0; i < 100; ++i) tick(along(5.4e-5) + 2e-3 * sideways, 0.0);
  EXPECT_GT(last_.cut_nodes, 0u);
  EXPECT_LT(last_.fluid_volume, 0.5 * before) << "a torn retina lets the fluid out (1.5 s time constant)";
  EXPECT_TRUE(std::isfinite(last_.max_strain));
  EXPECT_LT(last_.max_strain, 2.0);
}

TEST(PosteriorHyaloidWorld, SuctionOnTheRetinaInjuresItAndHoldsTheHyaloidFinite) {
  world::World world(scene::loadScene(scene::shippedScenePath("posterior_hyaloid")));
  world::TissueReport hyaloid;
  double damage = 0.0;
  world.setFrameObserver([&](const world::FrameResult& frame) {
    for (const auto& tissue : frame.tissues) hyaloid = tissue;
    for (const auto& injury : frame.injuries) damage = std::max(damage, injury.max_injury);
  });
  // The port pressed onto the retina next to the disc with full suction (through the hyaloid).
  const Eigen::Vector3d tip = (kEye - 5e-5) * (scene::posteriorPoleRotation(12.0, 0.0) * Eigen::Vector3d(0, 0, -1));
  for (world::Stamp k = 1; k <= 50; ++k) {
    world.handle(instrumentAt(world.scene(), "left", Eigen::Vector3d(-0.003, 0.003, -0.004), k * kTick));
    world::InstrumentState vitrector = instrumentAt(world.scene(), "right", tip, k * kTick);
    vitrector.suction = 1.0;
    world.handle(vitrector);
  }
  EXPECT_GT(damage, 0.1) << "the port aspirated the retina";
  EXPECT_GT(hyaloid.grasped_nodes, 0u) << "the suction holds the hyaloid it reaches";
  EXPECT_TRUE(std::isfinite(hyaloid.max_strain));
  EXPECT_LT(hyaloid.max_strain, 2.0);
}

TEST(RetinaInputs, TheMediatorRejectsANonFiniteOrImplausibleInjectionFlow) {
  world::InstrumentState state;
  state.slot = "right";
  EXPECT_EQ(world::checkInstrument(state), "");
  for (const double flow : {std::numeric_limits<double>::quiet_NaN(), -1e-10, 1e-3}) {
    state.injection_flow = flow;
    EXPECT_NE(world::checkInstrument(state), "") << flow;
  }
}

TEST(RetinaScenes, TheLoaderNamesATearForceThatDoesNotExceedTheBreakForce) {
  std::ifstream file(scene::shippedScenePath("posterior_hyaloid"));
  std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const std::string good = "adhesion_tear_force: 3.0e-3";
  ASSERT_NE(text.find(good), std::string::npos);
  text.replace(text.find(good), good.size(), "adhesion_tear_force: 5.0e-4");
  try {
    scene::loadSceneFromString(text, "posterior_hyaloid_bad.yaml");
    FAIL() << "accepted a tear force below the break force";
  } catch (const scene::SceneError& error) {
    EXPECT_NE(std::string(error.what()).find("adhesion_tear_force must exceed adhesion_break_force"), std::string::npos)
        << error.what();
    EXPECT_NE(std::string(error.what()).find("posterior_hyaloid_bad.yaml:"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace vrm_sim
