// The tissue layer's registries (issue 17): integrators and tissue models, each one table that the factories, the
// scene schema check and the listings read — names in order with the default first, an unknown name's error names
// the known ones, each factory builds what its name says — and both tissue models driven through the TissueModel
// interface by TissueSimulator.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "vrm_sim/tissue/integrator.h"
#include "vrm_sim/tissue/integrator_choice.h"
#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/tissue_model.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {
namespace {

constexpr double kL = 1e-3;  // grid spacing

// The message of the std::invalid_argument `action` throws ("" if it throws none).
template <typename Action>
std::string invalidArgument(Action action) {
  try {
    action();
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "";
}

TEST(IntegratorRegistry, NamesInOrderWithAutoFirst) {
  const std::vector<std::string> expected{
      "auto", "explicit_euler", "quasi_static_euler", "rk2", "implicit_euler", "symplectic_euler", "xpbd"};
  EXPECT_EQ(integratorRegistry().names(), expected);
  EXPECT_EQ(integratorRegistry().names().front(), kAutoIntegrator);
  // The integrators proper: the same table without "auto".
  EXPECT_EQ(integratorNames(), std::vector<std::string>(expected.begin() + 1, expected.end()));
  for (const auto& entry : integratorRegistry().entries()) EXPECT_FALSE(entry.summary.empty()) << entry.name;
}

TEST(IntegratorRegistry, FactoriesBuildTheNamedIntegrator) {
  IntegratorOptions options;
  for (const auto& entry : integratorRegistry().entries()) {
    ASSERT_NE(entry.make, nullptr) << entry.name;
    const std::unique_ptr<Integrator> integrator = entry.make(options);
    ASSERT_NE(integrator, nullptr) << entry.name;
    // "auto" starts with the explicit candidate of integrator_choice.h until the simulator has chosen.
    EXPECT_STREQ(integrator->name(), entry.name == kAutoIntegrator ? "symplectic_euler" : entry.name.c_str());
    EXPECT_STREQ(makeIntegrator(entry.name, options)->name(), integrator->name());
  }
}

TEST(IntegratorRegistry, UnknownNameListsTheKnownOnes) {
  const std::string message = invalidArgument([] { makeIntegrator("verlet"); });
  EXPECT_NE(message.find("'verlet'"), std::string::npos) << message;
  EXPECT_NE(message.find(integratorRegistry().namesJoined()), std::string::npos) << message;
  EXPECT_EQ(integratorRegistry().find("verlet"), nullptr);
}

TEST(TissueModelRegistry, NamesInOrderWithTheDefaultFirst) {
  EXPECT_EQ(tissueModelRegistry().names(), (std::vector<std::string>{"mass_spring", "chainmail"}));
  EXPECT_EQ(tissueModelRegistry().names().front(), TissueConfig().model);
  for (const auto& entry : tissueModelRegistry().entries()) EXPECT_FALSE(entry.summary.empty()) << entry.name;
}

TEST(TissueModelRegistry, FactoriesBuildTheNamedModel) {
  for (const auto& entry : tissueModelRegistry().entries()) {
    auto membrane = makeGridMembrane(4, 4 * kL, 1.0, 1e-5, /*pin_border=*/true);
    TissueConfig config;
    config.model = entry.name;
    const std::unique_ptr<TissueModel> model = entry.make(*membrane, config);
    ASSERT_NE(model, nullptr) << entry.name;
    EXPECT_EQ(model->name(), entry.name);
    EXPECT_EQ(model->fallbackLevel(), 0);
  }
  // What the simulator asks of them: refinement and the early stop need the integrated model.
  auto membrane = makeGridMembrane(4, 4 * kL, 1.0, 1e-5, true);
  const TissueConfig config;
  const auto mass_spring = tissueModelRegistry().at("mass_spring").make(*membrane, config);
  EXPECT_TRUE(mass_spring->supportsRefinement());
  EXPECT_TRUE(mass_spring->supportsEarlyStop());
  const auto chainmail = tissueModelRegistry().at("chainmail").make(*membrane, config);
  EXPECT_FALSE(chainmail->supportsRefinement());
  EXPECT_FALSE(chainmail->supportsEarlyStop());
}

TEST(TissueModelRegistry, UnknownModelListsTheKnownOnes) {
  auto membrane = makeGridMembrane(4, 4 * kL, 1.0, 1e-5, true);
  TissueConfig config;
  config.model = "fem";
  const std::string message = invalidArgument([&] { TissueSimulator simulator(*membrane, config); });
  EXPECT_NE(message.find("'fem'"), std::string::npos) << message;
  EXPECT_NE(message.find("mass_spring, chainmail"), std::string::npos) << message;
}

TEST(TissueModelRegistry, ModelSettingsAreCheckedByTheModel) {
  auto membrane = makeGridMembrane(4, 4 * kL, 1.0, 1e-5, true);
  TissueConfig config;
  config.model = "chainmail";
  config.chainmail.min_stretch = 1.1;  // excludes the rest state
  EXPECT_THROW(TissueSimulator(*membrane, config), std::invalid_argument);
  config.chainmail = ChainMailConfig{};
  config.refinement.levels = 1;  // needs virtual nodes that are integrated
  EXPECT_THROW(TissueSimulator(*membrane, config), std::invalid_argument);
}

// Each model, stepped by TissueSimulator through the interface: a sphere pressed into a pinned membrane moves the
// free nodes out of it; only ChainMail has a ChainMail and leaves no velocity.
TEST(TissueModelInterface, BothModelsStepThroughTheSimulator) {
  for (const std::string& name : tissueModelRegistry().names()) {
    SCOPED_TRACE(name);
    auto membrane = makeGridMembrane(12, 12 * kL, 1.0, 1e-5, /*pin_border=*/true);
    TissueConfig config;
    config.model = name;
    config.integrator = kAutoIntegrator;
    TissueSimulator simulator(*membrane, config);
    EXPECT_EQ(simulator.model().name(), name);
    EXPECT_EQ(simulator.chainmail() != nullptr, name == "chainmail");
    InstrumentInput pusher;
    pusher.radius = 1e-3;
    pusher.pose.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
    pusher.pose.translation() = Eigen::Vector3d(0.0, 0.0, 0.05e-3);
    const Clock clock = [] { return 0.0; };
    simulator.setInstruments({pusher});
    for (int frame = 0; frame < 10; ++frame) {
      pusher.pose.translation().z() -= 3e-5;
      simulator.setInstruments({pusher});
      const FrameReport report = simulator.advance(0.002, clock);
      EXPECT_EQ(report.steps, 2) << frame;
    }
    EXPECT_EQ(simulator.statistics().steps, 20u);
    EXPECT_EQ(simulator.statistics().unrecovered, 0u);
    EXPECT_FALSE(simulator.lastContacts().empty());
    const Eigen::Vector3d centre = pusher.pose * Eigen::Vector3d(0.0, 0.0, -pusher.radius);
    double deepest = 0.0;
    bool moving = false;
    for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
      if (membrane->fixedFlags()[i]) continue;
      EXPECT_GE((membrane->positions()[i] - centre).norm(), pusher.radius * (1.0 - 1e-6)) << i;
      deepest = std::min(deepest, membrane->positions()[i].z());
      moving = moving || membrane->velocities()[i] != Eigen::Vector3d::Zero();
    }
    EXPECT_LT(deepest, -1e-5);                 // pressed in
    EXPECT_EQ(moving, name == "mass_spring");  // ChainMail is inelastic
  }
}

}  // namespace
}  // namespace tissue
}  // namespace vrm_sim
