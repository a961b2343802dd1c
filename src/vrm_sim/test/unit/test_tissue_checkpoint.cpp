// Tissue checkpoints (issue 39 §1): a TissueSimulator saved mid-session — grasp held, adhesions pulling, springs
// torn, a trench cut, the implicit solver warm, auto's choice made — and loaded into a simulator built afresh from
// the same membrane goes on bit for bit with the original under the same instrument inputs, for every integrator.
// What cannot be restored exactly (local refinement, the chainmail model) is refused.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "vrm_sim/tissue/integrator.h"
#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {
namespace {

TissueConfig pullConfig(const std::string& integrator) {
  TissueConfig config;
  config.integrator = integrator;
  config.forces.damping = 2e-3;
  config.adhesion_stiffness = 5.0;
  config.adhesion_break_force = 2e-4;
  config.adhesion_release_time = 0.01;
  config.tear_strain = 1.3;
  return config;
}

// Frame f's instruments: forceps that grasp at frame 3 and pull up and sideways, and a vitrector that cuts a trench
// in frames 20-28 (topology changes mid-session, with the grasp held across them; after them the implicit solver's
// warm start is in use again).
std::vector<InstrumentInput> instrumentsAt(int frame) {
  InstrumentInput forceps;
  forceps.pose.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const double pull = frame > 3 ? 1.5e-4 * (frame - 3) : 0.0;
  forceps.pose.translation() = Eigen::Vector3d(2e-3 + 0.3 * pull, 0.0, -0.5e-3 - pull);
  forceps.can_grasp = true;
  forceps.collides = false;
  forceps.jaw_angle = frame >= 3 ? 0.0 : 1.0;
  forceps.jaw_length = 1e-3;
  InstrumentInput vitrector;
  vitrector.collides = true;
  vitrector.radius = 3e-4;
  vitrector.length = 3e-3;
  vitrector.cuts = frame >= 20 && frame <= 28;
  vitrector.cut_radius = 4e-4;
  vitrector.pose.translation() = Eigen::Vector3d(-3e-3, -4e-3 + 2e-4 * frame, 1e-4);
  return {forceps, vitrector};
}

struct Tissue {
  std::unique_ptr<mge::Membrane> membrane = makeGridMembrane(14, 0.012, 2.0, 1e-5);
  std::unique_ptr<TissueSimulator> simulator;
  explicit Tissue(const TissueConfig& config) : simulator(std::make_unique<TissueSimulator>(*membrane, config)) {}
  void frame(int f) {
    simulator->setInstruments(instrumentsAt(f));
    // Frame times that do not divide into steps: the carried time (pending_time_) is state too.
    simulator->advance(f % 3 == 0 ? 0.0027 : 0.002, [] { return 0.0; });
  }
  std::string checkpoint() {
    StateArchive archive = StateArchive::saver();
    simulator->transferState(archive);
    return archive.takeBytes();
  }
  void restore(const std::string& bytes) {
    StateArchive archive = StateArchive::loader(bytes);
    simulator->transferState(archive);
    ASSERT_TRUE(archive.atEnd());
  }
};

bool sameBits(const mge::Membrane& a, const mge::Membrane& b) {
  if (a.nodeCount() != b.nodeCount() || a.springCount() != b.springCount()) return false;
  const std::size_t n = a.nodeCount() * sizeof(Eigen::Vector3d);
  return std::memcmp(a.nodeArrays().data<mge::kNodePosition>(), b.nodeArrays().data<mge::kNodePosition>(), n) == 0 &&
         std::memcmp(a.nodeArrays().data<mge::kNodeVelocity>(), b.nodeArrays().data<mge::kNodeVelocity>(), n) == 0;
}

class TissueCheckpoint : public ::testing::TestWithParam<std::string> {};

TEST_P(TissueCheckpoint, LoadedSimulatorContinuesBitForBit) {
  const TissueConfig config = pullConfig(GetParam());
  Tissue original(config);
  for (int f = 0; f < 34; ++f) original.frame(f);
  // The session did what the checkpoint must carry.
  ASSERT_GT(original.simulator->graspedNodes().size(), 0u);
  ASSERT_GT(original.simulator->topologyChanges(), 0u);
  const std::string bytes = original.checkpoint();

  Tissue restored(config);
  restored.restore(bytes);
  EXPECT_TRUE(sameBits(*original.membrane, *restored.membrane));
  EXPECT_EQ(restored.simulator->graspedNodes(), original.simulator->graspedNodes());
  EXPECT_EQ(restored.simulator->integratorLabel(), original.simulator->integratorLabel());
  EXPECT_EQ(restored.checkpoint(), bytes);
  for (int f = 34; f < 60; ++f) {
    original.frame(f);
    restored.frame(f);
    ASSERT_TRUE(sameBits(*original.membrane, *restored.membrane)) << "frame " << f << " diverged";
    ASSERT_EQ(restored.simulator->graspedNodes(), original.simulator->graspedNodes()) << "frame " << f;
  }
  EXPECT_EQ(restored.checkpoint(), original.checkpoint()) << "state outside the positions diverged";
  EXPECT_EQ(restored.simulator->statistics().torn_springs, original.simulator->statistics().torn_springs);
}

INSTANTIATE_TEST_SUITE_P(Integrators, TissueCheckpoint,
                         ::testing::Values("auto", "symplectic_euler", "quasi_static_euler", "explicit_euler", "rk2",
                                           "xpbd", "implicit_euler"));

TEST(TissueCheckpointErrors, RefinementAndChainMailAreRefusedAndBadBytesToo) {
  TissueConfig refined = pullConfig("quasi_static_euler");
  refined.adhesion_stiffness = 0.0;
  refined.refinement.levels = 1;
  Tissue with_refinement(refined);
  StateArchive saver = StateArchive::saver();
  EXPECT_THROW(with_refinement.simulator->transferState(saver), StateError);

  TissueConfig chainmail;
  chainmail.model = "chainmail";
  Tissue with_chainmail(chainmail);
  StateArchive chainmail_saver = StateArchive::saver();
  try {
    with_chainmail.simulator->transferState(chainmail_saver);
    ADD_FAILURE() << "accepted";
  } catch (const StateError& error) {
    EXPECT_NE(std::string(error.what()).find("chainmail"), std::string::npos) << error.what();
  }

  Tissue source(pullConfig("auto"));
  for (int f = 0; f < 8; ++f) source.frame(f);
  const std::string bytes = source.checkpoint();
  for (std::size_t cut : {std::size_t{3}, bytes.size() / 2, bytes.size() - 1}) {
    Tissue target(pullConfig("auto"));
    StateArchive loader = StateArchive::loader(bytes.substr(0, cut));
    EXPECT_THROW(target.simulator->transferState(loader), StateError) << "cut at " << cut;
  }
  // A checkpoint of a simulator configured otherwise (another integrator): refused by name.
  Tissue other(pullConfig("symplectic_euler"));
  StateArchive loader = StateArchive::loader(bytes);
  try {
    other.simulator->transferState(loader);
    ADD_FAILURE() << "accepted";
  } catch (const StateError& error) {
    EXPECT_NE(std::string(error.what()).find("the configured integrator"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace tissue
}  // namespace vrm_sim
