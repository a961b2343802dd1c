// frame_check: checks run.sh's saved snapshots (issue 33 items 3-5) by re-rendering each one's saved state
// (<prefix>.frame beside <prefix>_left.png): first as it was (it must reproduce the saved image: the state is
// complete), then with shadows off and with depth of field off, and measures
//   3. shadow: a region >= 200 px darker by >= 25 % than without shadows, ending within 15 px of the projected tip
//      of the working instrument (slot right: the one that casts the shadow), or of where the light pipe's ray
//      through that tip meets the fundus (a tip held above the retina, or an object it carries, casts its shadow
//      there); not applicable when that point lies outside the light pipe's cone (nothing there is lit);
//   4. focus: the Laplacian variance of the working area (the fundus pixels of the 64 x 64 px around the projected
//      working tip: the working plane; the instruments rising out of it are left out) >= 0.8 x that of the same
//      state rendered without depth of field;
//   5. light: the mean grey of the fundus inside the light pipe's cone (the scoring's rule, litByLightPipe with
//      kLightConeHalfAngleDeg) >= 90 and >= 2 x the mean over the fundus in the field outside it.
// 3 and 5 apply where the scene has a light pipe (lit or not); a scene without one (bimanual) is lit by the
// microscope only and has no shadow cue.
// One line per frame, then a JSON summary. Exit 0: all pass; 1: a check failed; 2: bad input (no frames, a bad file).
// ROS-free (no roscore needed).

#include "vrm_render/frame_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "vrm_render/image_io.h"
#include "vrm_render/render_state.h"
#include "vrm_render/stereo_renderer.h"
#include "vrm_sim/scenario/light_cone.h"

namespace fs = std::filesystem;
using namespace vrm_render;

namespace {

constexpr const char* kWorkingInstrument = "instrument_right";
constexpr double kMinReproductionPsnr = 35.0;  // dB against the saved PNG (same renderer: normally identical)
constexpr double kMinFocusRatio = 0.8;

struct FrameResult {
  std::string prefix;
  double psnr = 0.0;
  bool reproduced = false;
  bool tip_in_view = false;
  Eigen::Vector2f tip = Eigen::Vector2f::Zero();
  ShadowResult shadow;
  double lap_saved = 0.0, lap_no_dof = 0.0, focus_ratio = 0.0;
  bool focus_pass = false;
  ConeResult cone;
  bool light_on = false;
  // The scene has an endoilluminator (a lit light pipe, or a light pipe object: one that is there but dark fails).
  // Without one (bimanual: both hands hold forceps; the coaxial light only) checks 3 and 5 do not apply.
  bool endoillumination = true;
  bool shadow_in_cone = true;       // where the tip's shadow falls is lit (else no shadow can show: check 3 n/a)
  double light_distance_mm = -1.0;  // light pipe tip to the retina along its axis (-1: the axis misses it / off)
  bool pass() const {
    return reproduced && tip_in_view && focus_pass &&
           (!endoillumination || ((shadow.pass || !shadow_in_cone) && cone.pass));
  }
};

std::vector<std::string> framePrefixes(const std::vector<std::string>& args) {
  std::vector<std::string> prefixes;
  for (const std::string& arg : args) {
    if (fs::is_directory(arg)) {
      std::vector<std::string> found;
      for (const auto& entry : fs::directory_iterator(arg)) {
        if (entry.path().extension() == ".frame")
          found.push_back((entry.path().parent_path() / entry.path().stem()).string());
      }
      std::sort(found.begin(), found.end());
      prefixes.insert(prefixes.end(), found.begin(), found.end());
    } else {
      std::string prefix = arg;
      for (const char* suffix : {".frame", "_left.png"}) {
        const std::string s(suffix);
        if (prefix.size() > s.size() && prefix.compare(prefix.size() - s.size(), s.size(), s) == 0)
          prefix.resize(prefix.size() - s.size());
      }
      prefixes.push_back(prefix);
    }
  }
  return prefixes;
}

const RenderState::Object* workingInstrument(const RenderState& state) {
  const RenderState::Object* fallback = nullptr;
  for (const auto& object : state.objects) {
    if (!object.has_mesh || !object.visible || object.style.ghost) continue;
    if (object.id == kWorkingInstrument) return &object;
    if (object.style.casts_shadow && !fallback) fallback = &object;
  }
  return fallback;
}

FrameResult check(StereoRenderer* renderer, const std::string& prefix, const RenderState& state,
                  const std::string& dump, bool same_fundus) {
  FrameResult r;
  r.prefix = prefix;
  const RgbImage saved = loadPng(prefix + "_left.png");
  renderer->restoreState(state, same_fundus);
  StereoFrame frame;
  renderer->render(&frame);
  if (frame.images[0].width != saved.width || frame.images[0].height != saved.height) {
    throw RenderStateError(prefix + ": saved PNG is " + std::to_string(saved.width) + "x" +
                           std::to_string(saved.height) + ", the state renders " +
                           std::to_string(frame.images[0].width) + "x" + std::to_string(frame.images[0].height));
  }
  r.psnr = psnr(saved, frame.images[0]);
  r.reproduced = r.psnr >= kMinReproductionPsnr;
  std::vector<float> depth;
  renderer->readDepth(Eye::kLeft, &depth);
  const CameraView camera = renderer->camera(Eye::kLeft);

  const RenderState::Object* tool = workingInstrument(state);
  if (tool) {
    r.tip_in_view = projectToPixel(camera, tool->pose.translation(), &r.tip) && r.tip.x() >= 0 && r.tip.y() >= 0 &&
                    r.tip.x() < saved.width && r.tip.y() < saved.height;
  }
  // Item 5 on the saved image, classes from the reproduced frame's depth.
  Eigen::Vector3f eye_centre = Eigen::Vector3f::Zero();
  for (const auto& object : state.objects) {
    if (object.style.fundus && object.has_mesh) eye_centre = object.pose.translation();
  }
  const float radius = state.has_fundus ? state.fundus.eye_radius : FundusParams().eye_radius;
  r.light_on = state.light.enabled && state.options.lighting;
  // A light pipe is the instrument that casts no shadow (scene_setup: every other instrument type does).
  r.endoillumination =
      r.light_on || std::any_of(state.objects.begin(), state.objects.end(), [](const auto& object) {
        return object.id.rfind("instrument_", 0) == 0 && !object.style.ghost && !object.style.casts_shadow;
      });
  if (r.light_on) {  // the axis ray from inside the sphere: the far root of |tip + t d - c| = R
    const Eigen::Vector3f d = state.light.direction.normalized(), o = state.light.tip - eye_centre;
    const float b = o.dot(d), c = o.squaredNorm() - radius * radius, disc = b * b - c;
    if (disc >= 0.0f && -b + std::sqrt(disc) > 0.0f) r.light_distance_mm = 1000.0 * (-b + std::sqrt(disc));
  }
  const auto classes = classifyFundus(depth, camera, eye_centre, radius, r.light_on, state.light.tip,
                                      state.light.direction, vrm_sim::scenario::kLightConeHalfAngleDeg);
  r.cone = coneLighting(saved, classes);

  RenderOptions options = state.options;
  options.shadow_pass = false;
  renderer->setOptions(options);
  StereoFrame no_shadow;
  renderer->render(&no_shadow);
  if (r.tip_in_view) {
    r.shadow = findShadow(saved, no_shadow.images[0], r.tip);
    if (!r.shadow.pass && r.light_on && tool != nullptr) {
      // Where the tip's shadow falls: the ray from the light pipe through the tip, on to the eye sphere. Outside the
      // cone nothing is lit, so there is no shadow to see (a tip on its way in, high in the vitreous).
      const Eigen::Vector3f tip = tool->pose.translation();
      const Eigen::Vector3f d = (tip - state.light.tip).normalized(), o = tip - eye_centre;
      const float b = o.dot(d), c = o.squaredNorm() - radius * radius, disc = b * b - c;
      Eigen::Vector2f cast_px;
      if (disc >= 0.0f) {
        const Eigen::Vector3f cast = tip + (-b + std::sqrt(disc)) * d;
        r.shadow_in_cone = vrm_sim::scenario::litByLightPipe(
            state.light.tip.cast<double>(), state.light.direction.cast<double>(), cast.cast<double>(),
            vrm_sim::scenario::lightConeCos(vrm_sim::scenario::kLightConeHalfAngleDeg));
        if (projectToPixel(camera, cast, &cast_px)) {
          const ShadowResult at_cast = findShadow(saved, no_shadow.images[0], cast_px);
          if (at_cast.pass) r.shadow = at_cast;
        }
      }
    }
  }

  options = state.options;
  options.dof_pass = false;
  renderer->setOptions(options);
  StereoFrame no_dof;
  renderer->render(&no_dof);
  if (r.tip_in_view) {
    const Window area = workingArea(r.tip, saved.width, saved.height);
    r.lap_saved = laplacianVariance(saved, area, &classes);
    r.lap_no_dof = laplacianVariance(no_dof.images[0], area, &classes);
    r.focus_ratio = r.lap_saved / std::max(1e-9, r.lap_no_dof);
    r.focus_pass = r.focus_ratio >= kMinFocusRatio;
  }
  if (!dump.empty()) {
    const std::string base = (fs::path(dump) / fs::path(prefix).filename()).string();
    savePng(frame.images[0], base + "_rerender.png");
    savePng(no_shadow.images[0], base + "_no_shadow.png");
    savePng(no_dof.images[0], base + "_no_dof.png");
    RgbImage mask = saved;
    for (std::size_t i = 0; i < classes.size(); ++i) {
      if (classes[i] == PixelClass::kFundusInside) mask.data[3 * i + 2] = 255;
      if (classes[i] == PixelClass::kOther) mask.data[3 * i + 1] = 255;
    }
    savePng(mask, base + "_cone.png");
  }
  return r;
}

std::string yes(bool ok) { return ok ? "ok" : "FAIL"; }

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args;
  std::string dump;
  bool same_fundus = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::cout
          << "usage: frame_check [--dump DIR] [--any-fundus] DIR_OR_PREFIX...\n"
             "  checks saved snapshots (<prefix>.frame + <prefix>_left.png): the saved state re-renders the\n"
             "  image; shadow of the working tip; focus of the working area; the light pipe's cone lights the\n"
             "  fundus. --dump writes the re-renderings and the cone mask (blue: in the cone, green: not fundus).\n"
             "  --any-fundus: restore frames saved before the fundus generator changed with today's fundus (the\n"
             "  reproduction then differs). Exit 0 all pass, 1 a check failed, 2 bad input.\n";
      return 0;
    }
    if (a == "--any-fundus") {  // development: frames saved before a change of the fundus generator
      same_fundus = false;
      continue;
    }
    if (a == "--dump" && i + 1 < argc) {
      dump = argv[++i];
      fs::create_directories(dump);
      continue;
    }
    args.push_back(a);
  }
  const std::vector<std::string> prefixes = framePrefixes(args);
  if (prefixes.empty()) {
    std::cerr << "frame_check: no saved frames (<prefix>.frame) in " << (args.empty() ? "(no arguments)" : args[0])
              << "\n";
    return 2;
  }
  std::vector<FrameResult> results;
  try {
    std::unique_ptr<StereoRenderer> renderer;
    for (const std::string& prefix : prefixes) {
      const RenderState state = readRenderState(prefix + ".frame");
      if (!renderer) renderer = std::make_unique<StereoRenderer>(state.options, state.rig);
      const FrameResult r = check(renderer.get(), prefix, state, dump, same_fundus);
      char line[900];
      std::snprintf(line, sizeof(line),
                    "frame_check %s (focus %.3f m, zoom %.2f, ambient %.2f, light pipe %.1f mm from the fundus): "
                    "reproduced %.1f dB %s | tip (%.0f, %.0f)%s | shadow %d px, %.0f %% darker, "
                    "%.1f px from tip %s%s | focus lap %.1f / %.1f no-DOF = %.2f %s | cone%s grey %.1f (%d px) vs "
                    "outside %.1f (%d px) = %.2fx, %d px saturated %s",
                    fs::path(prefix).filename().c_str(), state.microscope.focus_distance, state.microscope.zoom,
                    state.microscope.ambient_light, r.light_distance_mm, r.psnr, yes(r.reproduced).c_str(), r.tip.x(),
                    r.tip.y(), r.tip_in_view ? "" : " NOT IN VIEW", r.shadow.region_px, 100.0 * r.shadow.darkening,
                    r.shadow.distance_px, yes(r.shadow.pass).c_str(),
                    r.shadow_in_cone ? "" : " (the tip's shadow falls outside the cone: n/a)", r.lap_saved,
                    r.lap_no_dof, r.focus_ratio, yes(r.focus_pass).c_str(),
                    !r.endoillumination ? " (no light pipe in the scene: n/a)"
                    : r.light_on        ? ""
                                        : " (light pipe off)",
                    r.cone.inside_grey, r.cone.inside_px, r.cone.outside_grey, r.cone.outside_px, r.cone.ratio,
                    r.cone.saturated_px, yes(r.cone.pass).c_str());
      std::cout << line << std::endl;
      results.push_back(r);
    }
  } catch (const std::exception& e) {
    std::cerr << "frame_check: " << e.what() << "\n";
    return 2;
  }
  bool all = true;
  std::ostringstream json;
  json << "{\"frames\": [";
  for (std::size_t i = 0; i < results.size(); ++i) {
    const FrameResult& r = results[i];
    all = all && r.pass();
    char entry[900];
    std::snprintf(entry, sizeof(entry),
                  "%s{\"prefix\": \"%s\", \"pass\": %s, \"reproduction_psnr_db\": %.2f, \"tip_px\": [%.1f, %.1f], "
                  "\"tip_in_view\": %s, \"shadow\": {\"region_px\": %d, \"darkening\": %.3f, \"distance_px\": %.1f, "
                  "\"in_cone\": %s, \"pass\": %s}, \"focus\": {\"laplacian_var\": %.2f, \"laplacian_var_no_dof\": "
                  "%.2f, \"ratio\": "
                  "%.3f, \"pass\": %s}, \"cone\": {\"endoillumination\": %s, \"light_on\": %s, \"inside_grey\": %.2f, "
                  "\"inside_px\": %d, "
                  "\"outside_grey\": %.2f, \"outside_px\": %d, \"ratio\": %.3f, \"saturated_px\": %d, \"pass\": %s}}",
                  i ? ", " : "", r.prefix.c_str(), r.pass() ? "true" : "false", std::isfinite(r.psnr) ? r.psnr : 999.0,
                  r.tip.x(), r.tip.y(), r.tip_in_view ? "true" : "false", r.shadow.region_px, r.shadow.darkening,
                  r.shadow.distance_px, r.shadow_in_cone ? "true" : "false", r.shadow.pass ? "true" : "false",
                  r.lap_saved, r.lap_no_dof, r.focus_ratio, r.focus_pass ? "true" : "false",
                  r.endoillumination ? "true" : "false", r.light_on ? "true" : "false", r.cone.inside_grey,
                  r.cone.inside_px, r.cone.outside_grey, r.cone.outside_px, r.cone.ratio, r.cone.saturated_px,
                  r.cone.pass ? "true" : "false");
    json << entry;
  }
  json << "], \"pass\": " << (all ? "true" : "false") << "}";
  std::cout << json.str() << std::endl;
  return all ? 0 : 1;
}
