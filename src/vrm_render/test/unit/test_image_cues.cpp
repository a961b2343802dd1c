// Measurable image tests of issue 16: what a surgeon reads from the microscope image, checked by simple image
// analysis of rendered frames (not only golden images): the focal plane is sharp and a plane 2 mm nearer is not,
// the light pipe's shadow of an instrument closes on its tip as the tip descends to the retina (the depth cue of
// thesis §6 / §7.4.2 pass 1), the optic disc and the four arcade vessels are where the fundus map puts them, and
// the stereo disparity of a retina point is the microscope's geometry.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "vrm_render/fundus.h"
#include "vrm_render/image_io.h"
#include "vrm_render/scene_setup.h"
#include "vrm_render/stereo_renderer.h"
#include "vrm_scene/meshes/eye_meshes.h"
#include "vrm_scene/meshes/instrument_meshes.h"

namespace vrm_render {
namespace {

constexpr float kRadius = 0.012f;
constexpr float kFocalZ = -kRadius;  // default focus 0.2 m below the objective at 0.188 m: the posterior pole

// A checkerboard of `cells` x `cells` flat-coloured quads centred at (cx, cy); on the plane z = `z`, or on the
// retina sphere (radius kRadius about the origin) when `z` is NaN.
MeshData checker(float cx, float cy, float z, float half, int cells) {
  MeshData mesh;
  const float step = 2.0f * half / cells;
  auto height = [&](float x, float y) { return std::isnan(z) ? -std::sqrt(kRadius * kRadius - x * x - y * y) : z; };
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) {
      const float x0 = cx - half + i * step, y0 = cy - half + j * step;
      const float shade = (i + j) % 2 ? 0.1f : 1.0f;
      const auto base = static_cast<std::uint32_t>(mesh.positions.size() / 3);
      const float corners[4][2] = {{x0, y0}, {x0 + step, y0}, {x0 + step, y0 + step}, {x0, y0 + step}};
      for (const auto& c : corners) {
        mesh.positions.insert(mesh.positions.end(), {c[0], c[1], height(c[0], c[1])});
        mesh.normals.insert(mesh.normals.end(), {0.0f, 0.0f, 1.0f});
        mesh.colors.insert(mesh.colors.end(), {shade, shade, shade, 1.0f});
      }
      mesh.triangles.insert(mesh.triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    }
  }
  return mesh;
}

ObjectStyle matte(Eigen::Vector4f diffuse = {0.8f, 0.8f, 0.8f, 1.0f}) {
  ObjectStyle style;
  style.material.diffuse = diffuse;
  style.material.specular = Eigen::Vector3f::Zero();
  return style;
}

StereoFrame renderFrame(StereoRenderer& renderer) {
  StereoFrame frame;
  renderer.render(&frame);
  return frame;
}

Eigen::Vector2f pixelOf(const StereoRenderer& renderer, const Eigen::Vector3f& world, Eye eye = Eye::kLeft) {
  Eigen::Vector2f p;
  EXPECT_TRUE(projectToPixel(renderer.camera(eye), world, &p));
  return p;
}

cv::Mat luminance(const RgbImage& image) {
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.data.data()));
  cv::Mat grey;
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  return grey;
}

// ---- Focus: the circle of confusion of the objective. ----

// Variance-of-Laplacian sharpness of a 64x64 window.
double sharpness(const RgbImage& image, const Eigen::Vector2f& c) {
  return laplacianEnergy(image, int(c.x()) - 32, int(c.y()) - 32, int(c.x()) + 32, int(c.y()) + 32);
}

TEST(Focus, TheFocalPlaneOnTheRetinaStaysSharpAndAPlaneTwoMillimetresNearerBlurs) {
  RenderOptions options;
  options.width = 320;
  options.height = 240;
  options.stereo = false;
  options.lighting = false;  // flat checkerboards: sharpness depends only on the depth of field
  options.bump_mapping = false;
  options.dof_pass = false;
  StereoRenderer renderer(options);
  MicroscopeState microscope;
  microscope.zoom = 3.0;  // field 10 mm: 31 µm per pixel, a surgeon's view of the macula
  renderer.setMicroscope(microscope);
  // Left: 0.25 mm squares on the retina around the posterior pole (the focal plane); right: a plane 2 mm nearer.
  renderer.setStyle("retina", matte({1, 1, 1, 1}));
  renderer.updateMesh("retina", checker(-0.0025f, 0.0f, NAN, 0.002f, 16).view(), 1);
  renderer.setStyle("near", matte({1, 1, 1, 1}));
  renderer.updateMesh("near", checker(0.0025f, 0.0f, kFocalZ + 0.002f, 0.002f, 16).view(), 1);
  const Eigen::Vector2f retina_px = pixelOf(renderer, {-0.0025f, 0.0f, kFocalZ});
  const Eigen::Vector2f near_px = pixelOf(renderer, {0.0025f, 0.0f, kFocalZ + 0.002f});
  const StereoFrame reference = renderFrame(renderer);
  options.dof_pass = true;
  renderer.setOptions(options);
  const StereoFrame focused = renderFrame(renderer);
  const double retina_ratio = sharpness(focused.images[0], retina_px) / sharpness(reference.images[0], retina_px);
  const double near_ratio = sharpness(focused.images[0], near_px) / sharpness(reference.images[0], near_px);
  RecordProperty("retina_sharpness_ratio", std::to_string(retina_ratio));
  RecordProperty("near_sharpness_ratio", std::to_string(near_ratio));
  std::printf("focus 0.200 m: retina %.3f, plane 2 mm nearer %.3f of the DOF-off sharpness\n", retina_ratio,
              near_ratio);
  EXPECT_GE(retina_ratio, 0.9);
  EXPECT_LE(near_ratio, 0.5);

  // Focusing on the nearer plane swaps the roles (the focus knob visibly changes the image).
  microscope.focus_distance = 0.198;
  renderer.setMicroscope(microscope);
  const StereoFrame refocused = renderFrame(renderer);
  EXPECT_GE(sharpness(refocused.images[0], near_px) / sharpness(reference.images[0], near_px), 0.9);
  EXPECT_LE(sharpness(refocused.images[0], retina_px) / sharpness(reference.images[0], retina_px), 0.5);

  // Zoom: the same 2 mm defocus blurs fewer pixels at a lower magnification (the circle of confusion is fixed in
  // the object, the pixels grow), so the near plane keeps more of its (coarser) detail.
  microscope.focus_distance = 0.2;
  microscope.zoom = 1.0;
  renderer.setMicroscope(microscope);
  options.dof_pass = false;
  renderer.setOptions(options);
  const Eigen::Vector2f near_wide = pixelOf(renderer, {0.0025f, 0.0f, kFocalZ + 0.002f});
  const double wide_reference =
      laplacianEnergy(renderFrame(renderer).images[0], int(near_wide.x()) - 10, int(near_wide.y()) - 10,
                      int(near_wide.x()) + 10, int(near_wide.y()) + 10);
  options.dof_pass = true;
  renderer.setOptions(options);
  const double wide = laplacianEnergy(renderFrame(renderer).images[0], int(near_wide.x()) - 10, int(near_wide.y()) - 10,
                                      int(near_wide.x()) + 10, int(near_wide.y()) + 10);
  std::printf("zoom 1: plane 2 mm nearer %.3f of its DOF-off sharpness\n", wide / wide_reference);
  EXPECT_GT(wide / wide_reference, near_ratio + 0.1);
}

// ---- Shadow as a depth cue. ----

struct ShadowScene {
  StereoRenderer renderer;
  Eigen::Vector3f trocar{0.0085f, 0.0035f, -0.003f};
  Eigen::Vector3f foot{0.0005f, 0.0f, kFocalZ};  // where the instrument points at on the floor

  explicit ShadowScene(const RenderOptions& options) : renderer(options) {
    MicroscopeState microscope;
    microscope.zoom = 2.0;
    microscope.ambient_light = 0.15;
    renderer.setMicroscope(microscope);
    renderer.setStyle("floor", matte({0.9f, 0.9f, 0.9f, 1.0f}));
    MeshData floor = checker(0.0f, 0.0f, kFocalZ, 0.008f, 1);
    renderer.updateMesh("floor", floor.view(), 1);
    // The light pipe fixed 6 mm above the floor, on the instrument's side and 2.5 mm below (-y of) its foot, shining
    // at it: the tip's shadow falls ahead of and beside the tip, not under the instrument's own image.
    LightPipe light;
    light.enabled = true;
    light.tip = foot + Eigen::Vector3f(0.004f, -0.0025f, 0.006f);
    light.direction = (foot - light.tip).normalized();
    light.cone_half_angle_rad = 0.7f;
    renderer.setLightPipe(light);
    ObjectStyle forceps;
    forceps.material.diffuse = {0.75f, 0.75f, 0.78f, 1.0f};
    forceps.material.metallic = 0.85f;
    forceps.casts_shadow = true;
    renderer.setStyle("forceps", forceps);
    renderer.updateMesh("forceps", toMeshData(vrm_sim::scene::makeForceps({})).view(), 1);
  }

  // The instrument's tip `height` above the floor, on the line from the trocar to the foot.
  Eigen::Vector3f place(float height) {
    const Eigen::Vector3f dir = (foot - trocar).normalized();
    const float depth = (foot - trocar).norm() - height / std::abs(dir.z());
    const Eigen::Isometry3f pose = instrumentPoseThroughTrocar(trocar, foot, depth);
    renderer.setPose("forceps", pose);
    return pose.translation();
  }
};

// The detector: instrument pixels from an instrument-only flat render; shadow pixels are floor pixels (not the
// instrument) at most half as bright as the same pixel with the instrument removed; the instrument's tip is the
// image of its tip point (checked against the mask's extreme pixel along the shaft); the shadow's tip is the shadow
// pixel nearest to it (the light comes from the side, so the shadow's tip is its part nearest the instrument's).
// Returns the pixel distance, or nothing when there is no shadow.
std::optional<double> tipToShadowDistance(ShadowScene& scene, const RgbImage& floor_only, const Eigen::Vector3f& tip,
                                          RgbImage* shadow_image_out = nullptr) {
  StereoRenderer& r = scene.renderer;
  const StereoFrame full = renderFrame(r);
  RenderOptions options = r.options();
  const RenderOptions saved = options;
  options.lighting = false;
  r.setOptions(options);
  r.setVisible("floor", false);
  const StereoFrame instrument_only = renderFrame(r);
  r.setVisible("floor", true);
  r.setOptions(saved);
  const cv::Mat lit = luminance(full.images[0]);
  const cv::Mat reference = luminance(floor_only);
  const cv::Mat instrument = luminance(instrument_only.images[0]) > 40;  // no anti-aliasing: an exact mask
  const Eigen::Vector2f tip_px = pixelOf(r, tip);
  const Eigen::Vector2f shaft_px = pixelOf(r, scene.trocar);
  const Eigen::Vector2f axis = (tip_px - shaft_px).normalized();
  Eigen::Vector2f detected_tip(0, 0);
  float extreme = -1e9f;
  std::optional<double> nearest;
  for (int y = 0; y < lit.rows; ++y) {
    for (int x = 0; x < lit.cols; ++x) {
      const Eigen::Vector2f p(x + 0.5f, y + 0.5f);
      if (instrument.at<std::uint8_t>(y, x)) {
        if (p.dot(axis) > extreme) {
          extreme = p.dot(axis);
          detected_tip = p;
        }
      }
    }
  }
  // The mask's extreme pixel lies on the jaws' end, within a jaw's width of the tip point on the axis.
  EXPECT_LT((detected_tip - tip_px).norm(), 4.0f) << "instrument tip detection";
  for (int y = 0; y < lit.rows; ++y) {
    for (int x = 0; x < lit.cols; ++x) {
      if (instrument.at<std::uint8_t>(y, x)) continue;
      const int ref = reference.at<std::uint8_t>(y, x);
      if (ref < 30 || lit.at<std::uint8_t>(y, x) > 0.5 * ref) continue;
      const double d = (Eigen::Vector2f(x + 0.5f, y + 0.5f) - tip_px).norm();
      if (!nearest || d < *nearest) nearest = d;
    }
  }
  if (shadow_image_out) *shadow_image_out = full.images[0];
  return nearest;
}

TEST(ShadowCue, TheShadowTipClosesOnTheInstrumentTipAsItDescendsToTheRetina) {
  RenderOptions options;
  options.width = 320;
  options.height = 240;
  options.stereo = false;
  options.dof_pass = false;
  options.bump_mapping = false;
  ShadowScene scene(options);
  scene.renderer.setVisible("forceps", false);
  const RgbImage floor_only = renderFrame(scene.renderer).images[0];
  scene.renderer.setVisible("forceps", true);
  std::vector<double> distances;
  std::string curve;
  for (const float height : {0.002f, 0.0015f, 0.001f, 0.0006f, 0.0003f, 0.0001f, 0.0f}) {
    const Eigen::Vector3f tip = scene.place(height);
    RgbImage shot;
    const std::optional<double> d = tipToShadowDistance(scene, floor_only, tip, &shot);
    if (std::getenv("VRM_RENDER_SAVE_CUES")) savePng(shot, "/tmp/shadow_" + std::to_string(int(height * 1e5)) + ".png");
    ASSERT_TRUE(d.has_value()) << "no shadow detected at height " << height;
    distances.push_back(*d);
    curve += std::to_string(height * 1e3).substr(0, 4) + " mm: " + std::to_string(*d).substr(0, 5) + " px; ";
  }
  std::printf("tip-to-shadow distance: %s\n", curve.c_str());
  RecordProperty("shadow_distance_curve", curve);
  for (std::size_t i = 1; i < distances.size(); ++i) {
    // Non-increasing up to the quantisation of a nearest pixel centre (half a pixel).
    EXPECT_LE(distances[i], distances[i - 1] + 0.5) << "not monotonic at step " << i << ": " << curve;
  }
  EXPECT_GT(distances.front(), 20.0) << curve;
  EXPECT_LE(distances.back(), 3.0) << "at contact: " << curve;

  // The detector can fail: without the shadow pass it finds no shadow at all.
  options.shadow_pass = false;
  scene.renderer.setOptions(options);
  const Eigen::Vector3f tip = scene.place(0.001f);
  EXPECT_FALSE(tipToShadowDistance(scene, floor_only, tip).has_value()) << "the detector sees a shadow without one";
}

// ---- Fundus: the optic disc and the four arcades where the scene defines them. ----

TEST(FundusImage, TheDiscAndTheFourArcadeVesselsAreFoundWhereTheFundusMapPutsThem) {
  RenderOptions options;
  options.width = 800;
  options.height = 600;
  options.stereo = false;
  options.dof_pass = false;
  options.bump_mapping = false;
  StereoRenderer renderer(options);
  MicroscopeState microscope;  // the default view, coaxial light only
  microscope.ambient_light = 1.0;
  renderer.setMicroscope(microscope);
  // Another seed's fundus: VRM_RENDER_FUNDUS_SEED=<n> (the detector must not depend on one tree).
  FundusParams params;
  if (const char* seed = std::getenv("VRM_RENDER_FUNDUS_SEED"))
    params.seed = static_cast<std::uint32_t>(std::atoi(seed));
  auto fundus = std::make_shared<const FundusMap>(params);
  renderer.setFundus(fundus);
  ObjectStyle retina;
  retina.fundus = true;
  retina.material.specular = Eigen::Vector3f::Zero();
  renderer.setStyle("retina", retina);
  renderer.updateMesh("retina", toMeshData(vrm_sim::scene::makeRetina({kRadius, 90.0, 44})).view(), 1);
  const RgbImage image = renderFrame(renderer).images[0];
  if (std::getenv("VRM_RENDER_SAVE_CUES")) savePng(image, "/tmp/fundus_view.png");

  // Disc: the bright blob around the brightest point of the luminance (vessels closed away by a grey-level
  // closing, as they cross the disc), thresholded at a third of the way from the median fundus to that peak; its
  // centroid and equivalent diameter.
  cv::Mat grey = luminance(image), closed, smooth;
  cv::morphologyEx(grey, closed, cv::MORPH_CLOSE, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(11, 11)));
  cv::GaussianBlur(closed, smooth, cv::Size(0, 0), 2.0);
  double peak = 0.0;
  cv::Point brightest;
  cv::minMaxLoc(smooth, nullptr, &peak, nullptr, &brightest);
  std::vector<std::uint8_t> values(grey.begin<std::uint8_t>(), grey.end<std::uint8_t>());
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  const double median = values[values.size() / 2];
  cv::Mat bright = smooth > median + (peak - median) / 3.0, labels;
  cv::connectedComponents(bright, labels);
  const int disc_label = labels.at<int>(brightest);
  Eigen::Vector2d sum(0, 0);
  double area = 0.0;
  for (int y = 0; y < labels.rows; ++y) {
    for (int x = 0; x < labels.cols; ++x) {
      if (labels.at<int>(y, x) != disc_label) continue;
      sum += Eigen::Vector2d(x + 0.5, y + 0.5);
      area += 1.0;
    }
  }
  const Eigen::Vector2f disc_found = (sum / area).cast<float>();
  const Eigen::Vector2f disc_px = pixelOf(renderer, fundus->toEye(fundus->discCentre()));
  const float px_per_mm = options.width * 1e-3f / renderer.rig().field_width;
  const double diameter_mm = 2.0 * std::sqrt(area / M_PI) / px_per_mm;
  EXPECT_LT((disc_found - disc_px).norm(), 0.2f * px_per_mm)
      << "disc found at " << disc_found.transpose() << ", expected " << disc_px.transpose();
  EXPECT_GT(diameter_mm, 1.3) << "[Hogan] 1.5-1.8 mm";
  EXPECT_LT(diameter_mm, 2.0);

  // Vessels: dark ridges of the green channel (blood absorbs green; the red-free view of fundus photography),
  // black top-hat, sampled on a circle 2 mm around the disc centre; peaks are vessel crossings.
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.data.data()));
  cv::Mat green, ridges;
  cv::extractChannel(rgb, green, 1);
  cv::morphologyEx(green, ridges, cv::MORPH_BLACKHAT, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(13, 13)));
  const float circle = 0.002f;
  constexpr int kSamples = 1440;
  std::vector<float> profile(kSamples);
  for (int k = 0; k < kSamples; ++k) {
    const float phi = 2.0f * static_cast<float>(M_PI) * k / kSamples;
    const Eigen::Vector2f f = fundus->discCentre() + circle * Eigen::Vector2f(std::cos(phi), std::sin(phi));
    const Eigen::Vector2f p = pixelOf(renderer, fundus->toEye(f));
    profile[k] = ridges.at<std::uint8_t>(int(p.y()), int(p.x()));
  }
  std::vector<float> detected;  // angles of ridge peaks
  for (int k = 0; k < kSamples; ++k) {
    const float v = profile[k];
    if (v < 40.0f) continue;  // arcade-sized vessels (the veins ~60-70, capillary-sized branches less)
    bool peak = true;
    // Strict on one side: a plateau counts once.
    for (int o = -6; o <= 6 && peak; ++o)
      peak = o < 0 ? profile[(k + o + kSamples) % kSamples] < v : profile[(k + o) % kSamples] <= v;
    if (peak) detected.push_back(2.0f * static_cast<float>(M_PI) * k / kSamples);
  }
  // Where each arcade's trunk vein (generation 0) crosses the circle, from the fundus map.
  // As a control, the same positions turned by 0.6 rad must not all find a ridge (the check can fail).
  int found = 0, control = 0;
  for (int arcade = 0; arcade < 4; ++arcade) {
    std::optional<float> expected;
    for (const VesselSegment& s : fundus->vessels()) {
      if (s.arcade != arcade || s.generation != 0 || s.artery) continue;
      const float ra = (s.a - fundus->discCentre()).norm(), rb = (s.b - fundus->discCentre()).norm();
      if ((ra - circle) * (rb - circle) > 0.0f) continue;
      const Eigen::Vector2f c = s.a + (s.b - s.a) * ((circle - ra) / (rb - ra)) - fundus->discCentre();
      expected = std::atan2(c.y(), c.x());
      break;
    }
    ASSERT_TRUE(expected.has_value()) << "arcade " << arcade << " does not reach 2 mm from the disc";
    const float tolerance = 6.0f / (circle * 1e3f * px_per_mm);  // 6 px (a vein and its artery side by side)
    float nearest = 10.0f;
    for (float a : detected) nearest = std::min(nearest, std::abs(std::remainder(a - *expected, 2.0f * float(M_PI))));
    const bool hit = nearest <= tolerance;
    float shifted = 10.0f;
    for (float a : detected)
      shifted = std::min(shifted, std::abs(std::remainder(a - *expected - 0.6f, 2.0f * float(M_PI))));
    control += shifted <= tolerance ? 1 : 0;
    EXPECT_TRUE(hit) << "arcade " << arcade << " vein not detected at " << *expected << " rad (nearest ridge "
                     << nearest << " rad away, tolerance " << tolerance << ")";
    found += hit ? 1 : 0;
  }
  std::printf(
      "fundus: disc at (%.1f, %.1f) (expected %.1f, %.1f), %.2f mm across; %zu vessel crossings on the 2 mm "
      "circle, %d/4 arcades (control %d/4)\n",
      disc_found.x(), disc_found.y(), disc_px.x(), disc_px.y(), diameter_mm, detected.size(), found, control);
  EXPECT_GE(detected.size(), 6u) << "the four arcades' arteries and veins and their branches";
  EXPECT_LT(control, 4) << "ridges everywhere: the arcade check could not fail";
}

TEST(FundusMapApi, TheVesselMapIsQueryableAndSeeded) {
  const FundusMap a(FundusParams{}), b(FundusParams{});
  FundusParams other;
  other.seed = 7;
  const FundusMap c(other);
  EXPECT_EQ(a.texture(), b.texture()) << "same seed, same fundus";
  EXPECT_NE(a.texture(), c.texture());
  // A point on a trunk vein is inside a vessel; the fovea is in the avascular zone.
  const VesselSegment& trunk = a.vessels().front();
  const VesselQuery on = a.nearestVessel(a.toEye(0.5f * (trunk.a + trunk.b)));
  EXPECT_TRUE(on.inside);
  EXPECT_FALSE(a.nearestVessel(a.toEye(a.fovea())).inside);
  EXPECT_GT(a.nearestVessel(a.toEye(a.fovea())).distance, 0.0002f);
  // Murray's law shapes the tree: thinner vessels at higher generations, arteries thinner than veins at the disc.
  float vein = 0.0f, artery = 0.0f;
  for (const VesselSegment& s : a.vessels()) {
    if (s.generation == 0 && s.arcade == 0) (s.artery ? artery : vein) = std::max(s.artery ? artery : vein, s.radius_a);
  }
  EXPECT_LT(artery, vein);
  EXPECT_NEAR((a.toFundus(a.toEye({0.003f, -0.001f})) - Eigen::Vector2f(0.003f, -0.001f)).norm(), 0.0f, 1e-7f);
  const float disc_distance = a.discCentre().norm();
  EXPECT_NEAR(disc_distance, 0.0045f, 0.0002f);
}

// ---- Sheen: the endoillumination reflex shows where the membrane is lifted. ----

TEST(MembraneSheen, ALiftedFlapGlistensAndTheAdherentFilmDoesNot) {
  RenderOptions options;
  options.width = 320;
  options.height = 240;
  options.stereo = false;
  options.dof_pass = false;
  options.bump_mapping = false;
  options.shadow_pass = false;
  StereoRenderer renderer(options);
  MicroscopeState microscope;
  microscope.zoom = 2.0;
  microscope.ambient_light = 0.15;
  renderer.setMicroscope(microscope);
  renderer.setStyle("retina", matte({0.5f, 0.2f, 0.1f, 1.0f}));
  renderer.updateMesh("retina", checker(0.0f, 0.0f, kFocalZ, 0.006f, 1).view(), 1);
  // A film lying on the retina (left) and a flap of it lifted by 45 degrees about the y axis (right).
  MeshData flat = checker(-0.002f, 0.0f, kFocalZ + 0.0001f, 0.001f, 1);
  MeshData lifted = checker(0.002f, 0.0f, kFocalZ + 0.0001f, 0.001f, 1);
  for (std::size_t v = 0; v < lifted.positions.size(); v += 3) {
    const float dx = lifted.positions[v] - 0.001f;  // hinge at x = 1 mm
    lifted.positions[v] = 0.001f + dx * std::sqrt(0.5f);
    lifted.positions[v + 2] += dx * std::sqrt(0.5f);
    lifted.normals[v] = -std::sqrt(0.5f);
    lifted.normals[v + 2] = std::sqrt(0.5f);
  }
  LightPipe light;
  light.enabled = true;
  light.tip = Eigen::Vector3f(0.0f, -0.004f, kFocalZ + 0.005f);
  light.direction = (Eigen::Vector3f(0.0f, 0.0f, kFocalZ) - light.tip).normalized();
  light.cone_half_angle_rad = 1.0f;
  renderer.setLightPipe(light);
  auto film = [](float sheen) {
    ObjectStyle style;
    style.material.diffuse = {0.95f, 0.95f, 0.92f, 0.22f};
    style.material.specular = Eigen::Vector3f::Zero();  // the sheen alone
    style.material.sheen = sheen;
    return style;
  };
  auto luminanceAt = [&](const RgbImage& image, const Eigen::Vector3f& p) {
    const Eigen::Vector2f px = pixelOf(renderer, p);
    return meanLuminance(image, int(px.x()) - 3, int(px.y()) - 3, int(px.x()) + 4, int(px.y()) + 4);
  };
  const Eigen::Vector3f flat_centre(-0.002f, 0.0f, kFocalZ + 0.0001f);
  std::array<double, 2> flat_lum{}, lifted_lum{};
  for (int k = 0; k < 2; ++k) {
    renderer.setStyle("flat", film(k == 0 ? 0.0f : 1.2f));
    renderer.setStyle("lifted", film(k == 0 ? 0.0f : 1.2f));
    renderer.updateMesh("flat", flat.view(), 1);
    renderer.updateMesh("lifted", lifted.view(), 1);
    const StereoFrame frame = renderFrame(renderer);
    flat_lum[k] = luminanceAt(frame.images[0], flat_centre);
    // A point on the flap, 0.7 mm from its hinge (x = 1 mm): (1 + 0.7 cos 45°, 0, 0.1 + 0.7 sin 45°) mm.
    lifted_lum[k] = luminanceAt(frame.images[0], Eigen::Vector3f(0.0015f, 0.0f, kFocalZ + 0.0006f));
  }
  std::printf("sheen: flat film +%.1f, lifted flap +%.1f grey levels\n", flat_lum[1] - flat_lum[0],
              lifted_lum[1] - lifted_lum[0]);
  EXPECT_LT(flat_lum[1] - flat_lum[0], 3.0) << "the adherent film shows no sheen";
  EXPECT_GT(lifted_lum[1] - lifted_lum[0], 8.0) << "the lifted flap glistens";
}

// ---- Stereo: the disparity of a retina point is the microscope's geometry. ----

TEST(StereoImage, TheDisparityOfARetinaPointMatchesTheMicroscopeGeometry) {
  RenderOptions options;
  options.width = 400;
  options.height = 300;
  options.stereo = true;
  options.dof_pass = false;
  options.bump_mapping = false;
  StereoRenderer renderer(options);
  MicroscopeState microscope;
  microscope.ambient_light = 1.0;
  microscope.focus_distance = 0.196;  // focal plane 4 mm above the posterior pole: the retina has disparity
  renderer.setMicroscope(microscope);
  auto fundus = std::make_shared<const FundusMap>(FundusParams{});
  renderer.setFundus(fundus);
  ObjectStyle retina;
  retina.fundus = true;
  retina.material.specular = Eigen::Vector3f::Zero();
  renderer.setStyle("retina", retina);
  renderer.updateMesh("retina", toMeshData(vrm_sim::scene::makeRetina({kRadius, 90.0, 44})).view(), 1);
  for (const double scale : {1.0, 0.5}) {
    microscope.disparity_scale = scale;
    renderer.setMicroscope(microscope);
    const StereoFrame frame = renderFrame(renderer);
    // The optic disc's centre: a bright, compact feature (the retina's curvature changes the disparity across the
    // disc by less than 0.1 px).
    const Eigen::Vector3f point = fundus->toEye(fundus->discCentre());
    // Thin lens microscope, off-axis frusta meeting at the focal plane s: a point at distance z is seen shifted
    // by b (s / z - 1) between the eyes in the focal plane (b = baseline x disparity scale).
    const MicroscopeRig& rig = renderer.rig();
    const float z = rig.objective.z() - point.z();
    const float s = static_cast<float>(microscope.focus_distance);
    const float px_per_m = options.width * static_cast<float>(microscope.zoom) / rig.field_width;
    const float expected = rig.stereo_baseline * static_cast<float>(scale) * (s / z - 1.0f) * px_per_m;
    // Measured: the centroid of the disc's bright blob in each image (the same detector as for the fundus test).
    auto discCentroid = [&](const RgbImage& eye_image, const Eigen::Vector2f& near) {
      const cv::Mat grey = luminance(eye_image);
      const cv::Rect window(int(near.x()) - 24, int(near.y()) - 24, 48, 48);
      double peak = 0.0;
      cv::minMaxLoc(grey(window), nullptr, &peak);
      Eigen::Vector2d sum(0, 0);
      double weight = 0.0;
      for (int y = window.y; y < window.y + window.height; ++y) {
        for (int x = window.x; x < window.x + window.width; ++x) {
          if (grey.at<std::uint8_t>(y, x) < 0.8 * peak) continue;
          sum += Eigen::Vector2d(x + 0.5, y + 0.5);
          weight += 1.0;
        }
      }
      return Eigen::Vector2f((sum / weight).cast<float>());
    };
    const Eigen::Vector2f left_px = pixelOf(renderer, point, Eye::kLeft);
    const Eigen::Vector2f disparity = discCentroid(frame.images[0], left_px) - discCentroid(frame.images[1], left_px);
    const cv::Point2d shift(disparity.x(), disparity.y());
    std::printf("disparity x%.1f: measured %.2f px, geometry %.2f px\n", scale, shift.x, expected);
    EXPECT_NEAR(shift.x, expected, 1.0) << "disparity scale " << scale;
    EXPECT_NEAR(shift.y, 0.0, 0.5);
  }
}

}  // namespace
}  // namespace vrm_render
