// Issue 33 part 2: one fundus an ophthalmologist recognises. Checked on the vessel map (FundusMap::vessels()) and on
// rendered frames (StereoRenderer, offscreen): the disc where the scene's optic_disc object is, and only there; four
// arcade trunks leaving the disc, the temporal ones arching around the macula ~3 mm from the fovea and branching;
// arteries thinner ([Knudtson] AVR 0.60-0.75) and lighter than veins; trunks as straight as a healthy retina's
// ([Hart] arc / chord over 2 mm chords); the disc yellow-white with a pale cup and the brightest fundus structure
// under the light pipe; a darker macula with a foveal reflex. Sources: vrm_render/fundus.h.
//
// Rendered-frame vessel analysis: a multi-scale Hessian ridge filter of the green channel (blood absorbs green: the
// red-free view), thresholded and thinned to a skeleton (Zhang-Suen); widths are measured across the map's trunks
// as the full width at half depth of the green profile.
//
// VRM_RENDER_SAVE_ANATOMY=1 writes the frames and the skeleton to /tmp/fundus_anatomy_*.png.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "vrm_render/fundus.h"
#include "vrm_render/image_io.h"
#include "vrm_render/scene_setup.h"
#include "vrm_render/stereo_renderer.h"
#include "vrm_scene/meshes/eye_meshes.h"
#include "vrm_scene/scene_loader.h"

namespace vrm_render {
namespace {

namespace scene = vrm_sim::scene;
constexpr float kMm = 1e-3f;

bool saving() { return std::getenv("VRM_RENDER_SAVE_ANATOMY") != nullptr; }

// ---- The vessel map. ----

// An arcade's trunk (generation 0) of one kind, in growth order: the centre line from the disc and its radii.
struct Trunk {
  std::vector<Eigen::Vector2f> points;
  std::vector<float> radii;
  std::vector<int> segments;  // indices into vessels()
};

Trunk trunkOf(const FundusMap& map, int arcade, bool artery) {
  Trunk t;
  const auto& v = map.vessels();
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (v[i].arcade != arcade || v[i].artery != artery || v[i].generation != 0) continue;
    if (t.points.empty()) {
      t.points.push_back(v[i].a);
      t.radii.push_back(v[i].radius_a);
    } else if ((t.points.back() - v[i].a).norm() > 1e-7f) {
      break;  // the trunk is one chain of consecutive segments
    }
    t.points.push_back(v[i].b);
    t.radii.push_back(v[i].radius_b);
    t.segments.push_back(static_cast<int>(i));
  }
  return t;
}

float length(const std::vector<Eigen::Vector2f>& line) {
  float s = 0.0f;
  for (std::size_t i = 1; i < line.size(); ++i) s += (line[i] - line[i - 1]).norm();
  return s;
}

// Arc / chord of every `chord` along the line (start points every 0.1 mm of arc), from where the line leaves the
// circle `outside` about `centre` (tortuosity is graded outside the disc).
std::vector<float> arcChordRatios(const std::vector<Eigen::Vector2f>& line, float chord, const Eigen::Vector2f& centre,
                                  float outside) {
  std::vector<float> arc(line.size(), 0.0f);
  for (std::size_t i = 1; i < line.size(); ++i) arc[i] = arc[i - 1] + (line[i] - line[i - 1]).norm();
  std::vector<float> ratios;
  float next_start = 0.0f;
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (arc[i] < next_start || (line[i] - centre).norm() < outside) continue;
    next_start = arc[i] + 0.1f * kMm;
    for (std::size_t j = i + 1; j < line.size(); ++j) {
      const float c = (line[j] - line[i]).norm();
      if (c >= chord) {
        ratios.push_back((arc[j] - arc[i]) / c);
        break;
      }
    }
  }
  return ratios;
}

// Where the vessels cross the circle of `radius` about the disc centre: the calibre (diameter) there and the kind.
struct Crossing {
  float diameter;
  bool artery;
  int segment;
};

std::vector<Crossing> crossings(const FundusMap& map, float radius) {
  std::vector<Crossing> out;
  const Eigen::Vector2f c = map.discCentre();
  const auto& v = map.vessels();
  for (std::size_t i = 0; i < v.size(); ++i) {
    const float ra = (v[i].a - c).norm(), rb = (v[i].b - c).norm();
    if ((ra - radius) * (rb - radius) > 0.0f || ra == rb) continue;
    const float t = (radius - ra) / (rb - ra);
    out.push_back({2.0f * (v[i].radius_a + t * (v[i].radius_b - v[i].radius_a)), v[i].artery, static_cast<int>(i)});
  }
  return out;
}

// [Knudtson] revised formulas: the six largest calibres, paired largest with smallest (an odd middle one carried
// over), each pair combined as k * sqrt(w1^2 + w2^2) (k 0.88 arterioles, 0.95 venules), until one remains.
float knudtson(std::vector<float> widths, float k) {
  std::sort(widths.begin(), widths.end(), std::greater<float>());
  if (widths.size() > 6) widths.resize(6);
  while (widths.size() > 1) {
    std::sort(widths.begin(), widths.end());
    std::vector<float> next;
    std::size_t lo = 0, hi = widths.size() - 1;
    while (lo < hi) next.push_back(k * std::hypot(widths[lo++], widths[hi--]));
    if (lo == hi) next.push_back(widths[lo]);
    widths = next;
  }
  return widths.empty() ? 0.0f : widths.front();
}

struct Calibres {
  float crae = 0.0f, crve = 0.0f, paired = 0.0f;  // paired: mean artery / vein trunk calibre over the arcades
};

// In the middle of [Knudtson]'s zone: 0.75 disc diameters from the disc margin.
Calibres calibres(const FundusMap& map) {
  const float disc_r = 0.5f * map.params().disc_diameter;
  const float zone = disc_r + 1.5f * disc_r;
  const std::vector<Crossing> all = crossings(map, zone);
  std::vector<float> arteries, veins;
  for (const Crossing& x : all) (x.artery ? arteries : veins).push_back(x.diameter);
  Calibres c;
  c.crae = knudtson(arteries, 0.88f);
  c.crve = knudtson(veins, 0.95f);
  float sum = 0.0f;
  for (int arcade = 0; arcade < 4; ++arcade) {
    float w[2] = {0.0f, 0.0f};
    for (int kind = 0; kind < 2; ++kind) {
      const Trunk t = trunkOf(map, arcade, kind == 1);
      for (std::size_t i = 1; i < t.points.size() && w[kind] == 0.0f; ++i) {
        if ((t.points[i] - map.discCentre()).norm() >= zone) w[kind] = 2.0f * t.radii[i];
      }
    }
    sum += w[1] / w[0];
  }
  c.paired = sum / 4.0f;
  return c;
}

scene::SceneDescription shipped(const std::string& name) { return scene::loadScene(name); }

TEST(FundusFromScene, TheDiscIsTheScenesOpticDiscAndItsMeshIsNotDrawnAgain) {
  const scene::SceneDescription peeling = shipped("membrane_peeling");
  const scene::ObjectDescription* disc = opticDisc(peeling);
  ASSERT_NE(disc, nullptr);
  const FundusMap map(fundusParams(peeling));
  const Eigen::Vector3f xyz = disc->pose.xyz.cast<float>();
  const Eigen::Vector2f expected = fundusCoordinates(xyz, static_cast<float>(peeling.eye.radius));
  EXPECT_LT((map.discCentre() - expected).norm(), 1e-6f) << map.discCentre().transpose();
  EXPECT_GT(map.discCentre().x(), 0.0f) << "the scene's disc lies towards +x: nasal sign +1";
  EXPECT_NEAR(map.params().disc_diameter, 2.0 * std::get<scene::DiscParams>(*disc->mesh.generator).radius, 1e-7);
  // The disc's own pixel position: the object's position and the fundus map's disc project to the same point.
  // (The scene puts the mesh 50 µm inside the sphere; its direction from the eye centre is what places it.)
  EXPECT_LT((map.toEye(map.discCentre()) - xyz * (peeling.eye.radius / xyz.norm())).norm(), 0.002f * kMm);
  std::printf("membrane_peeling: disc at (%.2f, %.2f) mm from the fovea, %.2f mm across\n", map.discCentre().x() / kMm,
              map.discCentre().y() / kMm, map.params().disc_diameter / kMm);
  for (const auto& object : sceneContent(peeling).objects) EXPECT_NE(object.drawn.id, kOpticDiscName);

  // A scene without one keeps the anatomical default.
  const scene::SceneDescription ilm = shipped("ilm_peeling");
  EXPECT_EQ(opticDisc(ilm), nullptr);
  const FundusParams defaults;
  const FundusMap ilm_map(fundusParams(ilm));
  EXPECT_NEAR(ilm_map.discCentre().x(), defaults.disc_fovea_distance, 1e-7f);
  EXPECT_NEAR(ilm_map.params().disc_diameter, defaults.disc_diameter, 1e-7f);

  // A left eye: the disc mirrored to -x puts the fundus's disc there (nasal sign -1).
  scene::SceneDescription mirrored = peeling;
  for (auto& object : mirrored.objects)
    if (object.name == kOpticDiscName) object.pose.xyz.x() *= -1.0;
  EXPECT_EQ(fundusParams(mirrored).nasal_sign, -1.0f);
  EXPECT_LT(FundusMap(fundusParams(mirrored)).discCentre().x(), 0.0f);

  // Bad input gets a clear error: an optic_disc that is not a disc on the retina.
  scene::SceneDescription floating = peeling;
  for (auto& object : floating.objects)
    if (object.name == kOpticDiscName) object.pose.xyz *= 0.5;
  EXPECT_THROW(fundusParams(floating), scene::SceneError);
  scene::SceneDescription sphere = peeling;
  for (auto& object : sphere.objects)
    if (object.name == kOpticDiscName) object.mesh.generator = scene::SphereParams{};
  EXPECT_THROW(fundusParams(sphere), scene::SceneError);
}

// The anatomy on the map, for the default fundus, the membrane_peeling fundus and other seeds.
std::vector<FundusParams> mapCases() {
  std::vector<FundusParams> cases{FundusParams{}, fundusParams(shipped("membrane_peeling"))};
  for (std::uint32_t seed : {7u, 12345u, 99u}) {
    FundusParams p = cases[1];
    p.seed = seed;
    cases.push_back(p);
  }
  if (const char* seed = std::getenv("VRM_RENDER_FUNDUS_SEED")) {
    for (FundusParams& p : cases) p.seed = static_cast<std::uint32_t>(std::atoi(seed));
  }
  return cases;
}

TEST(FundusMapAnatomy, FourArcadesLeaveTheDiscArchAroundTheMaculaAndBranch) {
  for (const FundusParams& params : mapCases()) {
    const FundusMap map(params);
    const float disc_r = 0.5f * params.disc_diameter;
    SCOPED_TRACE("seed " + std::to_string(params.seed) + ", disc " + std::to_string(map.discCentre().x() / kMm));
    for (int arcade = 0; arcade < 4; ++arcade) {
      for (bool artery : {false, true}) {
        const Trunk t = trunkOf(map, arcade, artery);
        ASSERT_GE(t.points.size(), 2u) << "arcade " << arcade << (artery ? " artery" : " vein");
        EXPECT_LT((t.points.front() - map.discCentre()).norm(), 0.5f * disc_r) << "leaves the disc (its cup)";
        EXPECT_GT(length(t.points), 8.0f * kMm) << "arcade " << arcade;
        // Superior arcades run up, inferior ones down; nasal ones towards the nasal side, temporal ones around the
        // macula to the temporal side.
        const Eigen::Vector2f end = t.points.back();
        const float up = arcade % 2 == 0 ? 1.0f : -1.0f;
        const float nasal = params.nasal_sign * (end.x() - map.discCentre().x());
        if (arcade < 2) {
          EXPECT_GT(up * end.y(), 1.2f * kMm) << "temporal arcade " << arcade << " stays on its side of the raphe";
          EXPECT_LT(params.nasal_sign * end.x(), -5.0f * kMm) << "temporal arcade " << arcade << " runs temporally";
          // Over / under the macula: where it crosses the fovea's vertical meridian, ~3 mm from the fovea, and it
          // keeps out of the macula all along.
          float meridian = 0.0f, closest = 1.0f;
          for (std::size_t i = 1; i < t.points.size(); ++i) {
            closest = std::min(closest, t.points[i].norm());
            if (t.points[i - 1].x() * t.points[i].x() <= 0.0f && meridian == 0.0f) meridian = t.points[i].y();
          }
          EXPECT_GT(std::abs(meridian), 2.4f * kMm) << "arcade " << arcade;
          EXPECT_LT(std::abs(meridian), 3.6f * kMm) << "arcade " << arcade;
          EXPECT_GT(closest, 2.2f * kMm) << "arcade " << arcade << " enters the macula";
        } else {
          EXPECT_GT(nasal, 3.0f * kMm) << "nasal arcade " << arcade;
          EXPECT_GT(up * (end.y() - map.discCentre().y()), 3.0f * kMm) << "nasal arcade " << arcade;
        }
        // Branches: generation-1 vessels of this arcade and kind that start on the trunk.
        int branches = 0;
        for (const VesselSegment& s : map.vessels()) {
          if (s.arcade != arcade || s.artery != artery || s.generation != 1) continue;
          for (const Eigen::Vector2f& p : t.points) {
            if ((s.a - p).norm() < 1e-7f) {
              ++branches;
              break;
            }
          }
        }
        EXPECT_GE(branches, 3) << "arcade " << arcade << (artery ? " artery" : " vein") << " branches";
      }
    }
  }
}

TEST(FundusMapAnatomy, ArteriesAreThinnerThanVeinsByAHealthyAvRatio) {
  for (const FundusParams& params : mapCases()) {
    const FundusMap map(params);
    const Calibres c = calibres(map);
    std::printf("seed %u: CRAE %.0f um, CRVE %.0f um, AVR %.3f ([Knudtson]); paired trunks %.3f\n", params.seed,
                c.crae * 1e6f, c.crve * 1e6f, c.crae / c.crve, c.paired);
    EXPECT_GE(c.crae / c.crve, 0.60f) << "seed " << params.seed;
    EXPECT_LE(c.crae / c.crve, 0.75f) << "seed " << params.seed;
    EXPECT_GE(c.paired, 0.60f);
    EXPECT_LE(c.paired, 0.75f);
    EXPECT_GT(c.crve, 0.15f * kMm) << "[Jonas]/[Knudtson]: CRVE ~200 um in normal eyes";
    EXPECT_LT(c.crve, 0.30f * kMm);
  }
}

TEST(FundusMapAnatomy, ArcadeTrunksAreAsStraightAsAHealthyRetinasOverTwoMillimetreChords) {
  for (const FundusParams& params : mapCases()) {
    const FundusMap map(params);
    std::string line = "seed " + std::to_string(params.seed) + " arc/chord (2 mm) mean/max:";
    for (int arcade = 0; arcade < 4; ++arcade) {
      for (bool artery : {false, true}) {
        const std::vector<float> r = arcChordRatios(trunkOf(map, arcade, artery).points, 2.0f * kMm, map.discCentre(),
                                                    0.5f * params.disc_diameter);
        ASSERT_GE(r.size(), 20u);
        const float mean = std::accumulate(r.begin(), r.end(), 0.0f) / r.size();
        const float max = *std::max_element(r.begin(), r.end());
        char buffer[64];
        std::snprintf(buffer, sizeof(buffer), " %c%d %.3f/%.3f", artery ? 'A' : 'V', arcade, mean, max);
        line += buffer;
        // fundus.h [Hart]: healthy trunks a few % longer than their chords, not ruler-straight, never kinked.
        EXPECT_GE(mean, 1.005f) << "arcade " << arcade << (artery ? " artery" : " vein") << ": ruler-straight";
        EXPECT_LE(mean, 1.08f) << "arcade " << arcade << (artery ? " artery" : " vein") << ": tortuous";
        // The temporal trunks' bend from vertical to temporal just off the disc reaches ~1.1-1.25 over its 2 mm.
        EXPECT_LE(max, 1.30f) << "arcade " << arcade << (artery ? " artery" : " vein") << ": a kink or loop";
      }
    }
    std::printf("%s\n", line.c_str());
  }
}

// ---- Rendered frames. ----

struct View {
  RenderOptions options;
  StereoRenderer renderer;
  std::shared_ptr<const FundusMap> fundus;
  explicit View(const RenderOptions& o) : options(o), renderer(o) {}
  Eigen::Vector2f px(const Eigen::Vector2f& f) const {
    Eigen::Vector2f p;
    EXPECT_TRUE(projectToPixel(renderer.camera(Eye::kLeft), fundus->toEye(f), &p));
    return p;
  }
  float pxPerM() const { return options.width * renderer.microscope().zoom / renderer.rig().field_width; }
  RgbImage render() {
    StereoFrame frame;
    renderer.render(&frame);
    return frame.images[0];
  }
};

RenderOptions monoOptions() {
  RenderOptions options;
  options.width = 800;
  options.height = 600;
  options.stereo = false;
  options.dof_pass = false;
  options.bump_mapping = false;
  return options;
}

// The bare retina with `params`' fundus (no decoration, no membrane), viewed at `zoom`.
void showRetina(View* view, const FundusParams& params, double zoom, double ambient) {
  MicroscopeState microscope;
  microscope.zoom = zoom;
  microscope.ambient_light = ambient;
  view->renderer.setMicroscope(microscope);
  view->fundus = std::make_shared<const FundusMap>(params);
  view->renderer.setFundus(view->fundus);
  ObjectStyle retina;
  retina.fundus = true;
  retina.material.specular = Eigen::Vector3f::Zero();
  view->renderer.setStyle("retina", retina);
  view->renderer.updateMesh("retina", toMeshData(scene::makeRetina({params.eye_radius, 90.0, 44})).view(), 1);
}

// The endoilluminator through the scene's left trocar, its tip 5 mm from `target` on the retina, aimed at it.
LightPipe lightOn(const scene::SceneDescription& s, const Eigen::Vector3f& target) {
  Eigen::Vector3f trocar(0.0f, 0.0f, 0.0f);
  for (const auto& t : s.eye.trocars)
    if (t.name == "left") trocar = t.position_in_eye.cast<float>();
  const float depth = (target - trocar).norm() - 0.005f;
  return lightPipeAt(instrumentPoseThroughTrocar(trocar, target, depth), endoilluminator());
}

cv::Mat greyOf(const RgbImage& image) {
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.data.data())), grey;
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  return grey;
}

cv::Mat channelOf(const RgbImage& image, int c) {
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.data.data())), out;
  cv::extractChannel(rgb, out, c);
  return out;
}

// Median of `image` (8-bit) over pixels whose fundus position lies in the annulus [r0, r1) about `centre`.
double medianIn(const cv::Mat& image, const View& view, const Eigen::Vector2f& centre, float r0, float r1) {
  const Eigen::Vector2f c = view.px(centre);
  const float s = view.pxPerM();
  std::vector<std::uint8_t> values;
  for (int y = std::max(0, int(c.y() - r1 * s) - 1); y < std::min(image.rows, int(c.y() + r1 * s) + 2); ++y) {
    for (int x = std::max(0, int(c.x() - r1 * s) - 1); x < std::min(image.cols, int(c.x() + r1 * s) + 2); ++x) {
      const float d = (Eigen::Vector2f(x + 0.5f, y + 0.5f) - c).norm() / s;
      if (d >= r0 && d < r1) values.push_back(image.at<std::uint8_t>(y, x));
    }
  }
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

TEST(FundusRendered, MembranePeelingShowsOneDiscWhereTheSceneHasIt) {
  const scene::SceneDescription peeling = shipped("membrane_peeling");
  View view(monoOptions());
  const SceneContent content = sceneContent(peeling);
  showScene(&view.renderer, content);
  // The epiretinal membrane, a whitish film 5 mm across reaching over the disc, glistens under the light pipe by
  // design (test_image_cues: MembraneSheen): hidden here, where discs are counted.
  view.renderer.setVisible("membrane", false);
  view.fundus = content.fundus;
  const Eigen::Vector3f disc_xyz = opticDisc(peeling)->pose.xyz.cast<float>();
  view.renderer.setLightPipe(lightOn(peeling, disc_xyz));
  MicroscopeState microscope;  // zoom 1: the whole posterior pole
  view.renderer.setMicroscope(microscope);
  const RgbImage image = view.render();
  if (saving()) savePng(image, "/tmp/fundus_anatomy_peeling.png");

  // Bright blobs: the luminance with vessels closed away, above half-way from the median to the peak.
  cv::Mat grey = greyOf(image), closed, smooth, labels, stats, centroids;
  cv::morphologyEx(grey, closed, cv::MORPH_CLOSE, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
  cv::GaussianBlur(closed, smooth, cv::Size(0, 0), 1.5);
  double peak = 0.0;
  cv::minMaxLoc(smooth, nullptr, &peak);
  std::vector<std::uint8_t> values(grey.begin<std::uint8_t>(), grey.end<std::uint8_t>());
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  const double median = values[values.size() / 2];
  // (The fundus lit around the disc reaches more than half-way from the median to the peak, the disc the peak.)
  const cv::Mat bright = smooth > median + 0.85 * (peak - median);
  const int n = cv::connectedComponentsWithStats(bright, labels, stats, centroids);
  const float s = view.pxPerM();
  const double disc_area = M_PI * std::pow(0.5 * content.fundus->params().disc_diameter * s, 2.0);
  int blobs = 0;
  Eigen::Vector2f centre(0, 0);
  double area = 0.0;
  for (int k = 1; k < n; ++k) {
    if (stats.at<int>(k, cv::CC_STAT_AREA) < 0.2 * disc_area) continue;
    ++blobs;
    centre = Eigen::Vector2f(centroids.at<double>(k, 0) + 0.5, centroids.at<double>(k, 1) + 0.5);
    area = stats.at<int>(k, cv::CC_STAT_AREA);
  }
  Eigen::Vector2f expected;
  ASSERT_TRUE(projectToPixel(view.renderer.camera(Eye::kLeft), disc_xyz, &expected));
  const double diameter_mm = 2.0 * std::sqrt(area / M_PI) / s / kMm;
  std::printf(
      "membrane_peeling, light on the disc: %d bright blob(s), at (%.1f, %.1f) px (scene's disc %.1f, %.1f), "
      "%.2f mm across (peak %.0f, median %.0f)\n",
      blobs, centre.x(), centre.y(), expected.x(), expected.y(), diameter_mm, peak, median);
  EXPECT_EQ(blobs, 1) << "one optic disc";
  EXPECT_LT((centre - expected).norm() / s, 0.25f * kMm) << "where the scene's optic_disc is";
  EXPECT_GT(diameter_mm, 1.3);
  EXPECT_LT(diameter_mm, 2.2) << "two discs side by side read as one long blob";
}

TEST(FundusRendered, TheDiscIsYellowWhiteWithAPaleCupAndTheBrightestStructureUnderTheLight) {
  const scene::SceneDescription peeling = shipped("membrane_peeling");
  const FundusParams params = fundusParams(peeling);
  View view(monoOptions());
  showRetina(&view, params, 3.0, 0.3);
  const Eigen::Vector2f disc = view.fundus->discCentre();
  view.renderer.setLightPipe(lightOn(peeling, view.fundus->toEye(disc)));
  const RgbImage image = view.render();
  if (saving()) savePng(image, "/tmp/fundus_anatomy_disc.png");
  const cv::Mat grey = greyOf(image);
  const float disc_r = 0.5f * params.disc_diameter;
  const float s = view.pxPerM();

  // The brightest structure: the maximum of the luminance with vessels closed away lies on the disc.
  cv::Mat closed, smooth;
  cv::morphologyEx(grey, closed, cv::MORPH_CLOSE, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(17, 17)));
  cv::GaussianBlur(closed, smooth, cv::Size(0, 0), 2.0);
  cv::Point brightest;
  cv::minMaxLoc(smooth, nullptr, nullptr, nullptr, &brightest);
  const float from_disc = (Eigen::Vector2f(brightest.x + 0.5f, brightest.y + 0.5f) - view.px(disc)).norm() / s;
  const double on_disc = medianIn(grey, view, disc, 0.0f, 0.8f * disc_r);
  const double around = medianIn(grey, view, disc, 1.5f * disc_r, 2.5f * disc_r);
  // Yellow-white: green and blue well up towards red (the fundus around is orange-red).
  const cv::Mat red = channelOf(image, 0), green = channelOf(image, 1), blue = channelOf(image, 2);
  const double disc_g =
      medianIn(green, view, disc, 0.0f, 0.8f * disc_r) / medianIn(red, view, disc, 0.0f, 0.8f * disc_r);
  const double disc_b =
      medianIn(blue, view, disc, 0.0f, 0.8f * disc_r) / medianIn(red, view, disc, 0.0f, 0.8f * disc_r);
  const double around_g = medianIn(green, view, disc, 1.5f * disc_r, 2.5f * disc_r) /
                          medianIn(red, view, disc, 1.5f * disc_r, 2.5f * disc_r);
  // The cup (slightly temporal of the centre) paler than the neuroretinal rim.
  const Eigen::Vector2f cup = disc - Eigen::Vector2f(params.nasal_sign * 0.12f * disc_r, 0.0f);
  const double cup_grey = medianIn(grey, view, cup, 0.0f, 0.5f * params.cup_to_disc * disc_r);
  const double rim_grey = medianIn(grey, view, disc, 0.65f * disc_r, 0.85f * disc_r);
  const double cup_blue = medianIn(blue, view, cup, 0.0f, 0.5f * params.cup_to_disc * disc_r);
  const double rim_blue = medianIn(blue, view, disc, 0.65f * disc_r, 0.85f * disc_r);
  std::printf(
      "disc under the light: brightest point %.2f mm from its centre; disc %.0f vs around %.0f (x%.2f); G/R %.2f "
      "B/R %.2f (around G/R %.2f); cup %.0f (blue %.0f) vs rim %.0f (blue %.0f)\n",
      from_disc / kMm, on_disc, around, on_disc / around, disc_g, disc_b, around_g, cup_grey, cup_blue, rim_grey,
      rim_blue);
  EXPECT_LT(from_disc, disc_r) << "the brightest fundus structure is the disc";
  EXPECT_GT(on_disc / around, 1.5);
  EXPECT_GT(disc_g, 0.7) << "yellow-white";
  EXPECT_GT(disc_b, 0.45);
  EXPECT_LT(around_g, 0.55);
  EXPECT_GT(cup_blue, rim_blue + 8.0) << "a pale cup";
  EXPECT_GE(cup_grey, rim_grey);
}

TEST(FundusRendered, TheMaculaIsDarkerWithAFovealReflex) {
  View view(monoOptions());
  showRetina(&view, fundusParams(shipped("membrane_peeling")), 3.0, 1.0);  // coaxial light only: even illumination
  const RgbImage image = view.render();
  if (saving()) savePng(image, "/tmp/fundus_anatomy_macula.png");
  cv::Mat grey = greyOf(image), smooth;
  cv::GaussianBlur(grey, smooth, cv::Size(0, 0), 1.0);
  const Eigen::Vector2f fovea = view.fundus->fovea();
  const double macula = medianIn(grey, view, fovea, 0.0f, 0.75f * kMm);
  const double surround = medianIn(grey, view, fovea, 2.0f * kMm, 2.8f * kMm);
  const double ring = medianIn(smooth, view, fovea, 0.15f * kMm, 0.35f * kMm);
  const Eigen::Vector2f c = view.px(fovea);
  double reflex = 0.0;
  for (int y = int(c.y()) - 4; y <= int(c.y()) + 4; ++y)
    for (int x = int(c.x()) - 4; x <= int(c.x()) + 4; ++x)
      reflex = std::max<double>(reflex, smooth.at<std::uint8_t>(y, x));
  std::printf("macula %.0f vs surround %.0f (x%.2f); foveal reflex %.0f over the foveola's ring %.0f\n", macula,
              surround, macula / surround, reflex, ring);
  EXPECT_LT(macula, 0.85 * surround) << "a darker macula";
  EXPECT_GT(reflex, ring + 10.0) << "a foveal reflex";
}

// Zhang-Suen thinning of a 0/1 image.
cv::Mat skeletonOf(cv::Mat img) {
  img = img.clone();
  img.setTo(1, img > 0);
  cv::Mat marker;
  bool changed = true;
  while (changed) {
    changed = false;
    for (int pass = 0; pass < 2; ++pass) {
      marker = cv::Mat::zeros(img.size(), CV_8U);
      for (int y = 1; y < img.rows - 1; ++y) {
        for (int x = 1; x < img.cols - 1; ++x) {
          if (!img.at<std::uint8_t>(y, x)) continue;
          const int p2 = img.at<std::uint8_t>(y - 1, x), p3 = img.at<std::uint8_t>(y - 1, x + 1),
                    p4 = img.at<std::uint8_t>(y, x + 1), p5 = img.at<std::uint8_t>(y + 1, x + 1),
                    p6 = img.at<std::uint8_t>(y + 1, x), p7 = img.at<std::uint8_t>(y + 1, x - 1),
                    p8 = img.at<std::uint8_t>(y, x - 1), p9 = img.at<std::uint8_t>(y - 1, x - 1);
          const int b = p2 + p3 + p4 + p5 + p6 + p7 + p8 + p9;
          const int a = (!p2 && p3) + (!p3 && p4) + (!p4 && p5) + (!p5 && p6) + (!p6 && p7) + (!p7 && p8) +
                        (!p8 && p9) + (!p9 && p2);
          const bool m =
              pass == 0 ? (p2 * p4 * p6 == 0 && p4 * p6 * p8 == 0) : (p2 * p4 * p8 == 0 && p2 * p6 * p8 == 0);
          if (b >= 2 && b <= 6 && a == 1 && m) marker.at<std::uint8_t>(y, x) = 1;
        }
      }
      if (cv::countNonZero(marker) > 0) changed = true;
      img &= ~marker;
    }
  }
  return img;
}

// Multi-scale Hessian ridge filter for dark vessels: the largest eigenvalue of the scale-normalised Hessian of the
// green channel (positive across a dark line), maximised over scales.
cv::Mat ridges(const cv::Mat& green) {
  cv::Mat g, response = cv::Mat::zeros(green.size(), CV_32F);
  green.convertTo(g, CV_32F);
  for (const double sigma : {1.5, 2.5, 4.0}) {
    cv::Mat blurred, dxx, dyy, dxy;
    cv::GaussianBlur(g, blurred, cv::Size(0, 0), sigma);
    cv::Sobel(blurred, dxx, CV_32F, 2, 0, 3);
    cv::Sobel(blurred, dyy, CV_32F, 0, 2, 3);
    cv::Sobel(blurred, dxy, CV_32F, 1, 1, 3);
    for (int y = 0; y < g.rows; ++y) {
      for (int x = 0; x < g.cols; ++x) {
        const float a = dxx.at<float>(y, x), b = dyy.at<float>(y, x), c = dxy.at<float>(y, x);
        const float l = 0.5f * (a + b + std::sqrt((a - b) * (a - b) + 4.0f * c * c));
        response.at<float>(y, x) = std::max(response.at<float>(y, x), static_cast<float>(sigma * sigma) * l);
      }
    }
  }
  return response;
}

float bilinear(const cv::Mat& image, float x, float y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= image.cols || y0 + 1 >= image.rows) return NAN;
  const float tx = x - x0, ty = y - y0;
  auto at = [&](int xx, int yy) { return static_cast<float>(image.at<std::uint8_t>(yy, xx)); };
  return (1 - ty) * ((1 - tx) * at(x0, y0) + tx * at(x0 + 1, y0)) +
         ty * ((1 - tx) * at(x0, y0 + 1) + tx * at(x0 + 1, y0 + 1));
}

// Full width at half depth of the dark profile across the vessel at pixel `p` (direction `across`, unit), and the
// mean of `shade` over its core; NaN where the profile leaves the image.
struct Width {
  float px = NAN;
  float core = NAN;
};

Width widthAt(const cv::Mat& green, const cv::Mat& shade, const Eigen::Vector2f& p, const Eigen::Vector2f& across,
              float half_window, float expected_radius) {
  std::vector<float> prof;
  const float step = 0.25f;
  for (float t = -half_window; t <= half_window + 1e-3f; t += step) {
    const float v = bilinear(green, p.x() + t * across.x(), p.y() + t * across.y());
    if (std::isnan(v)) return {};
    prof.push_back(v);
  }
  const std::size_t n = prof.size(), edge = n / 6;
  const float left = std::accumulate(prof.begin(), prof.begin() + edge, 0.0f) / edge;
  const float right = std::accumulate(prof.end() - edge, prof.end(), 0.0f) / edge;
  const float background = 0.5f * (left + right);
  const auto lowest = std::min_element(prof.begin() + edge, prof.end() - edge);
  const float half = 0.5f * (background + *lowest);
  // The outermost samples below half depth within 1.6 expected radii (+2 px) of the centre line: an artery's
  // central light reflex may rise above half depth and must not split its width in two.
  const std::size_t mid = n / 2, reach = static_cast<std::size_t>((1.6f * expected_radius + 2.0f) / step);
  std::size_t lo = n, hi = 0;
  for (std::size_t i = mid > reach ? mid - reach : 1; i < std::min(n - 1, mid + reach + 1); ++i) {
    if (prof[i] >= half) continue;
    lo = std::min(lo, i);
    hi = std::max(hi, i);
  }
  if (lo == n || lo == 0 || hi + 1 >= n) return {};
  // Sub-sample crossings by linear interpolation.
  const float a = (lo - 1) + (half - prof[lo - 1]) / (prof[lo] - prof[lo - 1]);
  const float b = hi + (prof[hi] - half) / (prof[hi] - prof[hi + 1]);
  Width w;
  w.px = (b - a) * step;
  const float centre = 0.5f * (a + b) * step - half_window;
  float sum = 0.0f;
  int count = 0;
  for (float t = -0.25f * w.px; t <= 0.25f * w.px; t += step) {
    sum += bilinear(shade, p.x() + (centre + t) * across.x(), p.y() + (centre + t) * across.y());
    ++count;
  }
  w.core = sum / count;
  return w;
}

TEST(FundusRendered, TheArcadesAreFoundByARidgeFilterWithArteriesThinnerAndLighterThanVeins) {
  const scene::SceneDescription peeling = shipped("membrane_peeling");
  FundusParams params = fundusParams(peeling);
  if (const char* seed = std::getenv("VRM_RENDER_FUNDUS_SEED")) params.seed = std::atoi(seed);
  View view(monoOptions());
  showRetina(&view, params, 2.5, 1.0);  // 67 px/mm: a temporal vein ~9 px, its artery ~7 px across
  const RgbImage image = view.render();
  const cv::Mat green = channelOf(image, 1), grey = greyOf(image);
  const FundusMap& map = *view.fundus;
  const float s = view.pxPerM();
  const float disc_r = 0.5f * params.disc_diameter;

  // Vessel pixels: ridge response above a fifth of its 99.5th percentile over the fundus, small specks removed;
  // then the skeleton.
  const cv::Mat response = ridges(green);
  std::vector<float> values;
  for (int y = 0; y < response.rows; y += 2)
    for (int x = 0; x < response.cols; x += 2) values.push_back(response.at<float>(y, x));
  std::nth_element(values.begin(), values.begin() + values.size() * 995 / 1000, values.end());
  const float threshold = 0.2f * values[values.size() * 995 / 1000];
  cv::Mat vessels = response > threshold, labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(vessels, labels, stats, centroids);
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x)
      if (stats.at<int>(labels.at<int>(y, x), cv::CC_STAT_AREA) < 40) vessels.at<std::uint8_t>(y, x) = 0;
  (void)n;
  const cv::Mat skeleton = skeletonOf(vessels);
  if (saving()) {
    savePng(image, "/tmp/fundus_anatomy_vessels.png");
    RgbImage sk{skeleton.cols, skeleton.rows, {}};
    for (int y = 0; y < skeleton.rows; ++y)
      for (int x = 0; x < skeleton.cols; ++x)
        for (int c = 0; c < 3; ++c)
          sk.data.push_back(skeleton.at<std::uint8_t>(y, x) ? 255 : vessels.at<std::uint8_t>(y, x) ? 80 : 0);
    savePng(sk, "/tmp/fundus_anatomy_skeleton.png");
  }
  // Distance of every pixel to the nearest skeleton pixel.
  cv::Mat not_skeleton = skeleton == 0, distance;
  cv::distanceTransform(not_skeleton, distance, cv::DIST_L2, 3);

  // (1) The skeleton follows each trunk of the map, wherever the trunk is in the frame outside the disc; the same
  // points turned by 0.35 rad about the disc find far less (the check can fail).
  auto inFrame = [&](const Eigen::Vector2f& p) {
    return p.x() > 12 && p.y() > 12 && p.x() < image.width - 12 && p.y() < image.height - 12;
  };
  const Eigen::Rotation2Df turn(0.35f);
  std::string coverage_line;
  for (int arcade = 0; arcade < 4; ++arcade) {
    for (bool artery : {false, true}) {
      const Trunk t = trunkOf(map, arcade, artery);
      int seen = 0, on = 0, control = 0;
      for (const Eigen::Vector2f& f : t.points) {
        if ((f - map.discCentre()).norm() < disc_r + 0.1f * kMm) continue;
        const Eigen::Vector2f p = view.px(f);
        const Eigen::Vector2f q = view.px(map.discCentre() + turn * (f - map.discCentre()));
        if (!inFrame(p) || !inFrame(q)) continue;
        ++seen;
        on += distance.at<float>(int(p.y()), int(p.x())) <= 3.0f ? 1 : 0;
        control += distance.at<float>(int(q.y()), int(q.x())) <= 3.0f ? 1 : 0;
      }
      ASSERT_GE(seen, 8) << "arcade " << arcade << " is not in the frame";
      const float fraction = float(on) / seen, shifted = float(control) / seen;
      char buffer[64];
      std::snprintf(buffer, sizeof(buffer), " %c%d %.2f (%.2f)", artery ? 'A' : 'V', arcade, fraction, shifted);
      coverage_line += buffer;
      EXPECT_GE(fraction, 0.75f) << "arcade " << arcade << (artery ? " artery" : " vein") << " not found on the frame";
      EXPECT_LT(shifted, 0.5f) << "the ridge check finds vessels everywhere";
    }
  }
  std::printf("trunks followed by the skeleton (fraction of their points within 3 px; turned control):%s\n",
              coverage_line.c_str());

  // (2) Widths across each trunk in [Knudtson]'s zone and a little beyond (0.5-2 disc diameters from the margin),
  // where no other vessel is near; arteries against their arcade's vein, compared with the map's calibres there.
  const auto& all = map.vessels();
  float ratio_sum = 0.0f, map_ratio_sum = 0.0f;
  std::vector<float> artery_core, vein_core;
  std::string width_line;
  int measured = 0;
  for (int arcade = 0; arcade < 4; ++arcade) {
    float width[2] = {0, 0}, calibre[2] = {0, 0};
    std::size_t spots[2] = {0, 0};
    for (int kind = 0; kind < 2; ++kind) {
      const Trunk t = trunkOf(map, arcade, kind == 1);
      std::vector<float> widths, radii;
      for (std::size_t i = 1; i + 1 < t.points.size(); ++i) {
        const Eigen::Vector2f f = t.points[i];
        const float from_disc = (f - map.discCentre()).norm();
        if (from_disc < disc_r + disc_r || from_disc > disc_r + 4.0f * disc_r) continue;
        bool clear = true;
        for (std::size_t k = 0; k < all.size() && clear; ++k) {
          if (std::find(t.segments.begin(), t.segments.end(), int(k)) != t.segments.end()) continue;
          const Eigen::Vector2f ab = all[k].b - all[k].a;
          const float u = std::clamp((f - all[k].a).dot(ab) / std::max(ab.squaredNorm(), 1e-20f), 0.0f, 1.0f);
          clear = (f - all[k].a - u * ab).norm() > 2.5f * t.radii[i] + all[k].radius_a + 0.03f * kMm;
        }
        if (!clear) continue;
        const Eigen::Vector2f p = view.px(f);
        const Eigen::Vector2f tangent = (view.px(t.points[i + 1]) - view.px(t.points[i - 1])).normalized();
        const Width w = widthAt(green, grey, p, Eigen::Vector2f(-tangent.y(), tangent.x()), 2.5f * t.radii[i] * s + 3,
                                t.radii[i] * s);
        if (std::isnan(w.px)) continue;
        widths.push_back(w.px);
        radii.push_back(t.radii[i]);
        (kind ? artery_core : vein_core).push_back(w.core);
      }
      spots[kind] = widths.size();
      if (widths.size() < 3) break;  // too few clear spots in the frame
      std::nth_element(widths.begin(), widths.begin() + widths.size() / 2, widths.end());
      width[kind] = widths[widths.size() / 2];
      calibre[kind] = 2.0f * std::accumulate(radii.begin(), radii.end(), 0.0f) / radii.size() * s;
    }
    char buffer[128];
    std::snprintf(buffer, sizeof(buffer), " %d: A %.1f / V %.1f px (map %.1f / %.1f; %zu / %zu spots)", arcade,
                  width[1], width[0], calibre[1], calibre[0], spots[1], spots[0]);
    width_line += buffer;
    if (spots[0] < 3 || spots[1] < 3) continue;
    ++measured;
    EXPECT_LT(width[1], width[0]) << "arcade " << arcade << ": the artery is thinner than its vein";
    ratio_sum += width[1] / width[0];
    map_ratio_sum += calibre[1] / calibre[0];
  }
  ASSERT_GE(measured, 3) << "arcades whose artery and vein could be measured:" << width_line;
  const float ratio = ratio_sum / measured, map_ratio = map_ratio_sum / measured;
  const float mean = [](const std::vector<float>& v) {
    return std::accumulate(v.begin(), v.end(), 0.0f) / v.size();
  }(artery_core);
  const float vein_mean = std::accumulate(vein_core.begin(), vein_core.end(), 0.0f) / vein_core.size();
  std::printf(
      "widths (median, full width at half depth):%s\nartery/vein width ratio: rendered %.3f, map %.3f; core "
      "luminance artery %.0f, vein %.0f\n",
      width_line.c_str(), ratio, map_ratio, mean, vein_mean);
  EXPECT_NEAR(ratio, map_ratio, 0.1f) << "the frame's widths follow the map's calibres";
  EXPECT_GE(ratio, 0.5f);  // (the map's AVR is checked on the map; this is a sanity bound on the measurement)
  EXPECT_LE(ratio, 0.9f);
  EXPECT_GT(mean, vein_mean + 5.0f) << "arteries lighter than veins";
}

}  // namespace
}  // namespace vrm_render
