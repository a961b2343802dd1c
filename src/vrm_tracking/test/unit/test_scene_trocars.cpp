// The scene file as the single source of the trocars: scripts and marker layouts take the scene's trocars per slot.

#include <gtest/gtest.h>

#include <string>

#include "vrm_sim/scene/scene_loader.h"
#include "vrm_tracking/scene_trocars.h"

namespace vrm_tracking {
namespace {

namespace scene = vrm_sim::scene;

const std::string kSourceDir = VRM_TRACKING_SOURCE_DIR;

// Trocars moved away from the defaults (45 deg off axis, azimuth 150 / 30): "left" by angles, "right" explicit.
const char* const kMovedTrocars = R"(scene: {name: moved_trocars, kind: abstract}
eye:
  radius: 0.012
  trocars:
    - {name: left, angle_from_optical_axis_deg: 40.0, azimuth_deg: 170.0}
    - {name: right, position: [0.008, -0.002, 0.0087]}
objects:
  - {name: ball, role: abstract_target, mesh: {generator: sphere, params: {radius: 0.001}}}
simulations: [collision]
)";

void expectNear(const Eigen::Vector3d& actual, const Eigen::Vector3d& expected, double tolerance) {
  EXPECT_LT((actual - expected).norm(), tolerance)
      << "actual " << actual.transpose() << ", expected " << expected.transpose();
}

TEST(SceneTrocars, MovedTrocarsOverrideTheScript) {
  const scene::SceneDescription moved = scene::loadSceneFromString(kMovedTrocars, "moved_trocars.yaml");
  const Eigen::Vector3d left = moved.findTrocar("left")->position_in_eye;
  const Eigen::Vector3d right = moved.findTrocar("right")->position_in_eye;
  const SurgeonScript original = SurgeonScript::builtin("demo");
  ASSERT_EQ(original.definition().instruments.size(), 2u);
  ASSERT_GT((original.definition().instruments[0].trocar - left).norm(), 1e-3);  // really moved

  const SurgeonScript script = applySceneTrocars(moved, original);
  for (const InstrumentTrack& track : script.definition().instruments) {
    expectNear(track.trocar, track.slot == "left" ? left : right, 1e-12);
  }
  // The played instruments pivot at the scene's trocars: the shaft runs from the trocar to the tip.
  const SurgeonSnapshot snapshot = script.sample(3.0);
  ASSERT_EQ(snapshot.instruments.size(), 2u);
  for (const auto& instrument : snapshot.instruments) {
    const Eigen::Vector3d trocar = instrument.slot == "left" ? left : right;
    expectNear(instrument.tip - instrument.insertion_depth * instrument.shaft_axis, trocar, 1e-9);
  }
  EXPECT_EQ(script.playback(), original.playback());
}

TEST(SceneTrocars, MovedTrocarsOverrideTheLayout) {
  const scene::SceneDescription moved = scene::loadSceneFromString(kMovedTrocars, "moved_trocars.yaml");
  MarkerLayout layout = makeDefaultLayout();
  ASSERT_EQ(layout.instruments.size(), 2u);
  applySceneTrocars(moved, &layout);
  expectNear(layout.findSlot("left")->trocar, moved.findTrocar("left")->position_in_eye, 1e-12);
  expectNear(layout.findSlot("right")->trocar, moved.findTrocar("right")->position_in_eye, 1e-12);
}

TEST(SceneTrocars, SlotUsesTheTrocarOfTheScenesInstrument) {
  // The instrument in slot "left" enters through trocar "upper", not through a trocar named "left".
  const scene::SceneDescription crossed = scene::loadSceneFromString(R"(scene: {name: crossed, kind: abstract}
eye:
  trocars:
    - {name: upper, position: [0.0, 0.0085, 0.0085]}
    - {name: right, position: [0.0085, 0.0, 0.0085]}
objects:
  - {name: ball, role: abstract_target, mesh: {generator: sphere, params: {radius: 0.001}}}
instruments:
  - {slot: left, type: light_pipe, trocar: upper}
simulations: [collision]
)",
                                                                     "crossed.yaml");
  expectNear(sceneTrocarForSlot(crossed, "left"), Eigen::Vector3d(0.0, 0.0085, 0.0085), 1e-12);
  expectNear(sceneTrocarForSlot(crossed, "right"), Eigen::Vector3d(0.0085, 0.0, 0.0085), 1e-12);
}

TEST(SceneTrocars, MissingSlotIsAClearErrorAndChangesNothing) {
  const scene::SceneDescription one = scene::loadSceneFromString(R"(scene: {name: one_trocar, kind: abstract}
eye:
  trocars:
    - {name: left, angle_from_optical_axis_deg: 40.0, azimuth_deg: 170.0}
objects:
  - {name: ball, role: abstract_target, mesh: {generator: sphere, params: {radius: 0.001}}}
simulations: [collision]
)",
                                                                 "one_trocar.yaml");
  MarkerLayout layout = makeDefaultLayout();
  const MarkerLayout before = layout;
  try {
    applySceneTrocars(one, &layout);
    FAIL() << "a scene without trocar 'right' must be rejected";
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("one_trocar"), std::string::npos) << message;
    EXPECT_NE(message.find("slot 'right'"), std::string::npos) << message;
    EXPECT_NE(message.find("trocars: left"), std::string::npos) << message;
  }
  for (std::size_t i = 0; i < layout.instruments.size(); ++i) {
    EXPECT_EQ(layout.instruments[i].trocar, before.instruments[i].trocar);  // left not half-applied
  }
  EXPECT_THROW(applySceneTrocars(one, SurgeonScript::builtin("demo")), std::runtime_error);
}

// The copies shipped in vrm_tracking still agree with the shipped scenes (they are what runs without ~scene).
TEST(SceneTrocars, ShippedCopiesMatchTheShippedScenes) {
  for (const std::string name : {"membrane_peeling", "navigation", "ilm_peeling"}) {
    SCOPED_TRACE(name);
    const scene::SceneDescription shipped = loadSceneSpec(name);
    for (const InstrumentMarker& marker : loadLayoutYaml(kSourceDir + "/config/markers_default.yaml").instruments) {
      expectNear(marker.trocar, sceneTrocarForSlot(shipped, marker.slot), 1e-9);
    }
    for (const std::string script : {"membrane_peeling_demo", "navigation_demo"}) {
      const SurgeonScript file = SurgeonScript::fromFile(kSourceDir + "/config/trajectories/" + script + ".yaml");
      for (const InstrumentTrack& track : file.definition().instruments) {
        expectNear(track.trocar, sceneTrocarForSlot(shipped, track.slot), 1e-6);  // the files round to 0.1 um
      }
    }
  }
}

TEST(SceneTrocars, SceneSpecIsANameOrAPath) {
  const scene::SceneDescription by_name = loadSceneSpec("navigation");
  EXPECT_EQ(by_name.name, "navigation");
  EXPECT_EQ(loadSceneSpec(by_name.source_file).name, "navigation");
  EXPECT_THROW(loadSceneSpec("no_such_scene"), scene::SceneError);
}

}  // namespace
}  // namespace vrm_tracking
