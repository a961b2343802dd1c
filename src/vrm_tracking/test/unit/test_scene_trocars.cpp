// The scene file as the single source of the trocars and of where tissue is: scripts and marker layouts take the
// scene's trocars per slot, and waypoints written `on` a scene object are put on that object's surface.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <variant>

#include "vrm_scene/scene_loader.h"
#include "vrm_sim/world/world.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/tracker_diagnostics.h"

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
  const scene::ScriptedSession demo = loadSession("", moved);
  const SurgeonScript script = playInScene(moved, demo);
  ASSERT_EQ(script.tracks().size(), 2u);
  for (std::size_t i = 0; i < script.tracks().size(); ++i) {
    expectNear(script.tracks()[i].trocar, demo.instruments[i].slot == scene::InstrumentSlot::kLeft ? left : right,
               1e-12);
  }
  ASSERT_GT((script.tracks()[0].trocar - scene::defaultTrocars(0.012)[0].position_in_eye).norm(), 1e-3);  // moved
  // The played instruments pivot at the scene's trocars: the shaft runs from the trocar to the tip.
  const SurgeonSnapshot snapshot = script.sample(3.0);
  ASSERT_EQ(snapshot.instruments.size(), 2u);
  for (const auto& instrument : snapshot.instruments) {
    const Eigen::Vector3d trocar = instrument.slot == "left" ? left : right;
    expectNear(instrument.tip - instrument.insertion_depth * instrument.shaft_axis, trocar, 1e-9);
  }
  EXPECT_EQ(script.playback(), demo.playback);
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
  EXPECT_THROW(playInScene(one, loadSession("", one)), std::runtime_error);
}

// The shipped layout and scripts name no trocars: they take the scene's, by default the default scene's (what
// the nodelets run without ~scene), so there are no copies to keep in sync.
TEST(SceneTrocars, ShippedFilesTakeTheDefaultScenesTrocars) {
  EXPECT_EQ(sceneOrDefault(""), "membrane_peeling");
  EXPECT_EQ(sceneOrDefault("navigation"), "navigation");
  const scene::SceneDescription fallback = vrm_sim::scene::loadScene(sceneOrDefault(""));
  MarkerLayout layout = loadLayoutYaml(kSourceDir + "/config/markers_default.yaml");
  ASSERT_EQ(layout.instruments.size(), 2u);
  applySceneTrocars(fallback, &layout);
  for (const InstrumentMarker& marker : layout.instruments) {
    EXPECT_FALSE(marker.trocar_from_scene);
    EXPECT_EQ(marker.trocar, sceneTrocarForSlot(fallback, marker.slot));
  }
  for (const std::string name : {"demo", "membrane_peeling_demo", "navigation_demo"}) {
    SCOPED_TRACE(name);
    const SurgeonScript played = playInScene(fallback, loadSession(name, fallback));
    EXPECT_EQ(played.eye().radius, fallback.eye.radius);
    EXPECT_EQ(played.eye().rotation_center, fallback.eye.centre_in_world);
    for (std::size_t i = 0; i < played.tracks().size(); ++i) {
      EXPECT_EQ(played.tracks()[i].trocar,
                sceneTrocarForSlot(fallback, scene::toString(played.session().instruments[i].slot)));
    }
  }
}

// ---- The scene's eye for the tracker's layout, and following the running scene (issue 32) ----

// The shipped scenes' eye with its centre 1 mm off the world origin and the trocars at azimuths 140 / 40 deg (the
// shipped ones: 150 / 30), as test/rostest/scene_switch.yaml.
const char* const kMovedEye = R"(scene: {name: moved_eye, kind: abstract}
eye:
  radius: 0.012
  centre: [0.001, 0.0, 0.0]
  trocars:
    - {name: left, angle_from_optical_axis_deg: 45.0, azimuth_deg: 140.0}
    - {name: right, angle_from_optical_axis_deg: 45.0, azimuth_deg: 40.0}
objects:
  - {name: ball, role: abstract_target, mesh: {generator: sphere, params: {radius: 0.001}}}
simulations: [collision]
)";

Eigen::Vector3d onEyeSphere(double radius, double polar_deg, double azimuth_deg) {
  const double polar = polar_deg * M_PI / 180.0, azimuth = azimuth_deg * M_PI / 180.0;
  return radius *
         Eigen::Vector3d(std::sin(polar) * std::cos(azimuth), std::sin(polar) * std::sin(azimuth), std::cos(polar));
}

TEST(SceneEye, TheScenesEyeCentreAndTrocarsReplaceTheLayouts) {
  const scene::SceneDescription moved = scene::loadSceneFromString(kMovedEye, "moved_eye.yaml");
  MarkerLayout layout = loadLayoutYaml(kSourceDir + "/config/markers_default.yaml");
  layout.rotation_center = Eigen::Vector3d(0.0, 0.0, 0.002);  // the layout's own, to see it replaced
  const MarkerLayout before = layout;
  const Eigen::Vector3d layout_centre = applyScene(moved, &layout);
  EXPECT_EQ(layout_centre, Eigen::Vector3d(0.0, 0.0, 0.002));
  EXPECT_EQ(layout.rotation_center, Eigen::Vector3d(0.001, 0.0, 0.0));
  expectNear(layout.findSlot("left")->trocar, onEyeSphere(0.012, 45.0, 140.0), 1e-15);
  expectNear(layout.findSlot("right")->trocar, onEyeSphere(0.012, 45.0, 40.0), 1e-15);
  // The markers are the layout's: the scene has none.
  ASSERT_EQ(layout.eye_markers.size(), before.eye_markers.size());
  for (std::size_t i = 0; i < layout.eye_markers.size(); ++i) {
    EXPECT_EQ(layout.eye_markers[i].position, before.eye_markers[i].position);
  }
  EXPECT_EQ(layout.classes.size(), before.classes.size());
  // A pose tracker accepts it (no trocar left to the scene) and holds the eye at the scene's centre.
  PoseTracker tracker(makeDefaultRig(), layout);
  EXPECT_EQ(tracker.update({}).eye.rotation_center, Eigen::Vector3d(0.001, 0.0, 0.0));
}

TEST(SceneEye, AScenesOmittedCentreIsTheWorldOrigin) {
  // navigation writes no eye centre: the loader (and so the simulation) puts the eye at the origin.
  const scene::SceneDescription navigation = vrm_sim::scene::loadScene("navigation");
  MarkerLayout layout = makeDefaultLayout();
  layout.rotation_center = Eigen::Vector3d(0.0, 0.003, 0.0);
  applyScene(navigation, &layout);
  EXPECT_EQ(layout.rotation_center, Eigen::Vector3d::Zero());
}

TEST(SceneEye, TheScenesScriptedSessionPlaysInTheScenesEye) {
  // scene_switch.test's scene: membrane_peeling with the eye 1 mm off and the trocars at 140 / 40 deg.
  const scene::SceneDescription moved = vrm_sim::scene::loadScene(kSourceDir + "/test/rostest/scene_switch.yaml");
  const SurgeonScript expert = playInScene(moved, loadSession("scenario:expert", moved));
  EXPECT_EQ(expert.eye().rotation_center, Eigen::Vector3d(0.001, 0.0, 0.0));
  EXPECT_EQ(expert.sample(1.0).rotation_center, Eigen::Vector3d(0.001, 0.0, 0.0));
  ASSERT_EQ(expert.tracks().size(), 1u);
  expectNear(expert.tracks()[0].trocar, onEyeSphere(0.012, 45.0, 40.0), 1e-15);
}

TEST(SceneEye, AFailingSceneLeavesTheLayoutUntouched) {
  const scene::SceneDescription one = scene::loadSceneFromString(R"(scene: {name: one_trocar, kind: abstract}
eye:
  centre: [0.001, 0.0, 0.0]
  trocars:
    - {name: left, angle_from_optical_axis_deg: 40.0, azimuth_deg: 170.0}
objects:
  - {name: ball, role: abstract_target, mesh: {generator: sphere, params: {radius: 0.001}}}
simulations: [collision]
)",
                                                                 "one_trocar.yaml");
  MarkerLayout layout = makeDefaultLayout();
  const MarkerLayout before = layout;
  EXPECT_THROW(applyScene(one, &layout), std::runtime_error);
  EXPECT_EQ(layout.rotation_center, before.rotation_center);
  for (std::size_t i = 0; i < layout.instruments.size(); ++i) {
    EXPECT_EQ(layout.instruments[i].trocar, before.instruments[i].trocar);
  }
}

TEST(SceneEye, DiagnosticValuesShowTheSceneGeometry) {
  const scene::SceneDescription moved = scene::loadSceneFromString(kMovedEye, "moved_eye.yaml");
  MarkerLayout layout = makeDefaultLayout();
  applyScene(moved, &layout);
  const auto values = sceneGeometryValues(moved.name, layout);
  const auto value = [&values](const std::string& key) {
    for (const auto& [k, v] : values) {
      if (k == key) return v;
    }
    return std::string("<missing>");
  };
  EXPECT_EQ(value("scene"), "moved_eye");
  EXPECT_EQ(value("eye_centre"), "0.001000 0.000000 0.000000");
  EXPECT_EQ(value("trocar_left_azimuth_deg"), "140.00");
  EXPECT_EQ(value("trocar_right_azimuth_deg"), "40.00");
  // 12 mm * sin 45 deg * (cos 40, sin 40), 12 mm * cos 45 deg
  EXPECT_EQ(value("trocar_right"), "0.006500 0.005454 0.008485");
  EXPECT_EQ(value("trocar_left"), "-0.006500 0.005454 0.008485");
  // Below the x axis: azimuths as scene files write them, in [0, 360).
  layout.instruments[0].trocar = Eigen::Vector3d(0.0, -0.0085, 0.0085);
  EXPECT_EQ(sceneGeometryValues("s", layout).at(2).second, "0.000000 -0.008500 0.008500");
  EXPECT_EQ(sceneGeometryValues("s", layout).at(3).second, "270.00");
}

// What a follower compares with an announcement: the file, the level and the file's content, not the name.
TEST(SceneIdentity, FileLevelAndContentDecideNotTheName) {
  const std::string path = ::testing::TempDir() + "scene_identity_test.yaml";
  {
    std::ofstream out(path);
    out << kMovedEye;
  }
  const scene::SceneDescription loaded = vrm_sim::scene::loadScene(path);
  const SceneIdentity identity = sceneIdentity(loaded);
  EXPECT_EQ(identity.name, "moved_eye");
  EXPECT_EQ(identity.file, loaded.source_file);
  EXPECT_EQ(identity.difficulty, "");
  EXPECT_EQ(identity.content_hash, vrm_sim::scene::sceneContentHash(loaded.source_file, ""));
  EXPECT_NE(identity.content_hash, 0u);

  SceneIdentity announced = identity;
  announced.name = "renamed";  // the name alone is no other scene
  EXPECT_TRUE(sameScene(identity, announced));
  announced = identity;
  announced.difficulty = "hard";
  EXPECT_FALSE(sameScene(identity, announced));
  announced = identity;
  announced.file = "/elsewhere/moved_eye.yaml";
  EXPECT_FALSE(sameScene(identity, announced));
  // Edited on disk under the same name and path: another scene.
  {
    std::ofstream out(path, std::ios::app);
    out << "# edited\n";
  }
  EXPECT_FALSE(sameScene(identity, sceneIdentity(vrm_sim::scene::loadScene(path))));
  std::remove(path.c_str());
}

TEST(SceneTrocars, SceneSpecIsANameOrAPath) {
  const scene::SceneDescription by_name = vrm_sim::scene::loadScene("navigation");
  EXPECT_EQ(by_name.name, "navigation");
  EXPECT_EQ(vrm_sim::scene::loadScene(by_name.source_file).name, "navigation");
  EXPECT_THROW(vrm_sim::scene::loadScene("no_such_scene"), scene::SceneError);
}

// ---- Waypoints written on scene objects (vrm_sim surface_target.h, playInScene) ----

// The membrane of the shipped membrane_peeling scene: 0.3 mm above the 12 mm retina, centred 8 deg from the pole.
constexpr double kMembraneSphereRadius = 0.012 - 0.0003;

vrm_sim::TriangleMesh sceneMesh(const scene::SceneDescription& description, const std::string& object_name) {
  const scene::ObjectDescription* object = description.findObject(object_name);
  if (object == nullptr) throw std::runtime_error("test scene has no object " + object_name);
  return scene::buildMesh(*object, scene::MeshFrame::kParent);
}

// Height of `point` above the surface (along its inward normal; negative below), as the tissue simulation sees it.
double heightAbove(const vrm_sim::TriangleMesh& surface, const Eigen::Vector3d& point) {
  const scene::SurfacePoint nearest = scene::closestSurfacePoint(surface, point);
  return (point - nearest.position).dot(nearest.inward_normal);
}

// Waypoints 1-3 on the membrane at three heights, from written tips that are off the membrane (one outside it,
// towards the retina; one inside the eye); waypoint 4 stays there and closes the jaws; waypoint 5 is plain again.
const char* const kOnMembrane = R"(name: on_membrane
instruments:
  - slot: right
    type: forceps
    path:
      - {t: 0.0, tip: [0.001, 0.0, -0.006], jaw_angle_deg: 20}
      - {t: 6.0, on: membrane, tip: [0.00336, 0.0010, -0.0114], jaw_angle_deg: 17, roll_deg: 11}
      - {t: 7.0, on: membrane, tip: [0.00336, 0.0010, -0.0114], height: 0.0005}
      - {t: 8.0, on: membrane, tip: [0.0030, 0.0008, -0.0105], height: -0.00006}
      - {t: 8.5, on: membrane, tip: [0.0030, 0.0008, -0.0105], height: -0.00006, jaw_angle_deg: 0}
      - {t: 9.0, tip: [0.001, 0.0, -0.006]}
)";

scene::ScriptedSession onMembrane() { return scene::loadScriptFromString(kOnMembrane, "on_membrane.yaml"); }

TEST(SceneTargets, ResolvedTipLiesOnTheMembraneAndHeightFollowsTheInwardNormal) {
  const scene::SceneDescription peeling = vrm_sim::scene::loadScene("membrane_peeling");
  const vrm_sim::TriangleMesh membrane = sceneMesh(peeling, "membrane");
  const scene::ScriptedSession written = onMembrane();
  EXPECT_EQ(scene::surfaceTargetObjects(written), std::vector<std::string>{"membrane"});
  scene::SurfaceTargetReport report;
  const SurgeonScript script = playInScene(peeling, written, &report);
  EXPECT_EQ(report.resolved_waypoints, 4u);
  EXPECT_EQ(report.kept_waypoints, 0u);
  EXPECT_TRUE(report.missing_objects.empty());
  const std::vector<scene::InstrumentWaypoint>& keys = script.session().instruments.at(0).path;
  const std::vector<scene::InstrumentWaypoint>& before = written.instruments.at(0).path;
  ASSERT_EQ(keys.size(), 6u);
  EXPECT_TRUE(scene::surfaceTargetObjects(script.session()).empty());  // all resolved

  // Height 0: on the mesh, and (independently of the closest-point code) on the membrane's sphere; the chords of
  // the ~0.16 mm triangles lie < 0.3 um inside it.
  const Eigen::Vector3d on_surface = keys[1].tip_in_eye;
  EXPECT_LT(scene::closestSurfacePoint(membrane, on_surface).distance, 1e-6);
  EXPECT_NEAR(on_surface.norm(), kMembraneSphereRadius, 1e-6);
  // No vertex is nearer to the written tip than the resolved point (it is the closest point, not a nearby one).
  double nearest_vertex = 1.0;
  for (const Eigen::Vector3d& vertex : membrane.vertices) {
    nearest_vertex = std::min(nearest_vertex, (vertex - before[1].tip_in_eye).norm());
  }
  EXPECT_LE((on_surface - before[1].tip_in_eye).norm(), nearest_vertex + 1e-12);
  // The waypoint keeps its other fields.
  EXPECT_DOUBLE_EQ(keys[1].jaw_angle_deg, 17.0);
  EXPECT_DOUBLE_EQ(keys[1].roll_deg, 11.0);
  EXPECT_DOUBLE_EQ(keys[1].t, 6.0);

  // Height 0.5 mm from the same written tip: straight up the inward normal, which near the posterior pole is
  // roughly +z (towards the eye centre).
  const Eigen::Vector3d lifted = keys[2].tip_in_eye - on_surface;
  EXPECT_NEAR(lifted.norm(), 0.0005, 1e-9);
  EXPECT_GT(lifted.normalized().z(), 0.9);
  EXPECT_GT(lifted.normalized().dot(-on_surface.normalized()), 0.9999);
  EXPECT_NEAR(keys[2].tip_in_eye.norm(), kMembraneSphereRadius - 0.0005, 2e-6);
  EXPECT_NEAR(heightAbove(membrane, keys[2].tip_in_eye), 0.0005, 1e-9);

  // Negative height: below the membrane; the same written point resolves to the same point.
  EXPECT_NEAR(heightAbove(membrane, keys[3].tip_in_eye), -0.00006, 1e-9);
  EXPECT_NEAR(keys[3].tip_in_eye.norm(), kMembraneSphereRadius + 0.00006, 2e-6);
  EXPECT_LT((keys[4].tip_in_eye - keys[3].tip_in_eye).norm(), 1e-15);

  // Waypoints without `on` are unchanged.
  EXPECT_EQ(keys[0].tip_in_eye, before[0].tip_in_eye);
  EXPECT_EQ(keys[5].tip_in_eye, before[5].tip_in_eye);

  // The played script follows the resolved waypoints, through the scene's trocar.
  const InstrumentSample at_grasp = script.sample(8.0).instruments.at(0);
  EXPECT_LT((at_grasp.tip - keys[3].tip_in_eye).norm(), 1e-12);
  EXPECT_LT((at_grasp.trocar - sceneTrocarForSlot(peeling, "right")).norm(), 1e-12);

  // The offline tools resolve the same points (withScript of a scene's session, runScenario of a file).
  const scene::SceneDescription offline = scene::withScript(peeling, scene::resolveSurfaceTargets(peeling, written));
  for (std::size_t i = 0; i < keys.size(); ++i) {
    EXPECT_EQ(offline.findInstrument(scene::InstrumentSlot::kRight)->path[i].tip_in_eye, keys[i].tip_in_eye) << i;
  }
}

TEST(SceneTargets, ClosestPointOnAFlatSquare) {
  // Two triangles of the plane z = -0.01 (eye centre above it: the inward normal is +z), x, y in [0, 1] mm.
  vrm_sim::TriangleMesh square;
  square.name = "square";
  square.vertices = {{0.0, 0.0, -0.01}, {0.001, 0.0, -0.01}, {0.001, 0.001, -0.01}, {0.0, 0.001, -0.01}};
  square.triangles = {{0, 1, 2}, {0, 2, 3}};  // wound away from the centre: the normal must still point up
  const scene::SurfacePoint inside = scene::closestSurfacePoint(square, Eigen::Vector3d(0.0004, 0.0003, -0.012));
  expectNear(inside.position, Eigen::Vector3d(0.0004, 0.0003, -0.01), 1e-15);
  expectNear(inside.inward_normal, Eigen::Vector3d::UnitZ(), 1e-12);
  EXPECT_NEAR(inside.distance, 0.002, 1e-15);
  // Beyond an edge and a corner: the nearest boundary point.
  expectNear(scene::closestSurfacePoint(square, Eigen::Vector3d(0.0005, -0.002, -0.0095)).position,
             Eigen::Vector3d(0.0005, 0.0, -0.01), 1e-15);
  expectNear(scene::closestSurfacePoint(square, Eigen::Vector3d(0.003, 0.004, -0.0095)).position,
             Eigen::Vector3d(0.001, 0.001, -0.01), 1e-15);
  // On the shared diagonal both triangles are nearest: their (equal) normals, not a cancelled sum.
  expectNear(scene::resolveSurfaceTip(square, Eigen::Vector3d(0.0005, 0.0005, -0.011), 0.0002),
             Eigen::Vector3d(0.0005, 0.0005, -0.0098), 1e-15);
  EXPECT_THROW(scene::closestSurfacePoint(vrm_sim::TriangleMesh{}, Eigen::Vector3d::Zero()), std::invalid_argument);
}

TEST(SceneTargets, MissingObjectIsAnErrorNamingItTheWaypointAndTheScene) {
  const scene::SceneDescription navigation = vrm_sim::scene::loadScene("navigation");  // has no membrane
  try {
    playInScene(navigation, onMembrane());
    FAIL() << "a script file on an object the scene lacks must be rejected";
  } catch (const ScriptError& error) {
    const std::string message = error.what();
    EXPECT_EQ(error.location().file, "on_membrane.yaml");
    EXPECT_EQ(error.location().line, 7) << message;  // the first waypoint on the membrane
    EXPECT_EQ(error.location().field, "instruments[0].path[1].on") << message;
    EXPECT_NE(message.find("on_membrane.yaml:7:"), std::string::npos) << message;
    EXPECT_NE(message.find("'membrane'"), std::string::npos) << message;
    EXPECT_NE(message.find("t = 6 s"), std::string::npos) << message;
    EXPECT_NE(message.find("scene 'navigation'"), std::string::npos) << message;
    EXPECT_NE(message.find("target_sphere_1"), std::string::npos) << message;  // what the scene has instead
  }
}

TEST(SceneTargets, TheDemoOnAMissingObjectKeepsTheWrittenTips) {
  const scene::SceneDescription navigation = vrm_sim::scene::loadScene("navigation");
  const scene::ScriptedSession demo = loadSession("", navigation);
  ASSERT_TRUE(demo.keep_tip_on_missing_object);
  ASSERT_EQ(scene::surfaceTargetObjects(demo), std::vector<std::string>{"membrane"});
  scene::SurfaceTargetReport report;
  const SurgeonScript applied = playInScene(navigation, demo, &report);
  EXPECT_EQ(report.resolved_waypoints, 0u);
  EXPECT_EQ(report.kept_waypoints, 7u);
  EXPECT_EQ(report.missing_objects, std::vector<std::string>{"membrane"});
  for (std::size_t slot = 0; slot < demo.instruments.size(); ++slot) {
    const scene::ScriptedInstrument& played = applied.session().instruments[slot];
    expectNear(applied.tracks()[slot].trocar, sceneTrocarForSlot(navigation, scene::toString(played.slot)),
               1e-12);  // the trocars still apply
    for (std::size_t i = 0; i < played.path.size(); ++i) {
      EXPECT_EQ(played.path[i].tip_in_eye, demo.instruments[slot].path[i].tip_in_eye) << i;
    }
  }
  // The same session written for a scene would be an error.
  scene::ScriptedSession strict = demo;
  strict.keep_tip_on_missing_object = false;
  EXPECT_THROW(playInScene(navigation, strict), ScriptError);
}

TEST(SceneTargets, ObjectsInTheWorldFrameAreRejected) {
  const scene::SceneDescription world = scene::loadSceneFromString(R"(scene: {name: world_objects, kind: abstract}
objects:
  - {name: membrane, role: abstract_target, frame: world, mesh: {generator: sphere, params: {radius: 0.001}}}
simulations: [collision]
)",
                                                                   "world_objects.yaml");
  try {
    playInScene(world, onMembrane());
    FAIL() << "an object in the world frame must be rejected";
  } catch (const ScriptError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("world frame"), std::string::npos) << message;
    EXPECT_NE(message.find("'membrane'"), std::string::npos) << message;
    EXPECT_NE(message.find("world_objects"), std::string::npos) << message;
  }
}

// The demo, played in the shipped default scene, really grasps the membrane: when the jaws close, the tip
// is just below the membrane and vrm_sim's grasp region (TissueSimulator::updateGrasp: within 0.75 mm of the jaw
// centre 0.75 mm behind the tip, and within 0.3 mm of the shaft axis) holds membrane nodes; it peels and lets go
// early enough for a 20 s session.
TEST(SceneTargets, DemoGraspsTheShippedMembrane) {
  const scene::SceneDescription peeling = vrm_sim::scene::loadScene("membrane_peeling");
  const vrm_sim::TriangleMesh membrane = sceneMesh(peeling, "membrane");
  scene::SurfaceTargetReport report;
  SurgeonScript demo = playInScene(peeling, loadSession("", peeling), &report);
  demo.setTremorAmplitude(0.0);
  EXPECT_TRUE(report.missing_objects.empty());
  EXPECT_EQ(report.resolved_waypoints, 7u);
  const auto forceps = [&](double t) { return demo.sample(t).instruments.at(1); };
  ASSERT_EQ(forceps(0.0).slot, "right");
  ASSERT_EQ(forceps(0.0).type, scene::InstrumentType::kForceps);

  // The waypoint where the jaws have closed, and the moment they pass vrm_sim's grasp threshold on the way.
  constexpr double kGraspJawAngle = 0.15;  // rad, vrm_sim's default TissueConfig::grasp_jaw_angle
  const std::vector<scene::InstrumentWaypoint>& keys = demo.session().instruments.at(1).path;
  const auto closed = std::find_if(keys.begin() + 1, keys.end(),
                                   [](const scene::InstrumentWaypoint& key) { return key.jaw_angle_deg == 0.0; });
  ASSERT_NE(closed, keys.end());
  const double close_time = closed->t;
  double grasp_time = close_time;
  for (double t = (closed - 1)->t; t <= close_time; t += 1e-3) {
    if (forceps(t).jaw_angle < kGraspJawAngle) {
      grasp_time = t;
      break;
    }
  }
  EXPECT_LE(close_time, 6.0);
  EXPECT_GT(forceps(grasp_time - 0.3).jaw_angle, 0.3);  // closing takes about 0.3 s
  for (double t : {grasp_time, close_time}) {
    SCOPED_TRACE("t = " + std::to_string(t));
    const InstrumentSample tip = forceps(t);
    const double height = heightAbove(membrane, tip.tip);
    EXPECT_LE(height, 0.0) << "tip above the membrane: the jaws close on nothing";
    EXPECT_GE(height, -150e-6) << "tip too deep below the membrane";
    const Eigen::Vector3d jaw_centre = tip.tip - 0.00075 * tip.shaft_axis;
    int between_jaws = 0;
    for (const Eigen::Vector3d& node : membrane.vertices) {
      const Eigen::Vector3d from_centre = node - jaw_centre;
      const double off_axis = (from_centre - from_centre.dot(tip.shaft_axis) * tip.shaft_axis).norm();
      if (from_centre.norm() <= 0.00075 && off_axis <= 0.0003) ++between_jaws;
    }
    EXPECT_GE(between_jaws, 3) << "membrane nodes in vrm_sim's grasp region";
  }

  // Grasped point between the adhesion ring (1.5 mm from the membrane centre) and the edge (2.5 mm), on the side
  // facing the right trocar.
  const Eigen::Vector3d membrane_centre = membrane.vertices.at(0);  // the cap's pole vertex is the patch centre
  const Eigen::Vector3d grasp_point = scene::closestSurfacePoint(membrane, forceps(close_time).tip).position;
  const double from_centre = (grasp_point - membrane_centre).norm();
  EXPECT_GT(from_centre, 0.0017);
  EXPECT_LT(from_centre, 0.0023);
  const Eigen::Vector3d trocar = sceneTrocarForSlot(peeling, "right");
  EXPECT_GT((grasp_point - membrane_centre).head<2>().normalized().dot(trocar.head<2>().normalized()), 0.95);

  // Peel: jaws stay closed while the tip rises ~1.2 mm above the grasp point and moves ~1 mm towards the centre.
  double release_time = 0.0;
  for (double t = close_time; t < 20.0; t += 0.01) {
    if (forceps(t).jaw_angle > kGraspJawAngle) {
      release_time = t;
      break;
    }
  }
  ASSERT_GT(release_time, close_time + 4.0);
  EXPECT_LT(release_time, 12.0);
  const Eigen::Vector3d peeled = forceps(release_time - 0.35).tip;
  EXPECT_NEAR(heightAbove(membrane, peeled), 0.0012, 5e-5);
  const Eigen::Vector3d peeled_foot = scene::closestSurfacePoint(membrane, peeled).position;
  EXPECT_NEAR((grasp_point - peeled_foot).norm(), 0.001, 1e-4);
  EXPECT_LT((peeled_foot - membrane_centre).norm(), from_centre - 0.0009);
  // Back at the start by 14 s and resting there until the loop ends.
  EXPECT_LT((forceps(14.0).tip - forceps(0.0).tip).norm(), 1e-12);
  EXPECT_LT((forceps(39.9).tip - forceps(0.0).tip).norm(), 1e-12);
  EXPECT_GT(forceps(14.0).jaw_angle, kGraspJawAngle);
}

// The scripts that target tissue, played through the simulation core exactly as the graph would at 50 Hz: the grasp
// must catch the membrane and lift it. Fails when a script's grasp misses (e.g. closes above the membrane).

vrm_sim::world::TissueReport playThroughTheCore(const scene::SceneDescription& scene, SurgeonScript script,
                                                double seconds, std::size_t* max_grasped) {
  script.setTremorAmplitude(0.0);
  vrm_sim::world::World world(scene);
  *max_grasped = 0;
  for (int tick = 0; tick <= static_cast<int>(seconds * 50.0); ++tick) {
    const double t = tick / 50.0;
    const SurgeonSnapshot snapshot = script.sample(t);
    vrm_sim::world::EyeState eye;
    eye.stamp = vrm_sim::world::fromSeconds(t);
    eye.rotation = snapshot.eye_rotation;
    eye.rotation_center = snapshot.rotation_center;
    world.handle(eye);
    for (const InstrumentSample& sample : snapshot.instruments) {
      vrm_sim::world::InstrumentState state;
      state.stamp = eye.stamp;
      state.slot = sample.slot;
      state.type = sample.type;
      state.tip_position = sample.tip;
      state.tip_orientation = sample.orientation;
      state.jaw_angle = sample.jaw_angle;
      state.suction = sample.suction;
      state.cut_rate = sample.cut_rate;
      world.handle(state);
    }
    *max_grasped = std::max(*max_grasped, world.tissueReport("membrane").grasped_nodes);
  }
  world.flush();
  return world.tissueReport("membrane");
}

TEST(SceneTargets, TheDemoScriptsGraspAndPeelTheMembraneInTheSimulationCore) {
  const scene::SceneDescription peeling = vrm_sim::scene::loadScene("membrane_peeling");
  std::size_t grasped = 0;
  const vrm_sim::world::TissueReport demo =
      playThroughTheCore(peeling, playInScene(peeling, loadSession("", peeling)), 12.0, &grasped);
  EXPECT_GT(grasped, 0u) << "the demo's grasp misses the membrane";
  EXPECT_GT(demo.max_lift, 5e-4);
  EXPECT_NE(demo.outcome, vrm_sim::world::PeelOutcome::kUntouched);

  const vrm_sim::world::TissueReport peel =
      playThroughTheCore(peeling, playInScene(peeling, loadSession("membrane_peeling_demo", peeling)), 18.0, &grasped);
  EXPECT_GT(grasped, 0u) << "membrane_peeling_demo.yaml's grasp misses the membrane";
  EXPECT_GT(peel.max_lift, 5e-4);

  // Control: the same demo without the scene's targets (its written tips, against the membrane lying on the retina 0.3
  // mm deeper) must miss — the test can fail.
  scene::SceneDescription deeper = peeling;
  for (auto& object : deeper.objects) {
    if (object.name != "membrane") continue;
    auto& params = std::get<vrm_sim::scene::MembraneParams>(*object.mesh.generator);
    params.height_above_retina = 0.0;
  }
  scene::ScriptedSession written_tips = loadSession("", peeling);
  for (scene::ScriptedInstrument& instrument : written_tips.instruments) {
    for (scene::InstrumentWaypoint& waypoint : instrument.path) waypoint.on.clear();
  }
  playThroughTheCore(deeper, playInScene(deeper, written_tips), 12.0, &grasped);
  EXPECT_EQ(grasped, 0u);
}

}  // namespace
}  // namespace vrm_tracking
