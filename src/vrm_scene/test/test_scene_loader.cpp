// Scene files: the shipped scenes load and build, and every kind of mistake is reported with file, line and field.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/mesh_validation.h"
#include "vrm_scene/scene_loader.h"

namespace vrm_sim {
namespace scene {
namespace {

const std::string kPackageDir = VRM_SIM_SOURCE_DIR;
const std::string kTestScenes = std::string(VRM_SCENE_SOURCE_DIR) + "/test/data/scenes/";

// Loads `yaml` and returns the SceneError message; fails the test if loading succeeds.
std::string loadError(const std::string& yaml, const std::string& virtual_path = "inline_scene.yaml") {
  try {
    loadSceneFromString(yaml, virtual_path);
  } catch (const SceneError& error) {
    return error.what();
  } catch (const std::exception& error) {
    ADD_FAILURE() << "expected a SceneError, got another exception: " << error.what();
    return "";
  }
  ADD_FAILURE() << "expected a SceneError for:\n" << yaml;
  return "";
}

// A valid abstract scene to which the error tests add one mistake each.
const char* const kMinimalScene = R"(scene: {name: minimal, kind: abstract}
objects:
  - name: ball
    role: abstract_target
    mesh: {generator: sphere, params: {radius: 0.001}}
simulations: [collision]
)";

TEST(SceneLoader, MinimalSceneGetsDefaults) {
  const SceneDescription scene = loadSceneFromString(kMinimalScene, "minimal.yaml");
  EXPECT_EQ(scene.name, "minimal");
  EXPECT_EQ(scene.kind, SceneKind::kAbstract);
  ASSERT_EQ(scene.objects.size(), 1u);
  const ObjectDescription& ball = scene.objects[0];
  EXPECT_EQ(ball.frame, ObjectFrame::kEye);
  EXPECT_FALSE(ball.isDeformable());
  EXPECT_EQ(ball.collision.detector, "zcoll_f");
  ASSERT_TRUE(ball.mesh.generator.has_value());
  EXPECT_DOUBLE_EQ(std::get<SphereParams>(*ball.mesh.generator).radius, 0.001);
  EXPECT_EQ(std::get<SphereParams>(*ball.mesh.generator).ring_count, SphereParams{}.ring_count);
  EXPECT_DOUBLE_EQ(scene.eye.radius, 0.012);
  ASSERT_EQ(scene.eye.trocars.size(), 2u);  // the default pair
  EXPECT_NEAR(scene.eye.trocars[0].position_in_eye.norm(), 0.012, 1e-12);
  EXPECT_FALSE(scene.hasDeformableObjects());
  EXPECT_EQ(ball.location.line, 3);
}

TEST(SceneLoader, MembranePeelingScene) {
  const SceneDescription scene = loadScene(shippedScenePath("membrane_peeling"));
  EXPECT_EQ(scene.name, "membrane_peeling");
  EXPECT_EQ(scene.kind, SceneKind::kSurgical);
  EXPECT_TRUE(scene.hasDeformableObjects());
  EXPECT_TRUE(scene.simulates(Simulation::kTissue));
  EXPECT_TRUE(scene.simulates(Simulation::kBleeding));

  const ObjectDescription* retina = scene.findObject("retina");
  ASSERT_NE(retina, nullptr);
  EXPECT_EQ(retina->role, ObjectRole::kRetina);
  EXPECT_DOUBLE_EQ(std::get<RetinaParams>(*retina->mesh.generator).radius, scene.eye.radius);

  const ObjectDescription* membrane = scene.findObject("membrane");
  ASSERT_NE(membrane, nullptr);
  EXPECT_EQ(membrane->tissue.model, "mass_spring");
  EXPECT_EQ(membrane->tissue.integrator, "auto");
  EXPECT_DOUBLE_EQ(membrane->tissue.stiffness, 2.0);
  EXPECT_DOUBLE_EQ(membrane->tissue.strain_limit, 1.1);
  EXPECT_DOUBLE_EQ(membrane->tissue.adhesion_stiffness, 5.0);
  EXPECT_EQ(std::get<MembraneParams>(*membrane->mesh.generator).adhesion_point_count, 7);
  EXPECT_DOUBLE_EQ(membrane->material.diffuse_rgba[3], 0.55);

  const InstrumentDescription* left = scene.findInstrument(InstrumentSlot::kLeft);
  const InstrumentDescription* right = scene.findInstrument(InstrumentSlot::kRight);
  ASSERT_NE(left, nullptr);
  ASSERT_NE(right, nullptr);
  EXPECT_EQ(left->type, InstrumentType::kLightPipe);
  EXPECT_EQ(right->type, InstrumentType::kForceps);
  ASSERT_EQ(right->alternatives.size(), 1u);
  EXPECT_EQ(right->alternatives[0], InstrumentType::kVitrector);
  const Trocar* right_trocar = scene.findTrocar(right->trocar);
  ASSERT_NE(right_trocar, nullptr);
  EXPECT_NEAR(right_trocar->position_in_eye.norm(), scene.eye.radius, 1e-12);
  EXPECT_GT(right_trocar->position_in_eye.x(), 0.0);
  EXPECT_GT(right_trocar->position_in_eye.z(), 0.0);  // anterior half, towards the microscope
}

TEST(SceneLoader, NavigationSceneHasNoDeformables) {
  const SceneDescription scene = loadScene(shippedScenePath("navigation"));
  EXPECT_EQ(scene.kind, SceneKind::kAbstract);
  EXPECT_FALSE(scene.hasDeformableObjects());
  EXPECT_FALSE(scene.simulates(Simulation::kTissue));
  EXPECT_TRUE(scene.simulates(Simulation::kCollision));
  for (const auto& object : scene.objects) EXPECT_EQ(object.collision.detector, "geometric") << object.name;
  EXPECT_EQ(scene.findInstrument(InstrumentSlot::kRight)->type, InstrumentType::kNeedle);
  const ObjectDescription* ring = scene.findObject("ring");
  ASSERT_NE(ring, nullptr);
  EXPECT_TRUE(std::holds_alternative<TorusParams>(*ring->mesh.generator));
  EXPECT_DOUBLE_EQ(ring->pose.rpy_deg.x(), 60.0);
}

TEST(SceneLoader, IlmPeelingScene) {
  const SceneDescription scene = loadScene(shippedScenePath("ilm_peeling"));
  const ObjectDescription* ilm = scene.findObject("ilm");
  ASSERT_NE(ilm, nullptr);
  EXPECT_EQ(ilm->role, ObjectRole::kIlm);
  EXPECT_GT(ilm->tissue.stiffness,
            loadScene(shippedScenePath("membrane_peeling")).findObject("membrane")->tissue.stiffness);
  EXPECT_EQ(scene.findInstrument(InstrumentSlot::kRight)->alternatives.at(0), InstrumentType::kHook);
}

TEST(SceneLoader, ShippedScenesBuildUsableMeshes) {
  for (const std::string name : {"membrane_peeling", "navigation", "ilm_peeling"}) {
    const SceneDescription scene = loadScene(shippedScenePath(name));
    const std::vector<TriangleMesh> meshes = resolveMeshes(scene);
    ASSERT_EQ(meshes.size(), scene.objects.size());
    for (std::size_t i = 0; i < meshes.size(); ++i) {
      const MeshReport report = validateMesh(meshes[i]);
      EXPECT_EQ(meshes[i].name, scene.objects[i].name);
      EXPECT_TRUE(report.isUsable()) << name << "/" << meshes[i].name << ": " << report.summary();
      EXPECT_EQ(report.degenerate_triangles, 0u) << name << "/" << meshes[i].name;
    }
    for (const auto& instrument : scene.instruments) {
      const TriangleMesh mesh = buildInstrumentMesh(instrument);
      EXPECT_TRUE(validateMesh(mesh).isClosed()) << name << "/" << mesh.name;
    }
  }
}

TEST(SceneLoader, PoseIsAppliedInParentFrame) {
  const SceneDescription scene = loadScene(shippedScenePath("navigation"));
  const ObjectDescription& sphere = *scene.findObject("target_sphere_1");
  const TriangleMesh local = buildMesh(sphere, MeshFrame::kLocal);
  const TriangleMesh placed = buildMesh(sphere, MeshFrame::kParent);
  EXPECT_TRUE(boundingBox(local).center().isZero(1e-12));
  EXPECT_TRUE(boundingBox(placed).center().isApprox(Eigen::Vector3d(0.003, 0.002, -0.008), 1e-9));
}

// What the one scene owner announces (running_scene.content_hash) and a follower compares: the file's bytes and the
// level, nothing else.
TEST(SceneContentHash, FileBytesAndLevel) {
  const std::string shipped = shippedScenePath("navigation");
  const std::uint64_t hash = sceneContentHash(shipped, "");
  EXPECT_NE(hash, 0u);
  EXPECT_EQ(sceneContentHash(shipped, ""), hash);
  EXPECT_NE(sceneContentHash(shipped, "hard"), hash);
  EXPECT_EQ(sceneContentHash("/nonexistent/scene.yaml", ""), 0u);
  EXPECT_EQ(std::string(kDefaultSceneName), "membrane_peeling");
  EXPECT_NO_THROW(loadScene(kDefaultSceneName));

  // A copy is the same content; one byte more is another scene under the same name.
  const std::filesystem::path copy = std::filesystem::temp_directory_path() / "vrm_content_hash_navigation.yaml";
  std::filesystem::copy_file(shipped, copy, std::filesystem::copy_options::overwrite_existing);
  EXPECT_EQ(sceneContentHash(copy.string(), ""), hash);
  {
    std::ofstream append(copy, std::ios::app);
    append << "\n";
  }
  EXPECT_NE(sceneContentHash(copy.string(), ""), hash);
  // The level is separated from the bytes: moving a character between them changes the hash.
  EXPECT_NE(sceneContentHash(copy.string(), "a"), sceneContentHash(shipped, "\na"));
  std::filesystem::remove(copy);
}

TEST(SceneLoader, MeshFileRelativeToSceneFile) {
  const SceneDescription scene = loadScene(kTestScenes + "imported_mesh.yaml");
  const ObjectDescription& cube = scene.objects.at(0);
  EXPECT_FALSE(cube.mesh.generator.has_value());
  EXPECT_NE(cube.mesh.file.find("cube_quads.obj"), std::string::npos);
  const TriangleMesh mesh = buildMesh(cube);
  EXPECT_EQ(mesh.triangleCount(), 12u);
  EXPECT_NEAR(signedVolume(mesh), 1e-9, 1e-15);
  EXPECT_NEAR(boundingBox(mesh).min().z(), -0.005, 1e-9);
}

TEST(SceneLoader, RetinaAndMembraneFollowEyeRadius) {
  const SceneDescription scene = loadSceneFromString(R"(scene: {name: small_eye, kind: surgical}
eye: {radius: 0.011}
objects:
  - {name: retina, role: retina, mesh: {generator: retina}}
  - name: membrane
    role: membrane
    mesh: {generator: membrane}
    tissue: {model: chainmail}
simulations: [tissue]
)",
                                                     "small_eye.yaml");
  EXPECT_DOUBLE_EQ(std::get<RetinaParams>(*scene.objects[0].mesh.generator).radius, 0.011);
  EXPECT_DOUBLE_EQ(std::get<MembraneParams>(*scene.objects[1].mesh.generator).retina_radius, 0.011);
  EXPECT_EQ(scene.objects[1].tissue.model, "chainmail");
}

// ---- errors -------------------------------------------------------------------------------------------------

TEST(SceneErrors, WrongTypeNamesFileLineColumnAndField) {
  const std::string message = loadError(R"(scene: {name: x, kind: surgical}
objects:
  - {name: retina, role: retina, mesh: {generator: retina}}
  - name: membrane
    role: membrane
    mesh: {generator: membrane}
    tissue:
      model: mass_spring
      stiffness: abc
simulations: [tissue]
)",
                                        "membrane_peeling.yaml");
  EXPECT_EQ(message, "membrane_peeling.yaml:9:18: objects[1].tissue.stiffness: expected a positive number, got 'abc'");
}

TEST(SceneErrors, MissingFile) {
  try {
    loadScene(kTestScenes + "does_not_exist.yaml");
    FAIL() << "no error";
  } catch (const SceneError& error) {
    EXPECT_NE(std::string(error.what()).find("does_not_exist.yaml"), std::string::npos);
    EXPECT_NE(std::string(error.what()).find("not found"), std::string::npos);
  }
}

TEST(SceneErrors, SyntaxErrorHasLine) {
  try {
    loadScene(kTestScenes + "syntax_error.yaml");
    FAIL() << "no error";
  } catch (const SceneError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("syntax_error.yaml:"), std::string::npos) << message;
    EXPECT_NE(message.find("YAML syntax error"), std::string::npos) << message;
    EXPECT_GT(error.location().line, 0) << message;
  }
}

TEST(SceneErrors, MisspeltKeyIsRejectedWithSuggestion) {
  try {
    loadScene(kTestScenes + "typo_in_tissue.yaml");
    FAIL() << "no error";
  } catch (const SceneError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("typo_in_tissue.yaml:8:7: objects[0].tissue.stifness: unknown key"), std::string::npos)
        << message;
    EXPECT_NE(message.find("did you mean 'stiffness'"), std::string::npos) << message;
  }
}

TEST(SceneErrors, EachMistakeNamesLineAndField) {
  struct Case {
    std::string yaml;
    std::string expected;  // substring of the message, after "inline_scene.yaml:"
  };
  const std::string base = kMinimalScene;
  const auto replace = [&base](const std::string& from, const std::string& to) {
    std::string yaml = base;
    const auto at = yaml.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return yaml.replace(at, from.size(), to);
  };
  const std::vector<Case> cases = {
      {replace("radius: 0.001", "radius: -0.001"), "5:48: objects[0].mesh.params.radius: expected a positive number"},
      {replace("radius: 0.001", "radius: .nan"),
       "objects[0].mesh.params.radius: expected a positive number, got '.nan'"},
      {replace("radius: 0.001", "radius: nan"), "objects[0].mesh.params.radius: expected a positive number, got 'nan'"},
      {replace("radius: 0.001", "radius: [1, 2]"),
       "objects[0].mesh.params.radius: expected a positive number, got a list"},
      {replace("radius: 0.001", "raduis: 0.001"),
       "objects[0].mesh.params.raduis: unknown key (did you mean 'radius'?)"},
      {replace("kind: abstract", "kind: abstrct"),
       "1:30: scene.kind: expected one of abstract, surgical, got 'abstrct'"},
      {replace("generator: sphere", "generator: spheer"), "objects[0].mesh.generator: expected one of"},
      {replace("role: abstract_target", "role: target"), "4:11: objects[0].role: expected one of"},
      {replace("    role: abstract_target\n", ""), "objects[0]: missing required key 'role'"},
      {replace("simulations: [collision]\n", ""), "missing required key 'simulations'"},
      {replace("simulations: [collision]", "simulations: [collision, collision]"), "simulations[1]: listed twice"},
      {replace("simulations: [collision]", "simulations: [colision]"), "simulations[0]: expected one of"},
      {replace("simulations: [collision]", "simulations: [tissue]"),
       "simulations: 'tissue' is listed but no object has a tissue model"},
      {replace("mesh: {generator: sphere, params: {radius: 0.001}}", "mesh: {generator: sphere, file: x.obj}"),
       "objects[0].mesh: give either 'generator' or 'file'"},
      {replace("mesh: {generator: sphere, params: {radius: 0.001}}", "mesh: {file: no_such_mesh.obj}"),
       "objects[0].mesh.file: mesh file 'no_such_mesh.obj' not found"},
      {replace("mesh: {generator: sphere, params: {radius: 0.001}}", "mesh: {generator: sphere, scale: 2}"),
       "objects[0].mesh.scale: 'scale' applies to mesh files only"},
      {replace("mesh: {generator: sphere, params: {radius: 0.001}}",
               "mesh: {generator: torus, params: {major_radius: 0.001, minor_radius: 0.002}}"),
       "objects[0].mesh.params: torus: minor_radius must be smaller than major_radius"},
      {replace("mesh: {generator: sphere, params: {radius: 0.001}}",
               "mesh: {generator: sphere, params: {ring_count: 2.5}}"),
       "objects[0].mesh.params.ring_count: expected an integer in [2, 2000], got '2.5'"},
      {replace("name: ball", "name: ball\n    tissue: {model: mass_spring}"),
       "objects[0].tissue.model: an object with role 'abstract_target' cannot be deformable"},
      {replace("name: ball", "name: ball\n    material: {diffuse: [1, 0, 0]}"),
       "objects[0].material.diffuse: expected a list of 4 numbers, got a list of 3"},
      {replace("name: ball", "name: ball\n    material: {diffuse: [1, 0, 0, 1.5]}"),
       "objects[0].material.diffuse[3]: expected a colour component in [0, 1], got '1.5'"},
      {replace("name: ball", "name: ball\n    frame: eye\n    frame: world"), "objects[0].frame: duplicate key"},
      {replace("name: ball", "name: ball\n    pose: {xyz: [0, 0, inf]}"),
       "objects[0].pose.xyz[2]: expected a finite number, got 'inf'"},
      {base + "instruments:\n  - {slot: left, type: light_pipe, trocar: top}\n",
       "instruments[0].trocar: unknown trocar 'top'; the eye has: left, right"},
      {base + "instruments:\n  - {slot: left, type: laser}\n", "instruments[0].type: expected one of"},
      {base + "instruments:\n  - {slot: left, type: needle}\n  - {slot: left, type: hook}\n",
       "instruments[1]: slot 'left' already has an instrument"},
      {base + "instruments:\n  - {slot: left, type: forceps, params: {jaw_angle_deg: 200}}\n",
       "instruments[0].params.jaw_angle_deg: expected an angle in [0, 180] degrees, got '200'"},
      {base + "instruments:\n  - {slot: left, type: needle, params: {jaw_length: 0.001}}\n",
       "instruments[0].params.jaw_length: unknown key"},
      {base + "eye: {radius: 0}\n", "eye.radius: expected a positive number, got '0'"},
      {base + "eye:\n  trocars:\n    - {name: left, azimuth_deg: 30}\n",
       "eye.trocars[0]: a trocar needs 'position' or both"},
      {base + "objects_extra: 1\n", "objects_extra: unknown key"},
      {base + "format_version: 2\n", "format_version: expected an integer in [1, 1], got '2'"},
      {"- just\n- a list\n", "1:1: a scene file must be a map"},
      {"", "a scene file must be a map"},
  };
  for (const Case& test_case : cases) {
    const std::string message = loadError(test_case.yaml);
    EXPECT_EQ(message.rfind("inline_scene.yaml:", 0), 0u) << message;
    EXPECT_NE(message.find(test_case.expected), std::string::npos)
        << "message: " << message << "\nexpected: " << test_case.expected;
  }
}

TEST(SceneErrors, DeformableObjectRequiresTissueSimulation) {
  const std::string message = loadError(R"(scene: {name: x, kind: surgical}
objects:
  - name: membrane
    role: membrane
    mesh: {generator: membrane}
    tissue: {model: mass_spring}
simulations: [collision]
)");
  EXPECT_NE(message.find("inline_scene.yaml:6:21: objects[0].tissue.model: the object is deformable but"),
            std::string::npos)
      << message;
}

TEST(SceneErrors, AbstractSceneRejectsDeformables) {
  const std::string message = loadError(R"(scene: {name: x, kind: abstract}
objects:
  - name: membrane
    role: membrane
    mesh: {generator: membrane}
    tissue: {model: mass_spring}
simulations: [tissue]
)");
  EXPECT_NE(message.find("objects[0].tissue.model: abstract scenes have no deformable objects"), std::string::npos)
      << message;
}

// Topology and ChainMail keys of issue 3 (tearing, chainmail limits).
std::string deformableScene(const std::string& tissue) {
  return "scene: {name: x, kind: surgical}\nobjects:\n  - name: membrane\n    role: membrane\n"
         "    mesh: {generator: membrane}\n    tissue: " +
         tissue + "\nsimulations: [tissue]\n";
}

TEST(SceneLoader, TearingAndChainMailKeys) {
  const SceneDescription defaults = loadSceneFromString(deformableScene("{model: mass_spring}"), "d.yaml");
  EXPECT_EQ(defaults.objects[0].tissue.tear_strain, 0.0);
  const SceneDescription torn =
      loadSceneFromString(deformableScene("{model: mass_spring, tear_strain: 1.5}"), "t.yaml");
  EXPECT_EQ(torn.objects[0].tissue.tear_strain, 1.5);
  const SceneDescription chainmail = loadSceneFromString(
      deformableScene("{model: chainmail, chainmail: {min_stretch: 0.9, max_stretch: 1.3, max_shear: 0.05, "
                      "relaxation: 0.25, relaxation_iterations: 3}}"),
      "c.yaml");
  const TissueParameters& tissue = chainmail.objects[0].tissue;
  EXPECT_EQ(tissue.model, "chainmail");
  EXPECT_EQ(tissue.chainmail.min_stretch, 0.9);
  EXPECT_EQ(tissue.chainmail.max_stretch, 1.3);
  EXPECT_EQ(tissue.chainmail.max_shear, 0.05);
  EXPECT_EQ(tissue.chainmail.relaxation, 0.25);
  EXPECT_EQ(tissue.chainmail.relaxation_iterations, 3);
  const SceneDescription refined = loadSceneFromString(
      deformableScene("{model: mass_spring, refinement: {levels: 2, radius: 0.002, element_budget: 500, "
                      "chain_stiffness_scaling: true}}"),
      "r.yaml");
  const RefinementParameters& refinement = refined.objects[0].tissue.refinement;
  EXPECT_EQ(refinement.levels, 2);
  EXPECT_EQ(refinement.radius, 0.002);
  EXPECT_EQ(refinement.element_budget, 500);
  EXPECT_TRUE(refinement.chain_stiffness_scaling);
  EXPECT_EQ(defaults.objects[0].tissue.refinement.levels, 0);
}

TEST(SceneErrors, TearingAndChainMailMistakes) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"{model: mass_spring, tear_strain: 1.0}",
       "6:47: objects[0].tissue.tear_strain: expected 0 (no tearing) or a number > 1"},
      {"{model: mass_spring, tear_strain: -2}", "objects[0].tissue.tear_strain: expected 0 (no tearing)"},
      {"{model: mass_spring, tear_strain: .nan}", "objects[0].tissue.tear_strain: expected 0 (no tearing)"},
      {"{model: mass_spring, tear_strain: .inf}", "objects[0].tissue.tear_strain: expected 0 (no tearing)"},
      {"{model: mass_spring, chainmail: {max_shear: 0.1}}",
       "objects[0].tissue.chainmail: chainmail limits need model: chainmail"},
      {"{model: chainmail, chainmail: {min_stretch: 1.1}}",
       "objects[0].tissue.chainmail.min_stretch: expected a number in (0, 1], got '1.1'"},
      {"{model: chainmail, chainmail: {min_stretch: 0}}", "objects[0].tissue.chainmail.min_stretch: expected"},
      {"{model: chainmail, chainmail: {max_stretch: 0.9}}",
       "objects[0].tissue.chainmail.max_stretch: expected a number >= 1, got '0.9'"},
      {"{model: chainmail, chainmail: {max_shear: -0.1}}", "objects[0].tissue.chainmail.max_shear: expected"},
      {"{model: chainmail, chainmail: {relaxation: 2}}", "objects[0].tissue.chainmail.relaxation: expected"},
      {"{model: mass_spring, refinement: {levels: 5}}",
       "objects[0].tissue.refinement.levels: expected an integer in [0, 4], got '5'"},
      {"{model: mass_spring, refinement: {radius: 0}}", "objects[0].tissue.refinement.radius: expected a positive"},
      {"{model: mass_spring, refinement: {element_budget: 0}}", "objects[0].tissue.refinement.element_budget:"},
      {"{model: mass_spring, refinement: {levels: 1, radius: 0.001, budget: 10}}",
       "objects[0].tissue.refinement.budget: unknown key"},
      {"{model: chainmail, refinement: {levels: 1}}",
       "objects[0].tissue.refinement: refinement needs model: mass_spring"},
      {"{model: mass_spring, bending_stiffness: 0.1, refinement: {levels: 1}}",
       "objects[0].tissue.refinement: refinement does not support bending springs"},
      {"{model: mass_spring, adhesion_stiffness: 1, refinement: {levels: 1}}",
       "objects[0].tissue.refinement: refinement does not support adhesion_stiffness"},
      {"{model: chainmail, chainmail: {max_sheer: 0.1}}",
       "objects[0].tissue.chainmail.max_sheer: unknown key (did you mean 'max_shear'?)"},
  };
  for (const auto& [tissue, expected] : cases) {
    const std::string message = loadError(deformableScene(tissue));
    EXPECT_NE(message.find("inline_scene.yaml:"), std::string::npos) << message;
    EXPECT_NE(message.find(expected), std::string::npos) << "message: " << message << "\nexpected: " << expected;
  }
}

TEST(SceneErrors, DuplicateObjectName) {
  std::string yaml = kMinimalScene;
  yaml.insert(yaml.find("simulations"), "  - {name: ball, role: rigid, mesh: {generator: box}}\n");
  const std::string message = loadError(yaml);
  EXPECT_NE(message.find("inline_scene.yaml:6:12: objects[1].name: duplicate object name 'ball'"), std::string::npos)
      << message;
}

TEST(SceneErrors, BrokenMeshFileFailsInBuildMeshWithObjectLocation) {
  const std::string malformed = std::string(VRM_SCENE_SOURCE_DIR) + "/test/data/meshes/nan_vertex.obj";
  const SceneDescription scene = loadSceneFromString(
      "scene: {name: x, kind: abstract}\nobjects:\n  - {name: bad, role: rigid, mesh: {file: " + malformed +
          "}}\nsimulations: []\n",
      "bad_mesh.yaml");
  try {
    buildMesh(scene.objects.at(0));
    FAIL() << "no error";
  } catch (const SceneError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("bad_mesh.yaml:3:5: objects[0].mesh: "), std::string::npos) << message;
    EXPECT_NE(message.find("nan_vertex.obj"), std::string::npos) << message;
    EXPECT_NE(message.find("non-finite"), std::string::npos) << message;
  }
}

// Shipped scenes come from the package directory set at run time (issue 18: an install space has no source tree),
// never from a path compiled into the library.
TEST(ShippedScenes, FollowThePackageDirectorySetAtRunTime) {
  const std::string source_package = packageDirectory();
  ASSERT_FALSE(source_package.empty()) << "test/support/source_package.cpp sets the source package";
  EXPECT_EQ(resolveScenePath("navigation"), source_package + "/config/scenes/navigation.yaml");

  const std::string installed = ::testing::TempDir() + "vrm_sim_share";
  std::filesystem::create_directories(installed + "/config/scenes");
  std::filesystem::copy_file(source_package + "/config/scenes/navigation.yaml",
                             installed + "/config/scenes/navigation.yaml",
                             std::filesystem::copy_options::overwrite_existing);
  setPackageDirectory(installed);
  EXPECT_EQ(shippedScenes(), std::vector<std::string>{"navigation"});
  EXPECT_EQ(loadScene("navigation").source_file, installed + "/config/scenes/navigation.yaml");
  EXPECT_THROW(loadScene("membrane_peeling"), SceneError);  // not in this package

  setPackageDirectory("");  // nobody said where the package is: no shipped scenes, and an error that says why
  EXPECT_TRUE(shippedScenes().empty());
  try {
    shippedScenePath("navigation");
    ADD_FAILURE() << "no SceneError";
  } catch (const SceneError& error) {
    EXPECT_NE(std::string(error.what()).find("package directory is unknown"), std::string::npos) << error.what();
  }
  setPackageDirectory(source_package);
  std::filesystem::remove_all(installed);
}

}  // namespace
}  // namespace scene
}  // namespace vrm_sim
