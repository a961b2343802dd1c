// tracking_eval (issue 5): renders the rig from a surgeon trajectory file, runs detection + reconstruction without a
// master, and prints one JSON object with the accuracy and timing fields of the `tracking` benchmark.
//   tracking_eval --trajectory FILE [--noise-px X] [--occlude CAM] [--seed N] [--frames N] [--tremor-um A]
//                 [--rig FILE] [--layout FILE] [--distractors N] [--filter none|one_euro|alpha_beta]
//                 [--scene NAME|PATH]
// --trajectory: a script in the scene's format (vrm_sim loadScript: a file or a shipped script's name). --scene: the
// scene it plays in (trocars, eye, objects its waypoints are written on) and whose trocars a layout file that leaves
// them to the scene gets (default: the nodelets' default scene, membrane_peeling).
// --noise-px X > 0 evaluates the FPGA path (exact centroids + X px noise) instead of rendered images.
// Exit codes: 0 ok, 2 usage or malformed input (the message names the file, line and field).

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "vrm_scene/cli/cli.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/evaluation.h"
#include "vrm_tracking/scene_trocars.h"

using namespace vrm_tracking;

int main(int argc, char** argv) {
  namespace po = vrm_sim::cli::po;
  std::string trajectory, rig_file, layout_file, filter = "none", scene_spec = vrm_sim::scene::kDefaultSceneName;
  double noise_px = 0.0, tremor_um = -1.0;  // -1: the script's own tremor
  int occlude = -1, frames = 0, distractors = 0;
  std::uint32_t seed = 1;
  vrm_sim::cli::CommandLine cli(
      "tracking_eval",
      "--trajectory FILE [--noise-px X] [--occlude CAM] [--seed N] [--frames N] [--tremor-um A] [--rig FILE] "
      "[--layout FILE] [--distractors N] [--filter none|one_euro|alpha_beta] [--scene NAME|PATH]",
      "Renders the rig from a surgeon trajectory, runs detection and reconstruction, prints one JSON object.",
      "Exit status: 0 ok, 2 usage or malformed input (the message names the file, line and field).");
  cli.add()("trajectory", po::value(&trajectory)->required()->value_name("FILE|NAME"),
            "the script: a file, or a shipped script's name (vrm_sim config/scripts)")(
      "noise-px", vrm_sim::cli::real(&noise_px)->value_name("X"),
      "> 0: the FPGA path (exact centroids + X px noise) instead of rendered images")(
      "occlude", vrm_sim::cli::integer(&occlude)->value_name("CAM"), "hide this camera of the rig (default -1: none)")(
      "seed", vrm_sim::cli::uint32(&seed)->value_name("N"), "centroid noise seed (default 1)")(
      "frames", vrm_sim::cli::integer(&frames)->value_name("N"), "samples at 50 Hz (default 0: the whole script)")(
      "tremor-um", vrm_sim::cli::real(&tremor_um)->value_name("A"),
      "every instrument's tremor amplitude, um (default: the script's own)")(
      "rig", po::value(&rig_file)->value_name("FILE"), "camera rig (default: the built-in rig)")(
      "layout", po::value(&layout_file)->value_name("FILE"), "marker layout (default: the built-in layout)")(
      "distractors", vrm_sim::cli::integer(&distractors)->value_name("N"), "distracting blobs per image (default 0)")(
      "filter", vrm_sim::cli::choice(&filter, {"none", "one_euro", "alpha_beta"})->value_name("NAME"),
      "tracker filter: none, one_euro or alpha_beta (default none)")(
      "scene", po::value(&scene_spec)->value_name("NAME|PATH"),
      "the scene the script plays in: its trocars, eye and objects (default membrane_peeling)");
  if (const auto status = cli.parse(argc, argv)) return *status;
  if (!(noise_px >= 0.0)) return cli.fail("--noise-px expects a non-negative number");
  if (frames < 0) return cli.fail("--frames expects a non-negative number");
  if (tremor_um != -1.0 && !(tremor_um >= 0.0)) return cli.fail("--tremor-um expects a non-negative number");
  if (distractors < 0) return cli.fail("--distractors expects a non-negative number");

  try {
    vrm_sim::usePackageData();  // a scene or script name means vrm_sim's shipped one (found like rosrun finds packages)
    const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(scene_spec);
    SurgeonScript script = playInScene(scene, vrm_sim::scene::loadScript(trajectory));
    MarkerLayout layout = layout_file.empty() ? makeDefaultLayout() : loadLayoutYaml(layout_file);
    if (std::any_of(layout.instruments.begin(), layout.instruments.end(),
                    [](const InstrumentMarker& m) { return m.trocar_from_scene; })) {
      applySceneTrocars(scene, &layout);
    }
    script.setPlayback(Playback::kOnce);
    if (tremor_um >= 0.0) script.setTremorAmplitude(tremor_um * 1e-6);
    const CameraRig rig = rig_file.empty() ? makeDefaultRig() : loadRigYaml(rig_file);
    if (occlude >= static_cast<int>(rig.size())) return cli.fail("--occlude names no camera of the rig");
    // 50 Hz over the script (§7: tracking at <= 50 Hz), or --frames samples.
    const int n = frames > 0 ? frames : std::max(1, static_cast<int>(script.duration() * 50.0) + 1);
    std::vector<double> times;
    for (int f = 0; f < n; ++f) times.push_back(f / 50.0);
    EvalOptions opt;
    opt.rendered = noise_px == 0.0;
    opt.noise_px = noise_px;
    opt.occluded_camera = occlude;
    opt.seed = seed;
    opt.render.distractors = distractors;
    opt.tracker.filter.type = filterTypeFromString(filter);
    // Thread CPU time, as the benchmark: ms on one core, whatever else the machine runs.
    opt.clock = [] {
      timespec ts{};
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
      return ts.tv_sec + 1e-9 * ts.tv_nsec;
    };
    const EvalResult r = evaluate(
        rig, layout, [&](double t) { return script.sample(t); }, times, opt);
    std::printf(
        "{\"suite\": \"tracking\", \"source\": \"%s\", \"trajectory\": \"%s\", \"frames\": %d, \"noise_px\": %g, "
        "\"width\": %d, \"height\": %d, \"occluded_cams\": %d, \"seed\": %d, \"tip_rms_um\": %.4f, "
        "\"tip_max_um\": %.4f, \"tip_eye_rms_um\": %.4f, \"eye_err_deg\": %.6f, \"eye_err_max_deg\": %.6f, "
        "\"detect_rate\": %.6f, \"track_rate\": %.6f, \"ms_detect\": %.4f, \"ms_reconstruct\": %.4f, "
        "\"full_frame_rate\": %.4f, \"ms_render\": %.4f, \"filter\": \"%s\"}\n",
        opt.rendered ? "rendered" : "centroid_noise", trajectory.c_str(), r.frames, noise_px, rig.cameras[0].width,
        rig.cameras[0].height, occlude >= 0 ? 1 : 0, static_cast<int>(seed), r.tip_rms_um, r.tip_max_um,
        r.tip_eye_rms_um, r.eye_err_deg, r.eye_err_max_deg, r.detect_rate, r.track_rate, r.ms_detect, r.ms_reconstruct,
        r.full_frame_rate, r.ms_render, filter.c_str());
  } catch (const std::exception& e) {  // a script's or scene's YamlError names the file, line and field
    std::fprintf(stderr, "tracking_eval: %s\n", e.what());
    return 2;
  }
  return 0;
}
