// Issue 33: render state files (round trip through a second renderer, bad files) and the frame checks
// (frame_check.h) on synthetic images where the answer is known — each check is also shown to fail.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "vrm_render/frame_check.h"
#include "vrm_render/image_io.h"
#include "vrm_render/render_state.h"
#include "vrm_render/scene_setup.h"
#include "vrm_render/stereo_renderer.h"
#include "vrm_sim/scenario/light_cone.h"

namespace vrm_render {
namespace {

RgbImage uniform(int w, int h, std::uint8_t value) {
  RgbImage image;
  image.width = w;
  image.height = h;
  image.data.assign(static_cast<std::size_t>(w) * h * 3, value);
  return image;
}

void fillRect(RgbImage* image, int x0, int y0, int x1, int y1, std::uint8_t value) {
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      std::uint8_t* p = image->data.data() + (static_cast<std::size_t>(y) * image->width + x) * 3;
      p[0] = p[1] = p[2] = value;
    }
  }
}

std::string tempPath(const std::string& name) { return ::testing::TempDir() + "/" + name; }

// A renderer with the thesis' typical scene (retina, membrane, light pipe, forceps), small images.
std::unique_ptr<StereoRenderer> typicalRenderer(int width, int height) {
  RenderOptions options;
  options.width = width;
  options.height = height;
  auto renderer = std::make_unique<StereoRenderer>(options);
  LightPipe light;
  for (const SceneObject& object : typicalScene(&light)) {
    renderer->setStyle(object.id, object.style);
    renderer->updateMesh(object.id, object.mesh.view(), 1);
    renderer->setPose(object.id, object.pose);
  }
  renderer->setLightPipe(light);
  return renderer;
}

TEST(RenderState, ARestoredStateRendersTheSameFrameInAnotherRenderer) {
  auto original = typicalRenderer(200, 150);
  StereoFrame first;
  original->render(&first);
  const RenderState state = original->captureState();
  ASSERT_FALSE(state.objects.empty());
  const std::string path = tempPath("typical.frame");
  writeRenderState(state, path);
  const RenderState read = readRenderState(path);
  ASSERT_EQ(read.objects.size(), state.objects.size());
  for (std::size_t i = 0; i < read.objects.size(); ++i) {
    EXPECT_EQ(read.objects[i].id, state.objects[i].id);
    EXPECT_EQ(read.objects[i].mesh.positions, state.objects[i].mesh.positions);
    EXPECT_EQ(read.objects[i].mesh.normals, state.objects[i].mesh.normals);
    EXPECT_EQ(read.objects[i].mesh.triangles, state.objects[i].mesh.triangles);
    EXPECT_TRUE(read.objects[i].pose.isApprox(state.objects[i].pose, 0.0f));
  }
  EXPECT_EQ(read.light.tip, state.light.tip);
  EXPECT_EQ(read.fundus_texture_hash, state.fundus_texture_hash);

  RenderOptions other_options;  // a renderer set up differently, with an object the state does not have
  other_options.width = 64;
  other_options.height = 48;
  StereoRenderer copy(other_options);
  MeshData stray = typicalScene(nullptr)[0].mesh;
  copy.updateMesh("stray", stray.view(), 7);
  copy.restoreState(read);
  EXPECT_FALSE(copy.hasObject("stray"));
  StereoFrame second;
  copy.render(&second);
  for (int e = 0; e < 2; ++e) {
    ASSERT_EQ(second.images[e].width, 200);
    EXPECT_GT(psnr(first.images[e], second.images[e]), 45.0) << "eye " << e;
  }
  // The state is not a trivial one: without the light pipe the frame differs.
  RenderState dark = read;
  dark.light.enabled = false;
  copy.restoreState(dark);
  StereoFrame third;
  copy.render(&third);
  EXPECT_LT(psnr(first.images[0], third.images[0]), 30.0);
}

// Issue 37 (format 2): the fundus burns and the materials' emission travel through the file, a restored state shows
// the burns, and a non-finite burn is refused like a non-finite pose.
TEST(RenderState, BurnsAndEmissionRoundTrip) {
  auto original = typicalRenderer(120, 90);
  FundusBurn burn;
  burn.position = Eigen::Vector3f(0.001f, -0.0005f, -0.01195f);
  burn.diameter = 0.0006f;
  burn.whiteness = 0.7f;
  original->setFundusBurns({burn});
  ObjectStyle aim = laserAimStyle();
  original->setStyle(kLaserAimId, aim);
  original->updateMesh(kLaserAimId, laserAimMesh(0.0005f).view(), 1);
  StereoFrame first;
  original->render(&first);
  const RenderState read = decodeRenderState(encodeRenderState(original->captureState()));
  ASSERT_EQ(read.burns.size(), 1u);
  EXPECT_EQ(read.burns[0].position, burn.position);
  EXPECT_EQ(read.burns[0].diameter, burn.diameter);
  EXPECT_EQ(read.burns[0].whiteness, burn.whiteness);
  bool found = false;
  for (const RenderState::Object& object : read.objects) {
    if (object.id == kLaserAimId) found = object.style.material.emission == aim.material.emission;
  }
  EXPECT_TRUE(found);
  StereoRenderer copy;
  copy.restoreState(read);
  StereoFrame second;
  copy.render(&second);
  EXPECT_EQ(first.images[0].data, second.images[0].data);
  RenderState bad = read;
  bad.burns[0].diameter = std::numeric_limits<float>::infinity();
  EXPECT_THROW(writeRenderState(bad, tempPath("bad_burn.frame")), RenderStateError);
}

TEST(RenderState, BadFilesGiveClearErrors) {
  auto renderer = typicalRenderer(80, 60);
  StereoFrame frame;
  renderer->render(&frame);
  const std::string bytes = encodeRenderState(renderer->captureState());
  EXPECT_NO_THROW(decodeRenderState(bytes));
  try {
    decodeRenderState(bytes.substr(0, bytes.size() / 2), "half.frame");
    FAIL() << "a truncated file was accepted";
  } catch (const RenderStateError& e) {
    EXPECT_NE(std::string(e.what()).find("half.frame"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  }
  std::string wrong = bytes;
  wrong[0] = 'X';
  EXPECT_THROW(decodeRenderState(wrong), RenderStateError);
  EXPECT_THROW(decodeRenderState(""), RenderStateError);
  EXPECT_THROW(decodeRenderState(bytes + "x"), RenderStateError);
  EXPECT_THROW(readRenderState(tempPath("does_not_exist.frame")), RenderStateError);
  // A PNG is not a render state.
  savePng(frame.images[0], tempPath("image.png"));
  EXPECT_THROW(readRenderState(tempPath("image.png")), RenderStateError);
}

TEST(RenderState, NonFinitePosesAreRejectedOnWriteAndOnRead) {
  auto renderer = typicalRenderer(80, 60);
  StereoFrame frame;
  renderer->render(&frame);
  RenderState state = renderer->captureState();
  state.objects[0].pose.translation().x() = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(writeRenderState(state, tempPath("nan.frame")), RenderStateError);
  try {
    decodeRenderState(encodeRenderState(state), "nan.frame");
    FAIL() << "a NaN pose was accepted";
  } catch (const RenderStateError& e) {
    EXPECT_NE(std::string(e.what()).find("non-finite pose"), std::string::npos) << e.what();
  }
  EXPECT_THROW(renderer->restoreState(state), RenderStateError);
}

TEST(ShadowCheck, ADarkRegionReachingTheTipPassesAndOneElsewhereDoesNot) {
  const RgbImage lit = uniform(200, 150, 120);
  const Eigen::Vector2f tip(100.0f, 75.0f);
  RgbImage shaded = lit;
  fillRect(&shaded, 60, 70, 98, 80, 60);  // 38 x 10 = 380 px, 50 % darker, ends 2 px left of the tip
  const ShadowResult reaching = findShadow(shaded, lit, tip);
  EXPECT_TRUE(reaching.pass);
  EXPECT_EQ(reaching.region_px, 380);
  EXPECT_NEAR(reaching.darkening, 0.5, 0.01);
  EXPECT_LT(reaching.distance_px, 3.0);

  RgbImage away = lit;
  fillRect(&away, 20, 70, 60, 80, 60);  // ends 40 px from the tip
  const ShadowResult far = findShadow(away, lit, tip);
  EXPECT_FALSE(far.pass);
  EXPECT_GT(far.distance_px, 39.0);

  RgbImage small = lit;
  fillRect(&small, 90, 70, 100, 80, 60);  // 100 px: too small to be the instrument's shadow
  EXPECT_FALSE(findShadow(small, lit, tip).pass);

  RgbImage faint = lit;
  fillRect(&faint, 60, 70, 98, 80, 100);  // 17 % darker: not a shadow by the criteria
  EXPECT_FALSE(findShadow(faint, lit, tip).pass);
}

TEST(FocusCheck, ABlurredWorkingAreaFailsAndASharpOnePasses) {
  RgbImage sharp = uniform(200, 150, 0);
  for (int y = 0; y < 150; ++y) {
    for (int x = 0; x < 200; ++x) fillRect(&sharp, x, y, x + 1, y + 1, ((x / 3 + y / 3) % 2) ? 200 : 40);
  }
  cv::Mat src(150, 200, CV_8UC3, sharp.data.data());
  RgbImage blurred = sharp;
  cv::Mat dst(150, 200, CV_8UC3, blurred.data.data());
  cv::GaussianBlur(src, dst, cv::Size(0, 0), 2.0);
  const Window area = workingArea(Eigen::Vector2f(100.0f, 75.0f), 200, 150);
  EXPECT_EQ(area.pixels(), kWorkingAreaSide * kWorkingAreaSide);
  const double reference = laplacianVariance(sharp, area);
  EXPECT_NEAR(laplacianVariance(sharp, area) / reference, 1.0, 1e-9);
  EXPECT_LT(laplacianVariance(blurred, area) / reference, 0.8);
  // An out-of-focus instrument in the window (blurred, not fundus) lowers the unmasked variance; the working plane
  // (the fundus pixels) is still sharp.
  RgbImage with_instrument = sharp;
  std::vector<PixelClass> classes(200 * 150, PixelClass::kFundusOutside);
  for (int y = 60; y < 90; ++y) {
    for (int x = 0; x < 200; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * 200 + x;
      for (int c = 0; c < 3; ++c) with_instrument.data[3 * i + c] = blurred.data[3 * i + c];
      classes[i] = PixelClass::kOther;
    }
  }
  EXPECT_LT(laplacianVariance(with_instrument, area) / reference, 0.8);
  EXPECT_NEAR(laplacianVariance(with_instrument, area, &classes) / laplacianVariance(sharp, area, &classes), 1.0, 1e-9);
  // ... but a blurred working plane fails with the mask too.
  EXPECT_LT(laplacianVariance(blurred, area, &classes) / laplacianVariance(sharp, area, &classes), 0.8);
  // A window at the image corner is clipped, not out of bounds.
  const Window corner = workingArea(Eigen::Vector2f(2.0f, 2.0f), 200, 150);
  EXPECT_EQ(corner.x0, 0);
  EXPECT_GT(laplacianVariance(sharp, corner), 0.0);
  EXPECT_THROW(laplacianVariance(sharp, workingArea(Eigen::Vector2f(-500.0f, 2.0f), 200, 150)), RenderError);
}

TEST(ConeCheck, ALitDiscPassesAndAnUnlitOrDimOneFails) {
  const int w = 120, h = 90;
  std::vector<PixelClass> classes(w * h, PixelClass::kFundusOutside);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (std::hypot(x - 60.0, y - 45.0) < 20.0) classes[y * w + x] = PixelClass::kFundusInside;
      if (x < 5) classes[y * w + x] = PixelClass::kOther;  // background: counted nowhere
    }
  }
  auto paint = [&](std::uint8_t in, std::uint8_t out) {
    RgbImage image = uniform(w, h, out);
    for (int i = 0; i < w * h; ++i) {
      if (classes[i] == PixelClass::kFundusInside)
        image.data[3 * i] = image.data[3 * i + 1] = image.data[3 * i + 2] = in;
      if (classes[i] == PixelClass::kOther) image.data[3 * i] = image.data[3 * i + 1] = image.data[3 * i + 2] = 250;
    }
    return image;
  };
  const ConeResult lit = coneLighting(paint(140, 40), classes);
  EXPECT_TRUE(lit.pass);
  EXPECT_NEAR(lit.inside_grey, 140.0, 0.5);
  EXPECT_NEAR(lit.outside_grey, 40.0, 0.5);
  EXPECT_FALSE(coneLighting(paint(38, 36), classes).pass);   // the coaxial light alone
  EXPECT_FALSE(coneLighting(paint(80, 30), classes).pass);   // contrast, too dim
  EXPECT_FALSE(coneLighting(paint(110, 70), classes).pass);  // bright, but the fill is too bright
}

// The cone's pixels are found from the rendered depth with the scoring's rule: the fundus under the light pipe's
// axis is inside, the retina far from it outside, the instruments and the background neither.
TEST(ConeCheck, TheRenderedFundusUnderTheLightPipeIsInsideTheCone) {
  auto renderer = typicalRenderer(240, 180);
  StereoFrame frame;
  renderer->render(&frame);
  const RenderState state = renderer->captureState();
  std::vector<float> depth;
  renderer->readDepth(Eye::kLeft, &depth);
  const CameraView camera = renderer->camera(Eye::kLeft);
  const auto classes =
      classifyFundus(depth, camera, Eigen::Vector3f::Zero(), renderer->fundus().params().eye_radius, true,
                     state.light.tip, state.light.direction, vrm_sim::scenario::kLightConeHalfAngleDeg);
  int inside = 0, outside = 0;
  for (PixelClass c : classes) {
    inside += c == PixelClass::kFundusInside;
    outside += c == PixelClass::kFundusOutside;
  }
  EXPECT_GT(inside, 500);
  EXPECT_GT(outside, 500);
  EXPECT_LT(inside + outside, 240 * 180);  // the instruments are not fundus
  const ConeResult lit = coneLighting(frame.images[0], classes);
  RenderState unlit_state = state;
  unlit_state.light.enabled = false;
  renderer->restoreState(unlit_state);
  StereoFrame unlit;
  renderer->render(&unlit);
  const ConeResult dark = coneLighting(unlit.images[0], classes);
  EXPECT_GT(lit.inside_grey, 1.5 * dark.inside_grey);
  EXPECT_FALSE(dark.pass);
}

}  // namespace
}  // namespace vrm_render

namespace vrm_render {
namespace {

// The renderer's cone (endoilluminator: smoothstep from the outer edge to the inner one) and the scoring's lit rule
// (kLightConeHalfAngleDeg) agree: at the rule's half-angle the light has faded to about half its centre, inside it
// more, and at the renderer's outer edge it is gone.
TEST(ConeCheck, TheRendererConeIsAtHalfItsCentreAtTheScoringsHalfAngle) {
  const LightPipe light = endoilluminator();
  const double outer = std::cos(light.cone_half_angle_rad);
  const double inner = std::cos(light.cone_half_angle_rad * (1.0 - light.cone_softness));
  auto cone = [&](double deg) {  // GLSL smoothstep(cos_outer, cos_inner, cos(angle))
    const double t = std::clamp((std::cos(deg * M_PI / 180.0) - outer) / (inner - outer), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
  };
  const double at_rule = cone(vrm_sim::scenario::kLightConeHalfAngleDeg);
  EXPECT_GT(at_rule, 0.4);
  EXPECT_LT(at_rule, 0.7);
  EXPECT_GT(cone(vrm_sim::scenario::kLightConeHalfAngleDeg - 10.0), 0.9);
  EXPECT_NEAR(cone(light.cone_half_angle_rad * 180.0 / M_PI), 0.0, 1e-9);
}

}  // namespace
}  // namespace vrm_render
