// A renderer that follows the running scene (issue 32) switches scenes without a new GL context: showScene() on a
// renderer that has drawn another scene must leave it exactly as a new renderer given only the new scene, in what it
// holds (objects, meshes) and in what it draws (the same images, bit for bit, including the frames that reuse the
// static layer and the fundus texture, which the renderer knows by address).

#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "vrm_render/scene_setup.h"
#include "vrm_render/stereo_renderer.h"
#include "vrm_scene/scene_loader.h"

namespace vrm_render {
namespace {

RenderOptions smallOptions() {
  RenderOptions options;
  options.width = 160;
  options.height = 120;
  options.stereo = true;
  options.shadow_map_size = 256;
  return options;
}

SceneContent shippedContent(const std::string& name) { return sceneContent(vrm_sim::scene::loadScene(name)); }

// The light pipe over the posterior pole, so the lit and the cached (ambient-only) parts both show.
LightPipe lightOverThePole() {
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
  pose.translation() = Eigen::Vector3f(0.001f, 0.0f, -0.006f);
  pose.linear() = Eigen::AngleAxisf(3.1f, Eigen::Vector3f::UnitX()).toRotationMatrix();  // +z points down
  return lightPipeAt(pose, endoilluminator());
}

std::vector<StereoFrame> renderFrames(StereoRenderer& renderer, int count, bool light = true) {
  std::vector<StereoFrame> frames(static_cast<std::size_t>(count));
  renderer.setLightPipe(light ? lightOverThePole() : LightPipe());
  for (StereoFrame& frame : frames) renderer.render(&frame);
  return frames;
}

TEST(SceneSwitch, ARendererSwitchedToAnotherSceneHoldsAndDrawsWhatANewRendererOfThatSceneDoes) {
  StereoRenderer switched(smallOptions());
  showScene(&switched, shippedContent("navigation"));
  // What the nodelet adds to a scene: an instrument and a ghost (they must go with the scene, too).
  const SceneContent extra = shippedContent("membrane_peeling");
  switched.setStyle("instrument_left", extra.objects.front().drawn.style);
  switched.updateMesh("instrument_left", extra.objects.front().drawn.mesh.view(), 7);
  switched.setStyle("ghost_left", extra.objects.front().drawn.style);
  const std::vector<StereoFrame> navigation = renderFrames(switched, 3);  // frame 3 draws the static layer
  ASSERT_TRUE(switched.hasObject("target_1"));

  showScene(&switched, shippedContent("membrane_peeling"));
  StereoRenderer fresh(smallOptions());
  showScene(&fresh, shippedContent("membrane_peeling"));

  EXPECT_EQ(switched.objectIds(), fresh.objectIds());
  // Issue 33: the scene's optic_disc is drawn by the fundus (scene_setup.h: fundusParams), not as a mesh.
  const std::vector<std::string> expected = {"membrane", "retina"};
  EXPECT_EQ(fresh.objectIds(), expected);
  for (const std::string& id : fresh.objectIds()) {
    EXPECT_EQ(switched.triangleCount(id), fresh.triangleCount(id)) << id;
    EXPECT_GT(fresh.triangleCount(id), 0u) << id;
    EXPECT_EQ(switched.version(id), fresh.version(id)) << id;
  }
  EXPECT_EQ(switched.triangleCount(), fresh.triangleCount());

  // Frame 1 draws the static objects directly, frame 3 from a newly drawn static layer, frame 4 reuses it.
  const std::vector<StereoFrame> after_switch = renderFrames(switched, 4);
  const std::vector<StereoFrame> from_new = renderFrames(fresh, 4);
  for (std::size_t f = 0; f < after_switch.size(); ++f) {
    for (int eye = 0; eye < 2; ++eye) {
      ASSERT_FALSE(from_new[f].images[eye].data.empty());
      EXPECT_TRUE(after_switch[f].images[eye].data == from_new[f].images[eye].data)
          << "frame " << f << ", eye " << eye << " differs from a new renderer's";
    }
  }
  EXPECT_EQ(after_switch[2].timings.static_layers_drawn, from_new[2].timings.static_layers_drawn);
  EXPECT_FALSE(after_switch[0].images[0].data == navigation[0].images[0].data) << "the scenes should look different";
}

TEST(SceneSwitch, RemovedObjectsAreForgottenAndUnknownOnesIgnored) {
  StereoRenderer renderer(smallOptions());
  showScene(&renderer, shippedContent("navigation"));
  const std::size_t before = renderer.objectIds().size();
  renderer.removeObject("obstacle_box");
  renderer.removeObject("no_such_object");
  EXPECT_FALSE(renderer.hasObject("obstacle_box"));
  EXPECT_EQ(renderer.objectIds().size(), before - 1);
  EXPECT_EQ(renderer.triangleCount("obstacle_box"), 0u);
  EXPECT_EQ(renderer.version("obstacle_box"), 0u);
}

// A square floor of `half` metres at z = -0.012 (the posterior pole's depth), static: the static layer holds it.
MeshData floorMesh(float half) {
  MeshData mesh;
  mesh.positions = {-half, -half, -0.012f, half, -half, -0.012f, half, half, -0.012f, -half, half, -0.012f};
  mesh.normals = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  mesh.triangles = {0, 1, 2, 0, 2, 3};
  return mesh;
}

// The static layer knows its objects by address, version and pose: a removed object's successor of the same name,
// version and pose (the next scene's retina) must not pass for it, even where it reuses the freed memory.
TEST(SceneSwitch, AnObjectReplacedByOneOfTheSameNameVersionAndPoseIsRedrawn) {
  ObjectStyle style;
  style.material.specular = Eigen::Vector3f::Zero();
  StereoRenderer replaced(smallOptions());
  replaced.setStyle("floor", style);
  replaced.updateMesh("floor", floorMesh(0.002f).view(), kRestMeshVersion);
  // Unlit: the static layer alone shows the floor (lit triangles would be drawn over it).
  renderFrames(replaced, 3, false);  // frame 3 draws the static layer
  replaced.removeObject("floor");
  replaced.setStyle("floor", style);
  replaced.updateMesh("floor", floorMesh(0.004f).view(), kRestMeshVersion);

  StereoRenderer fresh(smallOptions());
  fresh.setStyle("floor", style);
  fresh.updateMesh("floor", floorMesh(0.004f).view(), kRestMeshVersion);
  const std::vector<StereoFrame> after = renderFrames(replaced, 4, false);
  const std::vector<StereoFrame> expected = renderFrames(fresh, 4, false);
  for (std::size_t f = 0; f < after.size(); ++f) {
    EXPECT_TRUE(after[f].images[0].data == expected[f].images[0].data) << "frame " << f;
  }
}

TEST(SceneContent, StreamsTheDeformableObjectsAndTheBleedingRetinaAndKeepsEachObjectInItsFrame) {
  const SceneContent peeling = shippedContent("membrane_peeling");
  EXPECT_EQ(peeling.name, "membrane_peeling");
  std::set<std::string> streamed;
  for (const SceneContent::Object& object : peeling.objects) {
    if (object.streamed) streamed.insert(object.drawn.id);
    EXPECT_TRUE(object.in_eye_frame) << object.drawn.id;
    EXPECT_FALSE(object.drawn.mesh.triangles.empty()) << object.drawn.id;
  }
  EXPECT_EQ(streamed, (std::set<std::string>{"membrane", "retina"}));
  ASSERT_NE(peeling.fundus, nullptr);

  for (const SceneContent::Object& object : shippedContent("navigation").objects) {
    EXPECT_FALSE(object.streamed) << object.drawn.id << ": navigation simulates no tissue and no bleeding";
  }
}

}  // namespace
}  // namespace vrm_render
