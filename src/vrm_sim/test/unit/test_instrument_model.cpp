// The instrument model (vrm_scene/instrument_model.h; its physics shapes in vrm_sim/world/instrument_shapes.h) and
// the registries of the scene's variation points: one definition each, so the drawn instrument is the one that collides
// and a name the schema accepts is one a factory builds.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

#include "vrm_scene/instrument_model.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/scenario/scenario.h"
#include "vrm_sim/world/instrument_shapes.h"
#include "vrm_sim/world/tissue_setup.h"

namespace vrm_sim {
namespace scene {
namespace {

using world::collisionModel;
using world::tissueShape;

InstrumentDescription forcepsSlot() {
  InstrumentDescription forceps;
  forceps.type = InstrumentType::kForceps;
  forceps.params = defaultInstrumentParams(InstrumentType::kForceps);
  std::get<ForcepsParams>(forceps.params).shaft.diameter = 7e-4;  // not the default: the scene's own parameters
  forceps.alternatives = {InstrumentType::kVitrector};
  return forceps;
}

TEST(InstrumentModel, ASlotTakesItsTypeAndItsAlternativesOnly) {
  const InstrumentDescription slot = forcepsSlot();
  EXPECT_TRUE(allowsType(slot, InstrumentType::kForceps));
  EXPECT_TRUE(allowsType(slot, InstrumentType::kVitrector));
  EXPECT_FALSE(allowsType(slot, InstrumentType::kHook));
  EXPECT_EQ(typeAfterRequest(slot, InstrumentType::kForceps, InstrumentType::kVitrector), InstrumentType::kVitrector);
  EXPECT_EQ(typeAfterRequest(slot, InstrumentType::kVitrector, InstrumentType::kHook), InstrumentType::kVitrector);
  EXPECT_EQ(typeAfterRequest(slot, InstrumentType::kVitrector, std::nullopt), InstrumentType::kVitrector);
}

TEST(InstrumentModel, TheDeclaredTypeKeepsTheSceneParametersAnAlternativeGetsTheDefaults) {
  const InstrumentDescription slot = forcepsSlot();
  const InstrumentDescription same = instrumentOfType(slot, InstrumentType::kForceps);
  EXPECT_EQ(std::get<ForcepsParams>(same.params).shaft.diameter, 7e-4);
  const InstrumentDescription vitrector = instrumentOfType(slot, InstrumentType::kVitrector);
  EXPECT_EQ(vitrector.type, InstrumentType::kVitrector);
  ASSERT_TRUE(std::holds_alternative<VitrectorParams>(vitrector.params));
  EXPECT_EQ(tissueShape(same).radius, 0.5 * 7e-4);
  EXPECT_TRUE(tissueShape(same).jaws && tissueShape(same).can_grasp);
  EXPECT_FALSE(tissueShape(vitrector).jaws);
  EXPECT_GT(tissueShape(vitrector).cut_radius, 0.0);
}

TEST(InstrumentModel, JawStepsAreWholeDegreesUpToTheForcepsLimit) {
  EXPECT_EQ(jawStepDeg(InstrumentType::kForceps, 0.5), static_cast<int>(std::lround(0.5 * 180.0 / M_PI)));
  EXPECT_EQ(jawStepDeg(InstrumentType::kForceps, kMaxJawOpening), 86);
  EXPECT_EQ(jawStepDeg(InstrumentType::kForceps, M_PI), 86) << "the drawn jaws open no further than the colliding ones";
  EXPECT_EQ(jawStepDeg(InstrumentType::kForceps, -0.3), 0);
  EXPECT_EQ(jawStepDeg(InstrumentType::kForceps, std::nan("")), 0);
  EXPECT_EQ(jawStepDeg(InstrumentType::kForceps, HUGE_VAL), 0);
  EXPECT_EQ(jawStepDeg(InstrumentType::kVitrector, 1.0), 0);
}

TEST(InstrumentModel, TheCollisionModelIsTheMeshAndTheCapsulesAtTheSameOpening) {
  const InstrumentDescription slot = forcepsSlot();
  const collision::InstrumentModel closed = collisionModel(slot, 0);
  const collision::InstrumentModel open = collisionModel(slot, 60);
  EXPECT_EQ(closed.mesh.vertices.size(), instrumentMesh(slot, 0).vertices.size());
  EXPECT_EQ(open.mesh.vertices, instrumentMesh(slot, 60).vertices);
  EXPECT_NE(closed.mesh.vertices, open.mesh.vertices);
  EXPECT_EQ(closed.primitives.size(), open.primitives.size());
  ASSERT_FALSE(open.primitives.empty());
  // The jaw capsules spread apart as the jaws open: the tips are further from the axis.
  double closed_reach = 0.0, open_reach = 0.0;
  for (const auto& p : closed.primitives) closed_reach = std::max(closed_reach, p.b.head<2>().norm());
  for (const auto& p : open.primitives) open_reach = std::max(open_reach, p.b.head<2>().norm());
  EXPECT_GT(open_reach, closed_reach);
}

TEST(Registries, InstrumentTypesFollowTheMessageOrderAndRoundTripByName) {
  const auto& entries = instrumentTypeRegistry().entries();
  ASSERT_EQ(entries.size(), 6u);
  for (std::size_t i = 0; i < entries.size(); ++i) {
    EXPECT_EQ(static_cast<std::size_t>(entries[i].make), i) << entries[i].name;
    EXPECT_EQ(toString(entries[i].make), entries[i].name);
    EXPECT_EQ(instrumentTypeNamed(entries[i].name), entries[i].make);
  }
  EXPECT_FALSE(instrumentTypeNamed("scalpel").has_value());
}

TEST(Registries, EveryDetectorNameBuildsAndSaysWhetherItsDeformationsMoveTissue) {
  const std::set<std::string> image_space = {"zcoll", "zcoll_f", "zcoll_cpu", "zcoll_f_cpu", "zcoll_gl", "zcoll_f_gl"};
  for (const std::string& name : collision::detectorRegistry().names()) {
    const auto detector = collision::makeCollisionDetector(name);
    ASSERT_NE(detector, nullptr) << name;
    EXPECT_EQ(detector->producesDeformations(), image_space.count(name) == 1) << name;
  }
  try {
    collision::makeCollisionDetector("zcol_f");
    FAIL() << "an unknown detector was built";
  } catch (const std::invalid_argument& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("unknown collision detector 'zcol_f' (did you mean 'zcoll_f'?)"), std::string::npos)
        << message;
    EXPECT_NE(message.find("fcl_kios"), std::string::npos) << message;
  }
}

TEST(Registries, TheSchemaAcceptsExactlyTheRegisteredDetectorNames) {
  const std::string base = R"(scene: {name: t, kind: surgical}
objects:
  - {name: retina, role: retina, mesh: {generator: retina, params: {ring_count: 12}}, collision: {detector: DETECTOR}}
simulations: []
)";
  auto load = [&](const std::string& detector) {
    std::string text = base;
    text.replace(text.find("DETECTOR"), 8, detector);
    SceneDescription scene = loadSceneFromString(text, "t.yaml");
    world::checkSimulationNames(scene);  // where the World checks the names the loader read as text (issue 42)
    return scene;
  };
  for (const std::string& name : collision::detectorRegistry().names()) {
    EXPECT_EQ(load(name).objects[0].collision.detector, name);
  }
  EXPECT_THROW(load("zcoll_fast"), SceneError);
}

// Every shipped scenario's type is registered, and every registered type has a shipped scene (one to train with).
TEST(Registries, EveryShippedScenarioTypeIsRegistered) {
  std::set<std::string> shipped_types;
  for (const std::string& name : shippedScenes()) {
    const SceneDescription scene = loadScene(name);
    if (!scene.scenario) continue;
    EXPECT_TRUE(scenario::scenarioRegistry().contains(scene.scenario->type)) << name;
    shipped_types.insert(scene.scenario->type);
  }
  const std::vector<std::string> registered = scenario::scenarioRegistry().names();
  EXPECT_EQ(shipped_types, std::set<std::string>(registered.begin(), registered.end()));
}

}  // namespace
}  // namespace scene
}  // namespace vrm_sim
