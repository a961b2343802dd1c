// Renderer tests (issue 6): property tests whose expectations come from the scene geometry (where a shadow must
// fall, where the spotlight must peak, which plane DOF must keep sharp), golden images of small fixed scenes
// against committed PNGs, and bad-input handling. Images are small (160x120) to keep the suite fast.
//
// Regenerate the golden PNGs after an intended visual change: VRM_RENDER_UPDATE_GOLDEN=1 <this test>.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>

#include "vrm_render/image_io.h"
#include "vrm_render/scene_setup.h"
#include "vrm_render/stereo_renderer.h"
#include "vrm_scene/instrument_model.h"
#include "vrm_scene/meshes/eye_meshes.h"
#include "vrm_scene/meshes/instrument_meshes.h"
#include "vrm_scene/scene_loader.h"

namespace vrm_render {
namespace {

constexpr int kWidth = 160;
constexpr int kHeight = 120;
constexpr float kFocalZ = -0.012f;  // default focus 0.2 m below the objective at 0.188 m

// A square in the plane z = `z`, centred at (cx, cy), `cells` x `cells` quads with unshared vertices so each cell
// can have its own flat colour (checkerboard when `checker`).
MeshData makePlane(float cx, float cy, float z, float half, int cells, bool checker, Eigen::Vector3f colour) {
  MeshData mesh;
  const float step = 2.0f * half / cells;
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) {
      const float x0 = cx - half + i * step;
      const float y0 = cy - half + j * step;
      const float shade = checker && ((i + j) % 2) ? 0.15f : 1.0f;
      const std::uint32_t base = static_cast<std::uint32_t>(mesh.positions.size() / 3);
      const float corners[4][2] = {{x0, y0}, {x0 + step, y0}, {x0 + step, y0 + step}, {x0, y0 + step}};
      for (const auto& c : corners) {
        mesh.positions.insert(mesh.positions.end(), {c[0], c[1], z});
        mesh.normals.insert(mesh.normals.end(), {0.0f, 0.0f, 1.0f});
        mesh.colors.insert(mesh.colors.end(), {colour.x() * shade, colour.y() * shade, colour.z() * shade, 1.0f});
      }
      mesh.triangles.insert(mesh.triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    }
  }
  return mesh;
}

MeshData makeSphere(const Eigen::Vector3f& centre, float radius, int rings = 12, int segments = 16) {
  MeshData mesh;
  for (int r = 0; r <= rings; ++r) {
    const float theta = static_cast<float>(M_PI) * r / rings;
    for (int s = 0; s < segments; ++s) {
      const float phi = 2.0f * static_cast<float>(M_PI) * s / segments;
      const Eigen::Vector3f n(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      const Eigen::Vector3f p = centre + radius * n;
      mesh.positions.insert(mesh.positions.end(), {p.x(), p.y(), p.z()});
      mesh.normals.insert(mesh.normals.end(), {n.x(), n.y(), n.z()});
    }
  }
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      const std::uint32_t a = r * segments + s, b = r * segments + (s + 1) % segments;
      const std::uint32_t c = a + segments, d = b + segments;
      mesh.triangles.insert(mesh.triangles.end(), {a, c, b, b, c, d});
    }
  }
  return mesh;
}

RenderOptions smallOptions(bool stereo = false) {
  RenderOptions options;
  options.width = kWidth;
  options.height = kHeight;
  options.stereo = stereo;
  options.dof_pass = false;
  options.bump_mapping = false;
  options.shadow_map_size = 512;
  return options;
}

ObjectStyle matte(Eigen::Vector4f diffuse = {0.8f, 0.8f, 0.8f, 1.0f}) {
  ObjectStyle style;
  style.material.diffuse = diffuse;
  style.material.specular = Eigen::Vector3f::Zero();
  return style;
}

Eigen::Vector2f pixelOf(const StereoRenderer& renderer, const Eigen::Vector3f& world, Eye eye = Eye::kLeft) {
  Eigen::Vector2f p;
  EXPECT_TRUE(projectToPixel(renderer.camera(eye), world, &p));
  return p;
}

double lumAt(const RgbImage& image, const Eigen::Vector2f& p, int half = 1) {
  const int x = static_cast<int>(p.x()), y = static_cast<int>(p.y());
  return meanLuminance(image, x - half, y - half, x + half + 1, y + half + 1);
}

StereoFrame renderFrame(StereoRenderer& renderer) {
  StereoFrame frame;
  renderer.render(&frame);
  return frame;
}

LightPipe downwardLight(const Eigen::Vector3f& tip) {
  LightPipe light;
  light.enabled = true;
  light.tip = tip;
  light.direction = {0.0f, 0.0f, -1.0f};
  light.cone_half_angle_rad = 0.9f;
  light.cone_softness = 0.2f;
  light.intensity = 1.5f;
  light.range = 0.012f;
  return light;
}

// Centroid of the brightest region (luminance >= 97% of the maximum), robust to plateaus and sparkle.
Eigen::Vector2f brightestPixel(const RgbImage& image) {
  double best = 0.0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) best = std::max(best, meanLuminance(image, x, y, x + 1, y + 1));
  }
  Eigen::Vector2d sum(0, 0);
  double count = 0.0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      if (meanLuminance(image, x, y, x + 1, y + 1) >= 0.97 * best) {
        sum += Eigen::Vector2d(x + 0.5, y + 0.5);
        count += 1.0;
      }
    }
  }
  return (sum / count).cast<float>();
}

TEST(Renderer, SpotlightPeakIsWhereTheLightPipePoints) {
  StereoRenderer renderer(smallOptions());
  MicroscopeState microscope;
  microscope.ambient_light = 0.1;
  renderer.setMicroscope(microscope);
  renderer.setStyle("floor", matte());
  renderer.updateMesh("floor", makePlane(0, 0, kFocalZ, 0.015f, 30, false, {1, 1, 1}).view(), 1);
  for (const Eigen::Vector2f foot : {Eigen::Vector2f(-0.004f, 0.002f), Eigen::Vector2f(0.005f, -0.003f)}) {
    LightPipe light = downwardLight({foot.x(), foot.y(), kFocalZ + 0.005f});
    light.intensity = 0.9f;  // below saturation, so the peak is a peak and not a plateau
    renderer.setLightPipe(light);
    const StereoFrame frame = renderFrame(renderer);
    const Eigen::Vector2f expected = pixelOf(renderer, {foot.x(), foot.y(), kFocalZ});
    const Eigen::Vector2f peak = brightestPixel(frame.images[0]);
    EXPECT_LT((peak - expected).norm(), 1.5f) << "peak " << peak.transpose() << " expected " << expected.transpose();
    // Outside the cone (half angle 0.9 rad at 5 mm: radius 6.3 mm) only the ambient light remains.
    const Eigen::Vector2f outside =
        pixelOf(renderer, {foot.x() + 0.0075f * (foot.x() < 0 ? 1 : -1), foot.y(), kFocalZ});
    EXPECT_LT(lumAt(frame.images[0], outside), 0.12 * 255 * 0.8 + 2.0);
    EXPECT_GT(lumAt(frame.images[0], peak), 120.0);
  }
}

TEST(Renderer, ShadowFallsWhereTheRayFromTheLightTipThroughTheCasterMeetsTheFloor) {
  StereoRenderer renderer(smallOptions());
  MicroscopeState microscope;
  microscope.ambient_light = 0.1;
  renderer.setMicroscope(microscope);
  renderer.setStyle("floor", matte());
  renderer.updateMesh("floor", makePlane(0, 0, kFocalZ, 0.015f, 30, false, {1, 1, 1}).view(), 1);
  const Eigen::Vector3f tip(0.0f, 0.0f, kFocalZ + 0.008f);
  renderer.setLightPipe(downwardLight(tip));
  ObjectStyle caster = matte({0.2f, 0.6f, 0.2f, 1.0f});
  caster.casts_shadow = true;
  renderer.setStyle("ball", caster);
  for (const Eigen::Vector3f ball :
       {Eigen::Vector3f(0.002f, 0.0f, kFocalZ + 0.004f), Eigen::Vector3f(0.0f, -0.002f, kFocalZ + 0.004f)}) {
    renderer.updateMesh("ball", makeSphere(ball, 0.0007f).view(), ball.y() == 0.0f ? 1 : 2);
    // Shadow centre: the ray tip -> ball centre continued to the floor (twice as far: the ball is halfway down).
    const Eigen::Vector3f shadow = tip + 2.0f * (ball - tip);
    const Eigen::Vector3f mirror(-shadow.x(), -shadow.y(), shadow.z());
    RenderOptions options = smallOptions();
    options.shadow_pass = false;
    renderer.setOptions(options);
    const StereoFrame lit = renderFrame(renderer);
    options.shadow_pass = true;
    renderer.setOptions(options);
    const StereoFrame shadowed = renderFrame(renderer);
    const Eigen::Vector2f ps = pixelOf(renderer, shadow), pm = pixelOf(renderer, mirror);
    EXPECT_LT(lumAt(shadowed.images[0], ps), 0.4 * lumAt(lit.images[0], ps)) << "no shadow at " << ps.transpose();
    EXPECT_NEAR(lumAt(shadowed.images[0], pm), lumAt(lit.images[0], pm), 2.0) << "shadow at the mirror point";
    // The half-way point between the ball's image and the shadow's is still lit floor (the shadow is not smeared).
    const Eigen::Vector3f beyond = tip + 3.2f * (ball - tip);  // past the shadow's far edge
    const Eigen::Vector2f pb = pixelOf(renderer, {beyond.x(), beyond.y(), kFocalZ});
    EXPECT_NEAR(lumAt(shadowed.images[0], pb), lumAt(lit.images[0], pb), 2.0);
  }
}

TEST(Renderer, ObjectsThatDoNotCastShadowsLeaveTheFloorLit) {
  StereoRenderer renderer(smallOptions());
  renderer.setStyle("floor", matte());
  renderer.updateMesh("floor", makePlane(0, 0, kFocalZ, 0.015f, 10, false, {1, 1, 1}).view(), 1);
  const Eigen::Vector3f tip(0.0f, 0.0f, kFocalZ + 0.008f);
  renderer.setLightPipe(downwardLight(tip));
  renderer.setStyle("light_pipe_like", matte());  // casts_shadow = false, like the light pipe itself
  const Eigen::Vector3f ball(0.002f, 0.0f, kFocalZ + 0.004f);
  renderer.updateMesh("light_pipe_like", makeSphere(ball, 0.0007f).view(), 1);
  const StereoFrame with = renderFrame(renderer);
  renderer.setVisible("light_pipe_like", false);
  const StereoFrame without = renderFrame(renderer);
  const Eigen::Vector2f ps = pixelOf(renderer, tip + 2.0f * (ball - tip));
  EXPECT_NEAR(lumAt(with.images[0], ps), lumAt(without.images[0], ps), 2.0);
}

TEST(Renderer, DepthOfFieldLeavesTheFocusedPlaneSharpAndBlursTheOther) {
  RenderOptions options = smallOptions();
  options.lighting = false;  // unlit checkerboards: sharpness depends only on DOF
  StereoRenderer renderer(options);
  renderer.setStyle("far", matte({1, 1, 1, 1}));
  renderer.setStyle("near", matte({1, 1, 1, 1}));
  // Left half of the view: a checkerboard on the default focal plane; right half: one 8 mm nearer the objective.
  renderer.updateMesh("far", makePlane(-0.004f, 0, kFocalZ, 0.0035f, 12, true, {1, 1, 1}).view(), 1);
  renderer.updateMesh("near", makePlane(0.004f, 0, kFocalZ + 0.008f, 0.0035f, 12, true, {1, 1, 1}).view(), 1);
  MicroscopeState zoomed;
  zoomed.zoom = 3.0;
  renderer.setMicroscope(zoomed);
  const Eigen::Vector2f far_px = pixelOf(renderer, {-0.004f, 0.0f, kFocalZ});
  const Eigen::Vector2f near_px = pixelOf(renderer, {0.004f, 0.0f, kFocalZ + 0.008f});
  auto sharpness = [](const RgbImage& image, const Eigen::Vector2f& c) {
    return laplacianEnergy(image, int(c.x()) - 12, int(c.y()) - 12, int(c.x()) + 12, int(c.y()) + 12);
  };
  const StereoFrame reference = renderFrame(renderer);
  options.dof_pass = true;
  renderer.setOptions(options);
  for (const double focus : {0.2, 0.192}) {  // on the far plane, then on the near plane
    MicroscopeState microscope;
    // Issue 16: the blur is the objective's circle of confusion in pixels, so it grows with the magnification; at
    // zoom 3 the 8 mm defocus blurs ~6 px at this image size (at zoom 1 only ~2 px).
    microscope.zoom = 3.0;
    microscope.focus_distance = focus;
    renderer.setMicroscope(microscope);
    const StereoFrame blurred = renderFrame(renderer);
    const bool far_in_focus = focus == 0.2;
    const Eigen::Vector2f sharp_px = far_in_focus ? far_px : near_px;
    const Eigen::Vector2f soft_px = far_in_focus ? near_px : far_px;
    EXPECT_GT(sharpness(blurred.images[0], sharp_px), 0.9 * sharpness(reference.images[0], sharp_px)) << focus;
    EXPECT_LT(sharpness(blurred.images[0], soft_px), 0.3 * sharpness(reference.images[0], soft_px)) << focus;
  }
}

TEST(Renderer, InjuredTissueBleeds) {
  StereoRenderer renderer(smallOptions());
  renderer.setLightPipe(downwardLight({0.0f, 0.0f, kFocalZ + 0.006f}));
  renderer.setStyle("retina", matte({0.85f, 0.6f, 0.5f, 1.0f}));
  MeshData floor = makePlane(0, 0, kFocalZ, 0.01f, 20, false, {1, 1, 1});
  floor.injury.assign(floor.positions.size() / 3, 0.0f);
  renderer.updateMesh("retina", floor.view(), 1);
  const StereoFrame healthy = renderFrame(renderer);
  for (std::size_t v = 0; v < floor.injury.size(); ++v) {
    if (floor.positions[3 * v] < -0.0005f) floor.injury[v] = 1.0f;  // the left half was hit
  }
  renderer.updateMesh("retina", floor.view(), 2);
  const StereoFrame bleeding = renderFrame(renderer);
  auto redness = [](const RgbImage& image, const Eigen::Vector2f& p) {
    const std::uint8_t* px = image.pixel(int(p.x()), int(p.y()));
    return (px[0] + 1.0) / (px[1] + px[2] + 2.0);
  };
  const Eigen::Vector2f hit = pixelOf(renderer, {-0.002f, 0.0f, kFocalZ});
  const Eigen::Vector2f intact = pixelOf(renderer, {0.002f, 0.0f, kFocalZ});
  EXPECT_GT(redness(bleeding.images[0], hit), 3.0 * redness(healthy.images[0], hit));
  EXPECT_NEAR(redness(bleeding.images[0], intact), redness(healthy.images[0], intact), 0.05);
}

TEST(Renderer, GhostInstrumentsAreTranslucent) {
  RenderOptions options = smallOptions();
  options.lighting = false;
  StereoRenderer renderer(options);
  renderer.setStyle("floor", matte({0.0f, 0.0f, 1.0f, 1.0f}));
  renderer.updateMesh("floor", makePlane(0, 0, kFocalZ, 0.01f, 4, false, {1, 1, 1}).view(), 1);
  ObjectStyle instrument = matte({1.0f, 0.0f, 0.0f, 1.0f});
  renderer.setStyle("instrument", instrument);
  renderer.updateMesh("instrument", makeSphere({0, 0, kFocalZ + 0.003f}, 0.002f).view(), 1);
  const Eigen::Vector2f centre = pixelOf(renderer, {0, 0, kFocalZ + 0.005f});
  const StereoFrame opaque = renderFrame(renderer);  // named: a pixel pointer into a temporary frame would dangle
  const std::uint8_t* solid = opaque.images[0].pixel(int(centre.x()), int(centre.y()));
  EXPECT_GT(solid[0], 240);
  EXPECT_LT(solid[2], 10);
  instrument.ghost = true;
  renderer.setStyle("instrument", instrument);
  const StereoFrame ghost = renderFrame(renderer);
  const std::uint8_t* seen = ghost.images[0].pixel(int(centre.x()), int(centre.y()));
  EXPECT_NEAR(seen[0], 255 * options.ghost_alpha, 4);  // red over blue, blended with alpha 0.35
  EXPECT_NEAR(seen[2], 255 * (1.0 - options.ghost_alpha), 4);
}

TEST(Renderer, ObjectsOutsideTheViewAreNotDrawn) {
  StereoRenderer renderer(smallOptions(true));
  renderer.setStyle("floor", matte());
  renderer.updateMesh("floor", makePlane(0, 0, kFocalZ, 0.01f, 4, false, {1, 1, 1}).view(), 1);
  renderer.setStyle("far_away", matte());
  renderer.updateMesh("far_away", makeSphere({0.5f, 0.0f, 0.0f}, 0.001f).view(), 1);
  const StereoFrame frame = renderFrame(renderer);
  EXPECT_EQ(frame.timings.objects_culled, 2u);  // once per eye
  EXPECT_EQ(frame.timings.triangles_drawn, 2u * 32u);
  ASSERT_EQ(frame.images[1].width, kWidth);
}

TEST(Renderer, StaticMeshesUploadOnceAndStreamedMeshesOnlyOnANewVersion) {
  StereoRenderer renderer(smallOptions());
  ObjectStyle style = matte();
  style.deformable = true;
  renderer.setStyle("membrane", style);
  MeshData plane = makePlane(0, 0, kFocalZ, 0.004f, 4, false, {1, 1, 1});
  EXPECT_TRUE(renderer.updateMesh("membrane", plane.view(), 7));
  EXPECT_FALSE(renderer.updateMesh("membrane", plane.view(), 7));
  for (std::size_t i = 2; i < plane.positions.size(); i += 3) plane.positions[i] += 0.001f;
  EXPECT_TRUE(renderer.updateMesh("membrane", plane.view(), 8));
  EXPECT_EQ(renderer.version("membrane"), 8u);
}

TEST(Renderer, BadInputIsRejectedWithAClearErrorAndTheRendererKeepsRunning) {
  StereoRenderer renderer(smallOptions());
  renderer.setLightPipe(downwardLight({0, 0, kFocalZ + 0.005f}));
  renderer.setStyle("floor", matte());
  const MeshData floor = makePlane(0, 0, kFocalZ, 0.01f, 8, false, {1, 1, 1});
  renderer.updateMesh("floor", floor.view(), 1);
  const StereoFrame before = renderFrame(renderer);

  MeshData nan_mesh = floor;
  nan_mesh.positions[4] = std::numeric_limits<float>::quiet_NaN();
  try {
    renderer.updateMesh("floor", nan_mesh.view(), 2);
    ADD_FAILURE() << "NaN accepted";
  } catch (const RenderError& e) {
    EXPECT_NE(std::string(e.what()).find("non-finite"), std::string::npos) << e.what();
  }
  MeshData bad_index = floor;
  bad_index.triangles[5] = 100000;
  EXPECT_THROW(renderer.updateMesh("floor", bad_index.view(), 3), RenderError);
  EXPECT_THROW(renderer.updateMesh("floor", MeshData().view(), 4), RenderError);
  MeshView huge = floor.view();
  huge.vertex_count = StereoRenderer::kMaxVertices + 1;
  EXPECT_THROW(renderer.updateMesh("floor", huge, 5), RenderError);
  RenderOptions too_big = smallOptions();
  too_big.width = 100000;
  EXPECT_THROW(renderer.setOptions(too_big), RenderError);
  MicroscopeState broken;
  broken.zoom = std::nan("");
  EXPECT_THROW(renderer.setMicroscope(broken), RenderError);
  LightPipe nan_light = downwardLight({0, 0, kFocalZ + 0.005f});
  nan_light.direction.x() = std::nanf("");
  renderer.setLightPipe(nan_light);  // treated as "no light", not a crash
  renderFrame(renderer);
  renderer.setLightPipe(downwardLight({0, 0, kFocalZ + 0.005f}));

  EXPECT_EQ(renderer.version("floor"), 1u);
  const StereoFrame after = renderFrame(renderer);
  EXPECT_EQ(after.images[0].width, kWidth);
  EXPECT_EQ(after.images[0].data, before.images[0].data);
}

// The lit shader drawn only for the triangles that may reach into the spotlight's pyramid, its shadow lookup only
// for those that may reach the casters' rectangle in the shadow map (ambient-only elsewhere), must give the image of
// the lit shader everywhere: a partition that missed part of the footprint would leave lit pixels dark, one that
// missed part of the shadow would light it. Stereo, shadows (the forceps' shadow lies in view: checked below), bump
// mapping, DOF, a translucent membrane and instruments whose long shaft triangles cross the cone and reach behind
// the light pipe tip.
TEST(Renderer, SpotlightPartitionRendersTheSameImageAsLightingEverywhere) {
  RenderOptions options;
  options.width = kWidth;
  options.height = kHeight;
  LightPipe light;
  const std::vector<SceneObject> scene = typicalScene(&light);
  options.light_partition = false;
  StereoRenderer everywhere(options);
  options.shadow_pass = false;
  StereoRenderer unshadowed(options);
  options.shadow_pass = true;
  options.light_partition = true;
  StereoRenderer split(options);
  for (StereoRenderer* renderer : {&everywhere, &split, &unshadowed}) {
    for (const SceneObject& object : scene) {
      renderer->setStyle(object.id, object.style);
      renderer->setPose(object.id, object.pose);
      renderer->updateMesh(object.id, object.mesh.view(), 1);
    }
  }
  // The typical aim, a wide cone, and a light pipe near the rim aiming across the eye.
  unshadowed.setLightPipe(light);
  everywhere.setLightPipe(light);
  EXPECT_GT(fractionDifferent(renderFrame(everywhere).images[0], renderFrame(unshadowed).images[0], 8), 1e-3)
      << "the typical scene shows no shadow: the test would not see a wrong shadow partition";
  LightPipe wide = light;
  wide.cone_half_angle_rad = 1.2f;
  LightPipe rim = light;
  rim.tip = Eigen::Vector3f(-0.008f, 0.004f, -0.004f);
  rim.direction = Eigen::Vector3f(1.0f, -0.3f, -0.5f).normalized();
  for (const LightPipe& pipe : {light, wide, rim}) {
    everywhere.setLightPipe(pipe);
    split.setLightPipe(pipe);
    const StereoFrame a = renderFrame(everywhere);
    const StereoFrame b = renderFrame(split);
    for (int eye = 0; eye < 2; ++eye) {
      EXPECT_LT(fractionDifferent(a.images[eye], b.images[eye], 2), 1e-4) << "eye " << eye;
      EXPECT_GT(psnr(a.images[eye], b.images[eye]), 50.0) << "eye " << eye;
    }
  }
}

// The static layer (issue 30, RenderOptions::cache_static): the retina kept per eye ambient-only and the lit
// triangles drawn over it each frame must give exactly the image of drawing every triangle every frame — while the
// light pipe and the forceps move, the retina bleeds (new mesh version), the eye turns, the focus changes — and the
// layer must be redrawn exactly when what it shows changed and then held still for a frame (a stale layer would show
// the old retina; one redrawn while the eye keeps turning would cost more than it saves).
TEST(Renderer, StaticLayerCacheRendersTheSameImagesAndIsRedrawnOnlyWhenItsContentChanges) {
  RenderOptions options;
  options.width = kWidth;
  options.height = kHeight;
  options.cache_static = false;
  StereoRenderer reference(options);
  options.cache_static = true;
  StereoRenderer cached(options);
  LightPipe light;
  std::vector<SceneObject> scene = typicalScene(&light);
  for (StereoRenderer* renderer : {&reference, &cached}) {
    for (const SceneObject& object : scene) {
      renderer->setStyle(object.id, object.style);
      renderer->setPose(object.id, object.pose);
      renderer->updateMesh(object.id, object.mesh.view(), 1);
    }
    renderer->setLightPipe(light);
  }
  SceneObject* retina = nullptr;
  SceneObject* forceps = nullptr;
  for (SceneObject& object : scene) {
    if (object.id == "retina") retina = &object;
    if (object.id == "instrument_right") forceps = &object;
  }
  ASSERT_NE(retina, nullptr);
  ASSERT_NE(forceps, nullptr);
  ASSERT_FALSE(retina->style.deformable || retina->style.casts_shadow) << "the retina must be static for this test";
  std::uint64_t retina_version = 1;
  bool changed_before = true;  // the first frame has no layer yet
  for (int frame = 0; frame < 12; ++frame) {
    // Every frame the light pipe and the forceps move (the layer must not hold them).
    LightPipe moved = light;
    moved.tip += Eigen::Vector3f(0.0004f * (frame % 5), -0.0003f * (frame % 4), 0.0f);
    Eigen::Isometry3f forceps_pose = forceps->pose;
    forceps_pose.translation() += Eigen::Vector3f(-0.0002f * frame, 0.0001f * frame, 0.0002f * (frame % 3));
    for (StereoRenderer* renderer : {&reference, &cached}) {
      renderer->setLightPipe(moved);
      renderer->setPose("instrument_right", forceps_pose);
    }
    bool changed = frame == 0;
    if (frame == 3) {  // the retina bleeds: its mesh comes with a new version
      retina->mesh.injury.assign(retina->mesh.positions.size() / 3, 0.0f);
      for (std::size_t v = 0; v < retina->mesh.injury.size(); v += 7) retina->mesh.injury[v] = 0.8f;
      ++retina_version;
      for (StereoRenderer* renderer : {&reference, &cached}) {
        renderer->updateMesh("retina", retina->mesh.view(), retina_version);
      }
      changed = true;
    }
    if (frame == 6 || frame == 7) {  // the eye turns for two frames: the retina's pose changes
      retina->pose = Eigen::Isometry3f(Eigen::AngleAxisf(0.03f, Eigen::Vector3f::UnitX())) * retina->pose;
      for (StereoRenderer* renderer : {&reference, &cached}) renderer->setPose("retina", retina->pose);
      changed = true;
    }
    if (frame == 10) {  // the surgeon refocuses: the layer's DOF weights change
      MicroscopeState microscope;
      microscope.focus_distance = 0.199;
      for (StereoRenderer* renderer : {&reference, &cached}) renderer->setMicroscope(microscope);
      changed = true;
    }
    // A changed layer is drawn directly; the first frame it holds still, the layer is redrawn (one per eye).
    const int expected_layers = !changed && changed_before ? 2 : 0;
    changed_before = changed;
    const StereoFrame a = renderFrame(reference);
    const StereoFrame b = renderFrame(cached);
    EXPECT_EQ(a.timings.static_layers_drawn, 0);
    EXPECT_EQ(b.timings.static_layers_drawn, expected_layers) << "frame " << frame;
    for (int eye = 0; eye < 2; ++eye) {
      EXPECT_EQ(a.images[eye].data, b.images[eye].data)
          << "frame " << frame << " eye " << eye << ": " << fractionDifferent(a.images[eye], b.images[eye], 0)
          << " of the pixels differ";
    }
  }
}

// Issue 37: laser burns are painted into the fundus texture where they lie (and nowhere else), whiter than the retina
// around them; the static layer is redrawn when one is added (same images with and without the cache); an emissive
// object (the aiming beam) is red where it lies and never cached.
TEST(Renderer, LaserBurnsWhitenTheFundusWhereTheyLieAndTheAimGlowsRed) {
  RenderOptions options;
  options.width = kWidth;
  options.height = kHeight;
  options.stereo = false;
  options.cache_static = false;
  StereoRenderer reference(options);
  options.cache_static = true;
  StereoRenderer cached(options);
  LightPipe light;
  const std::vector<SceneObject> scene = typicalScene(&light);
  for (StereoRenderer* renderer : {&reference, &cached}) {
    for (const SceneObject& object : scene) {
      if (object.id != "retina") continue;  // the fundus alone: nothing in front of the burns
      renderer->setStyle(object.id, object.style);
      renderer->setPose(object.id, object.pose);
      renderer->updateMesh(object.id, object.mesh.view(), 1);
    }
  }
  const FundusMap& fundus = reference.fundus();
  const Eigen::Vector3f on_retina = fundus.toEye(Eigen::Vector2f(-0.002f, 0.0015f));
  FundusBurn burn;
  burn.position = on_retina;
  burn.diameter = 0.0009f;
  burn.whiteness = 0.9f;
  const Eigen::Vector2f at = pixelOf(reference, on_retina);
  const Eigen::Vector2f away = pixelOf(reference, fundus.toEye(Eigen::Vector2f(0.002f, -0.0025f)));
  StereoFrame before = renderFrame(reference);
  renderFrame(cached);
  renderFrame(cached);  // the layer is drawn once the content holds still
  for (StereoRenderer* renderer : {&reference, &cached}) renderer->setFundusBurns({burn});
  const StereoFrame after = renderFrame(reference);
  const StereoFrame after_cached = renderFrame(cached);
  EXPECT_EQ(after.images[0].data, after_cached.images[0].data) << "the static layer shows the burn too";
  EXPECT_GT(lumAt(after.images[0], at), 1.6 * lumAt(before.images[0], at));  // 29 -> 59 under the ambient light alone
  EXPECT_NEAR(lumAt(after.images[0], away), lumAt(before.images[0], away), 0.5);
  EXPECT_EQ(reference.fundusBurns().size(), 1u);
  // A list that does not extend the painted one repaints from the baked texture: the burn is gone again.
  for (StereoRenderer* renderer : {&reference, &cached}) renderer->setFundusBurns({});
  EXPECT_EQ(renderFrame(reference).images[0].data, before.images[0].data);
  // Non-finite burns are skipped, not painted and not fatal.
  FundusBurn broken = burn;
  broken.position.x() = std::numeric_limits<float>::quiet_NaN();
  reference.setFundusBurns({broken});
  EXPECT_EQ(renderFrame(reference).images[0].data, before.images[0].data);

  // The aiming beam: an emissive disc is red where it lies, whatever the light.
  const MeshData disc = laserAimMesh(0.0006f);
  reference.setStyle(kLaserAimId, laserAimStyle());
  reference.updateMesh(kLaserAimId, disc.view(), 1);
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
  pose.translation() = 0.9975f * fundus.toEye(Eigen::Vector2f(0.002f, -0.0025f));
  pose.linear() =
      Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), -pose.translation().normalized()).toRotationMatrix();
  reference.setPose(kLaserAimId, pose);
  const StereoFrame aimed_frame = renderFrame(reference);  // named: a reference into the temporary would dangle
  const RgbImage& aimed = aimed_frame.images[0];
  const std::uint8_t* rgb = &aimed.data[(static_cast<int>(away.y()) * aimed.width + static_cast<int>(away.x())) * 3];
  EXPECT_GT(rgb[0], 200);
  EXPECT_GT(rgb[0], 3 * rgb[1]);
  RenderState state = reference.captureState();
  EXPECT_EQ(state.burns.size(), 1u);
  bool emissive_saved = false;
  for (const RenderState::Object& object : state.objects)
    emissive_saved |= object.id == kLaserAimId && !object.style.material.emission.isZero();
  EXPECT_TRUE(emissive_saved);
}

TEST(FundusBurn, PaintsOnlyTheTexelsWithinItsRadius) {
  const int size = 256;
  const float radius = 0.012f;
  std::vector<std::uint8_t> texture(size * size * 4, 100);
  FundusBurn burn;
  burn.position = Eigen::Vector3f(0.0f, 0.0f, -radius);  // the pole: the texture's centre
  burn.diameter = 0.001f;
  burn.whiteness = 1.0f;
  const TexelRect rect = paintBurn(&texture, size, radius, burn);
  const float texel = 2.0f * radius / size;  // 94 µm
  EXPECT_NEAR(rect.width, burn.diameter / texel, 2.0);
  EXPECT_EQ(rect.width, rect.height);
  int changed = 0;
  for (int j = 0; j < size; ++j) {
    for (int i = 0; i < size; ++i) {
      if (texture[(j * size + i) * 4] == 100) continue;
      ++changed;
      EXPECT_TRUE(i >= rect.x && i < rect.x + rect.width && j >= rect.y && j < rect.y + rect.height);
      EXPECT_GT(texture[(j * size + i) * 4], 100);  // whiter
      EXPECT_EQ(texture[(j * size + i) * 4 + 3], 100) << "alpha (the bleeding channel) is left alone";
    }
  }
  // The disc's area in texels, within its soft rim.
  EXPECT_NEAR(changed, M_PI * 0.25 * burn.diameter * burn.diameter / (texel * texel), 0.35 * changed);
  const std::uint8_t centre = texture[((size / 2) * size + size / 2) * 4];
  EXPECT_GT(centre, 200);
  FundusBurn off = burn;
  off.position.x() = 0.5f;  // far off the texture
  EXPECT_EQ(paintBurn(&texture, size, radius, off).width, 0);
  off = burn;
  off.diameter = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(paintBurn(&texture, size, radius, off).width, 0);
  // Finite but far beyond int texel indices (the fuzzer's input: -1.8e11 texels); UBSan catches a cast out of range.
  for (const float far : {-3e38f, -1e7f, 1e7f, 3e38f}) {
    off = burn;
    off.position.x() = far;
    EXPECT_EQ(paintBurn(&texture, size, radius, off).width, 0) << far;
    off = burn;
    off.diameter = std::abs(far);
    EXPECT_EQ(paintBurn(&texture, size, radius, off).width, size) << "a burn larger than the texture covers it all";
  }
  std::vector<std::uint8_t> wrong_size(10);
  EXPECT_EQ(paintBurn(&wrong_size, size, radius, burn).width, 0);
}

// Tracked eye poses jitter by a fraction of a pixel every frame. Within RenderOptions::static_pose_tolerance_px the
// retina stays at its anchor pose (the layer is kept, the image is that of the anchor pose); a larger move is drawn
// where it is asked for.
TEST(Renderer, StaticObjectsKeepTheirAnchorPoseWhileTheyMoveLessThanTheTolerance) {
  RenderOptions options;
  options.width = kWidth;
  options.height = kHeight;
  options.cache_static = false;
  StereoRenderer reference(options);
  options.cache_static = true;
  StereoRenderer cached(options);
  LightPipe light;
  const std::vector<SceneObject> scene = typicalScene(&light);
  Eigen::Isometry3f retina_pose = Eigen::Isometry3f::Identity();
  for (StereoRenderer* renderer : {&reference, &cached}) {
    for (const SceneObject& object : scene) {
      renderer->setStyle(object.id, object.style);
      renderer->setPose(object.id, object.pose);
      renderer->updateMesh(object.id, object.mesh.view(), 1);
      if (object.id == "retina") retina_pose = object.pose;
    }
    renderer->setLightPipe(light);
  }
  for (int frame = 0; frame < 3; ++frame) {  // anchor and layer in place
    renderFrame(reference);
    renderFrame(cached);
  }
  // Pixels per metre at the focal plane: 160 px over the 30 mm field. 0.1 px of translation: kept.
  const float metres_per_pixel = 0.03f / kWidth;
  Eigen::Isometry3f jittered = retina_pose;
  jittered.translation() += Eigen::Vector3f(0.1f * metres_per_pixel, 0.0f, 0.0f);
  cached.setPose("retina", jittered);
  StereoFrame a = renderFrame(reference);  // still at the anchor pose
  StereoFrame b = renderFrame(cached);
  EXPECT_EQ(b.timings.static_layers_drawn, 0);
  EXPECT_EQ(a.images[0].data, b.images[0].data) << "within the tolerance the retina is drawn at its anchor pose";
  // 3 px: drawn where asked (as the reference, given the same pose).
  Eigen::Isometry3f moved = retina_pose;
  moved.translation() += Eigen::Vector3f(3.0f * metres_per_pixel, 0.0f, 0.0f);
  cached.setPose("retina", moved);
  reference.setPose("retina", moved);
  a = renderFrame(reference);
  b = renderFrame(cached);
  EXPECT_EQ(a.images[0].data, b.images[0].data);
  EXPECT_EQ(a.images[1].data, b.images[1].data);
  StereoFrame before = renderFrame(cached);
  EXPECT_EQ(before.timings.static_layers_drawn, 2) << "held still for a frame: the layer follows the new anchor";
}

// Instrument switching and jaw animation (InstrumentState.type, .jaw_angle): the forceps' jaws open with the angle
// (the mesh widens across the jaws), other instruments ignore it, and a switched slot draws the other instrument.
TEST(InstrumentMesh, ForcepsJawsOpenWithTheAngleAndSwitchingChangesTheMesh) {
  namespace scene = vrm_sim::scene;
  scene::InstrumentDescription forceps;
  forceps.type = scene::InstrumentType::kForceps;
  forceps.params = scene::defaultInstrumentParams(forceps.type);
  auto spread = [](const MeshData& mesh) {  // extent across the jaws (y) of the part beyond the shaft's end
    float lo = 0.0f, hi = 0.0f;
    for (std::size_t i = 0; i < mesh.positions.size(); i += 3) {
      if (mesh.positions[i + 2] > -0.0016f) {
        lo = std::min(lo, mesh.positions[i + 1]);
        hi = std::max(hi, mesh.positions[i + 1]);
      }
    }
    return hi - lo;
  };
  auto drawn = [&](scene::InstrumentType type, double jaw_angle) {  // what the nodelet uploads for a slot
    return toMeshData(
        scene::instrumentMesh(scene::instrumentOfType(forceps, type), scene::jawStepDeg(type, jaw_angle)));
  };
  const MeshData closed = drawn(forceps.type, 0.0);
  const MeshData open = drawn(forceps.type, 0.6);
  EXPECT_EQ(closed.triangles.size(), open.triangles.size());
  EXPECT_GT(spread(open), spread(closed) + 0.0003f) << "0.6 rad over 1.5 mm jaws: the tips ~0.9 mm apart";
  EXPECT_EQ(scene::jawStepDeg(forceps.type, 0.6), 34);
  EXPECT_EQ(scene::jawStepDeg(forceps.type, std::nan("")), 0);
  EXPECT_EQ(scene::jawStepDeg(scene::InstrumentType::kVitrector, 0.6), 0) << "only forceps have jaws";
  const MeshData vitrector = drawn(scene::InstrumentType::kVitrector, 0.6);
  const MeshData reference =
      toMeshData(scene::buildInstrumentMesh({scene::InstrumentSlot::kLeft, scene::InstrumentType::kVitrector, "left",
                                             scene::defaultInstrumentParams(scene::InstrumentType::kVitrector)}));
  EXPECT_EQ(vitrector.positions, reference.positions) << "a switched slot draws the default instrument of that type";
  EXPECT_NE(vitrector.positions.size(), closed.positions.size());
}

TEST(Renderer, MonoModeRendersOneImage) {
  StereoRenderer renderer(smallOptions(false));
  renderer.setStyle("floor", matte());
  renderer.updateMesh("floor", makePlane(0, 0, kFocalZ, 0.01f, 4, false, {1, 1, 1}).view(), 1);
  const StereoFrame frame = renderFrame(renderer);
  EXPECT_EQ(frame.images[0].width, kWidth);
  EXPECT_TRUE(frame.images[1].data.empty());
}

// ---- Golden images: instrument above the retina under the light pipe (vrm_sim's procedural meshes). ----

class GoldenScene {
 public:
  explicit GoldenScene(const RenderOptions& options) : renderer_(options) {
    const float radius = 0.012f;
    ObjectStyle retina;
    retina.material.diffuse = {0.85f, 0.35f, 0.22f, 1.0f};
    retina.material.specular = {0.3f, 0.25f, 0.2f};
    retina.material.shininess = 24.0f;
    retina.bump_mapped = true;
    retina_ = toMeshData(vrm_sim::scene::makeRetina({radius, 60.0, 24}));
    renderer_.setStyle("retina", retina);
    renderer_.updateMesh("retina", retina_.view(), 1);
    ObjectStyle metal;
    metal.material.diffuse = {0.75f, 0.75f, 0.78f, 1.0f};
    metal.material.specular = {0.8f, 0.8f, 0.8f};
    metal.material.shininess = 40.0f;
    const float s = std::sqrt(0.5f) * radius;
    const Eigen::Vector3f left_trocar(-s * 0.866f, s * 0.5f, s), right_trocar(s * 0.866f, s * 0.5f, s);
    const Eigen::Isometry3f light_pose =
        instrumentPoseThroughTrocar(left_trocar, Eigen::Vector3f(0.001f, 0.0f, -radius), 0.013f);
    renderer_.setStyle("light_pipe", metal);
    renderer_.setPose("light_pipe", light_pose);
    renderer_.updateMesh("light_pipe", toMeshData(vrm_sim::scene::makeLightPipe({})).view(), 1);
    ObjectStyle forceps = metal;
    forceps.casts_shadow = true;
    renderer_.setStyle("forceps", forceps);
    renderer_.setPose("forceps",
                      instrumentPoseThroughTrocar(right_trocar, Eigen::Vector3f(-0.001f, -0.001f, -radius), 0.0185f));
    renderer_.updateMesh("forceps", toMeshData(vrm_sim::scene::makeForceps({})).view(), 1);
    LightPipe light = lightPipeAt(light_pose);
    light.cone_half_angle_rad = 0.5f;
    renderer_.setLightPipe(light);
    MicroscopeState microscope;
    microscope.zoom = 1.6;
    microscope.ambient_light = 0.25;
    renderer_.setMicroscope(microscope);
  }
  StereoRenderer& renderer() { return renderer_; }
  MeshData& retina() { return retina_; }

  // Left and right image side by side.
  RgbImage renderSideBySide() {
    StereoFrame frame;
    renderer_.render(&frame);
    RgbImage both;
    const RgbImage& l = frame.images[0];
    const RgbImage& r = frame.images[1];
    both.width = l.width + r.width;
    both.height = l.height;
    both.data.resize(static_cast<std::size_t>(both.width) * both.height * 3);
    for (int y = 0; y < both.height; ++y) {
      std::copy(l.pixel(0, y), l.pixel(0, y) + l.width * 3, both.data.begin() + y * both.width * 3);
      std::copy(r.pixel(0, y), r.pixel(0, y) + r.width * 3, both.data.begin() + y * both.width * 3 + l.width * 3);
    }
    return both;
  }

 private:
  StereoRenderer renderer_;
  MeshData retina_;
};

void expectMatchesGolden(const RgbImage& image, const std::string& name) {
  const std::string path = std::string(VRM_RENDER_GOLDEN_DIR) + "/" + name + ".png";
  const char* update = std::getenv("VRM_RENDER_UPDATE_GOLDEN");
  if (update && std::string(update) == "1") {
    savePng(image, path);
    return;
  }
  if (!std::ifstream(path).good()) {
    ADD_FAILURE() << "missing golden image " << path << " (create with VRM_RENDER_UPDATE_GOLDEN=1)";
    return;
  }
  const RgbImage golden = loadPng(path);
  ASSERT_EQ(golden.width, image.width);
  ASSERT_EQ(golden.height, image.height);
  const double quality = psnr(image, golden);
  const double different = fractionDifferent(image, golden, 24);
  EXPECT_GT(quality, 36.0) << name << ": PSNR " << quality << " dB";
  EXPECT_LT(different, 0.003) << name << ": " << different * 100 << "% of pixels differ by more than 24";
  if (quality <= 36.0 || different >= 0.003) savePng(image, ::testing::TempDir() + "/" + name + "_actual.png");
}

RgbImage renderGolden(bool shadow, bool dof, double focus, bool bleed) {
  RenderOptions options = smallOptions(true);
  options.bump_mapping = true;
  options.shadow_pass = shadow;
  options.dof_pass = dof;
  GoldenScene scene(options);
  MicroscopeState microscope = scene.renderer().microscope();
  microscope.focus_distance = focus;
  scene.renderer().setMicroscope(microscope);
  if (bleed) {
    MeshData& retina = scene.retina();
    retina.injury.assign(retina.positions.size() / 3, 0.0f);
    for (std::size_t v = 0; v < retina.injury.size(); ++v) {
      const Eigen::Vector3f p(retina.positions[3 * v], retina.positions[3 * v + 1], retina.positions[3 * v + 2]);
      retina.injury[v] = std::max(0.0f, 1.0f - (p - Eigen::Vector3f(0.0005f, 0.0005f, -0.012f)).norm() / 0.0025f);
    }
    scene.renderer().updateMesh("retina", retina.view(), 2);
  }
  return scene.renderSideBySide();
}

TEST(Golden, InstrumentAboveRetinaWithShadow) { expectMatchesGolden(renderGolden(true, false, 0.2, false), "shadow"); }
TEST(Golden, InstrumentAboveRetinaWithoutShadow) {
  expectMatchesGolden(renderGolden(false, false, 0.2, false), "no_shadow");
}
TEST(Golden, DepthOfFieldFocusedOnRetina) { expectMatchesGolden(renderGolden(true, true, 0.2, false), "dof_retina"); }
TEST(Golden, DepthOfFieldFocusedAboveRetina) {
  expectMatchesGolden(renderGolden(true, true, 0.193, false), "dof_above");
}
TEST(Golden, BleedingRetina) { expectMatchesGolden(renderGolden(true, false, 0.2, true), "bleeding"); }

}  // namespace
}  // namespace vrm_render
