// Benchmark `render` (issue 6): per-pass and total frame times of the stereo microscope view on the thesis' typical
// scene (§7: 15,000 triangles, 5,000 deformable), stereo 2x800x600 with all passes against mono, lower resolutions
// and passes switched off; triangle throughput for static and streamed geometry; readback cost. Target: all passes
// in stereo <= 33 ms (>= 30 Hz); EyeSi 2003: ~17 ms on a GeForce 4.
//   bench_render [--quick] [--out FILE] [--png DIR] [--case NAME] [--frames N]
//   bench_render --frame PREFIX_OR_DIR [--current-light] [--frames N] [--out FILE]
// --frame (issue 33): a saved snapshot's render state (<prefix>.frame, run.sh's session: that scene, its instruments
// and light pipe, the knobs and options of the running graph) rendered with the light pipe lit, lit without the
// shadow pass, and off, frame by frame in turns (the deformable meshes re-uploaded every frame as the session streams
// them): what the light pipe costs per stereo frame. --current-light: today's endoilluminator() (cone, intensity) at
// the saved light pipe's pose, to compare a change of the light on the same frames. Issue 37: two more variants per
// frame, "laser_off" (the saved frame without its burns and aiming beam) and "burn_every_frame" (a new burn painted,
// uploaded and the static layer redrawn in every frame: the worst case of a trainee firing at the frame rate).

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "vrm_render/image_io.h"
#include "vrm_render/render_state.h"
#include "vrm_render/scene_setup.h"
#include "vrm_render/stereo_renderer.h"

namespace {

using vrm_render::MeshData;
using vrm_render::RenderOptions;
using vrm_render::StereoFrame;
using vrm_render::StereoRenderer;

struct Case {
  std::string name;
  int width;
  int height;
  bool stereo;
  bool shadow;
  bool lighting;
  bool dof;
  bool stream;  // deformable membrane re-uploaded every frame (new version)
  bool time_passes;
  int shadow_map = 512;
  int dof_downsample = 4;
  bool light_partition = true;  // lit shader only for the triangles the spotlight may reach
  bool cache_static = true;     // issue 30: the retina's ambient-only layer kept per eye while it is unchanged
  bool eye_moving = false;      // the worst case of the cache: the eye turns every frame, the layer is redrawn
  bool fundus = true;           // issue 16: the fundus texture on the retina
  bool metal = true;            // issue 16: metallic instruments, glowing light pipe tip, membrane sheen
  // The plain reference frame (issue 16): one shadow pass, two Phong + spotlight eye passes over every triangle (no
  // partition, no fundus, no bump mapping, no metal), a 13-tap separable blur at full resolution per eye.
  bool plain = false;
};

Case plainReference(const std::string& name, int width, int height) {
  Case c{name, width, height, true, true, true, true, true, true, 512, 1, false};
  c.fundus = false;
  c.metal = false;
  c.plain = true;
  return c;
}

struct Row {
  Case c;
  std::size_t triangles = 0;
  double ms_upload = 0, ms_shadow = 0, ms_scene = 0, ms_dof = 0, ms_readback = 0, ms_total = 0, ms_total_min = 0;
  double tris_per_s = 0, streamed_tris_per_s = 0;
  int frames = 0;
  double cpu_ms_per_frame = 0;
};

std::string passesOf(const Case& c) {
  std::vector<std::string> p;
  if (c.shadow) p.push_back("shadow");
  p.push_back(c.plain ? "scene_phong" : c.lighting ? "scene" : "scene_flat");
  if (c.dof) p.push_back(c.plain ? "blur13_full" : "dof");
  std::string s;
  for (const auto& x : p) s += (s.empty() ? "" : "+") + x;
  return s;
}

// CPU time of the whole process (the calling thread and llvmpipe's rasterizer threads), in ms. On a shared,
// loaded machine wall-clock frame times inflate; CPU time per frame does not, and on an idle machine with N
// rasterizer threads the frame time is bounded below by roughly cpu_ms / N.
double processCpuMs() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return (usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) * 1e3 +
         (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) * 1e-3;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

RenderOptions optionsOf(const Case& c) {
  RenderOptions options;
  options.width = c.width;
  options.height = c.height;
  options.stereo = c.stereo;
  options.shadow_pass = c.shadow;
  options.lighting = c.lighting;
  options.dof_pass = c.dof;
  options.time_passes = c.time_passes;
  options.shadow_map_size = c.shadow_map;
  options.dof_downsample = c.dof_downsample;
  options.light_partition = c.light_partition;
  options.cache_static = c.cache_static;
  options.fundus = c.fundus;
  if (c.plain) {
    options.bump_mapping = false;
    options.dof_taps = 13;
  }
  return options;
}

// One case's renderer with the typical scene, warmed up; render(i) streams the membrane (if the case does) and
// renders.
struct Setup {
  Case c;
  StereoRenderer renderer;
  std::vector<vrm_render::SceneObject> scene;
  MeshData* membrane = nullptr;
  std::size_t streamed_triangles = 0;
  std::vector<float> base;
  StereoFrame frame;

  explicit Setup(const Case& c_in) : c(c_in), renderer(optionsOf(c_in)) {
    vrm_render::LightPipe light;
    scene = vrm_render::typicalScene(&light);
    for (auto& object : scene) {
      if (!c.metal) {
        object.style.material.metallic = 0.0f;
        object.style.material.glow_tip_length = 0.0f;
        object.style.material.sheen = 0.0f;
      }
      renderer.setStyle(object.id, object.style);
      renderer.setPose(object.id, object.pose);
      renderer.updateMesh(object.id, object.mesh.view(), 1);
      if (object.style.deformable) {
        membrane = &object.mesh;
        streamed_triangles = object.mesh.triangles.size() / 3;
      }
    }
    renderer.setLightPipe(light);
    // The default focus (0.2 m): the posterior pole sharp, the instruments above it blurred by the circle of
    // confusion.
    renderer.setMicroscope(vrm_render::MicroscopeState{});
    renderer.render(&frame);  // warm-up (shader compilation by llvmpipe happens on first use)
    base = membrane ? membrane->positions : std::vector<float>();
  }

  const vrm_render::PassTimings& render(int i) {
    if (c.stream && membrane) {
      // The tissue simulation moves the membrane every frame (§5): a small wave keeps the data changing.
      for (std::size_t v = 0; v < base.size() / 3; ++v) {
        membrane->positions[3 * v + 2] = base[3 * v + 2] + 5e-5f * std::sin(0.3f * i + 2000.0f * base[3 * v]);
      }
      renderer.updateMesh("membrane", membrane->view(), 2 + i);
    }
    if (c.eye_moving) {
      // The eye turns (± 0.6 deg about x, alternating): everything in the eye frame moves; here the retina, whose
      // static layer must then be redrawn every frame.
      for (const auto& object : scene) {
        if (object.id != "retina") continue;
        const float angle = (i % 2 ? 1.0f : -1.0f) * 0.01f;
        renderer.setPose(object.id,
                         Eigen::Isometry3f(Eigen::AngleAxisf(angle, Eigen::Vector3f::UnitX())) * object.pose);
      }
    }
    renderer.render(&frame);
    return frame.timings;
  }
};

// The cost of `c` against the plain reference measured frame by frame in turns (plain, c, plain, c, ...): on a
// shared machine the load drifts within a run, and alternating exposes both to the same drift. Median of the
// per-pair ratios of the total frame times.
double pairedRatio(const Case& plain, const Case& c, int frames) {
  Setup a(plain), b(c);
  std::vector<double> ratios;
  for (int i = 0; i < frames; ++i) {
    const double ta = a.render(i).ms_total;
    const double tb = b.render(i).ms_total;
    if (ta > 0.0) ratios.push_back(tb / ta);
  }
  return median(ratios);
}

// What an element costs: the full case `all` against the case without it (`without`), frame by frame in turns,
// median of the per-pair differences of the total frame time (ms).
double pairedCost(const Case& all, const Case& without, int frames) {
  Setup a(all), b(without);
  std::vector<double> differences;
  for (int i = 0; i < frames; ++i) {
    const double ta = a.render(i).ms_total;
    differences.push_back(ta - b.render(i).ms_total);
  }
  return median(differences);
}

Row run(const Case& c, int frames, const std::string& png_dir) {
  Setup setup(c);
  StereoRenderer& renderer = setup.renderer;
  StereoFrame& frame = setup.frame;
  const std::size_t streamed_triangles = setup.streamed_triangles;
  std::vector<double> upload, shadow, scene_ms, dof, readback, total;
  const double cpu_start = processCpuMs();
  for (int i = 0; i < frames; ++i) {
    const auto& t = setup.render(i);
    upload.push_back(t.ms_upload);
    shadow.push_back(t.ms_shadow);
    scene_ms.push_back(t.ms_scene);
    dof.push_back(t.ms_dof);
    readback.push_back(t.ms_readback);
    total.push_back(t.ms_total);
  }
  Row row;
  row.cpu_ms_per_frame = (processCpuMs() - cpu_start) / frames;
  row.c = c;
  row.frames = frames;
  row.triangles = renderer.triangleCount();
  row.ms_upload = median(upload);
  row.ms_shadow = median(shadow);
  row.ms_scene = median(scene_ms);
  row.ms_dof = median(dof);
  row.ms_readback = median(readback);
  row.ms_total = median(total);
  row.ms_total_min = *std::min_element(total.begin(), total.end());
  const double eyes = c.stereo ? 2.0 : 1.0;
  row.tris_per_s = row.ms_total > 0 ? row.triangles * eyes / (row.ms_total * 1e-3) : 0.0;
  row.streamed_tris_per_s = c.stream && row.ms_upload > 0 ? streamed_triangles / (row.ms_upload * 1e-3) : 0.0;
  if (!png_dir.empty()) {
    vrm_render::savePng(frame.images[0], png_dir + "/" + c.name + "_left.png");
    if (c.stereo) vrm_render::savePng(frame.images[1], png_dir + "/" + c.name + "_right.png");
  }
  return row;
}

// --frame: the light pipe's cost on saved session frames (see the header).
int benchSavedFrames(const std::vector<std::string>& args, int frames, const std::string& out,
                     const std::string& command, bool current_light) {
  std::vector<std::string> prefixes;
  for (const std::string& arg : args) {
    if (std::filesystem::is_directory(arg)) {
      for (const auto& entry : std::filesystem::directory_iterator(arg)) {
        if (entry.path().extension() == ".frame")
          prefixes.push_back((entry.path().parent_path() / entry.path().stem()).string());
      }
    } else {
      prefixes.push_back(arg.size() > 6 && arg.compare(arg.size() - 6, 6, ".frame") == 0 ? arg.substr(0, arg.size() - 6)
                                                                                         : arg);
    }
  }
  std::sort(prefixes.begin(), prefixes.end());
  if (prefixes.empty()) {
    std::fprintf(stderr, "bench_render: no saved frames (<prefix>.frame)\n");
    return 2;
  }
  const char* names[6] = {"lit", "lit_noshadow", "light_off", "lit_nobump", "laser_off", "burn_every_frame"};
  constexpr int kVariants = 6;
  std::ostringstream json;
  json << "{\"suite\":\"render_saved_frames\",\"command\":\"" << command << "\",\"frames\":" << frames << ",\"rows\":[";
  std::printf("%-44s %-13s %6s %7s %7s %7s %7s %8s\n", "frame", "variant", "tris", "shadow", "scene", "dof", "total",
              "cpu_ms");
  for (std::size_t f = 0; f < prefixes.size(); ++f) {
    vrm_render::RenderState state;
    try {
      state = vrm_render::readRenderState(prefixes[f] + ".frame");
    } catch (const std::exception& e) {
      std::fprintf(stderr, "bench_render: %s\n", e.what());
      return 2;
    }
    if (!state.light.enabled) std::printf("(%s: the light pipe is off in this frame)\n", prefixes[f].c_str());
    if (current_light) {  // today's endoilluminator() at the saved light pipe's pose
      vrm_render::LightPipe light = vrm_render::endoilluminator();
      light.enabled = state.light.enabled;
      light.tip = state.light.tip;
      light.direction = state.light.direction;
      state.light = light;
    }
    std::vector<std::unique_ptr<StereoRenderer>> renderers;
    for (int v = 0; v < kVariants; ++v) {
      vrm_render::RenderState variant = state;
      if (v == 1) variant.options.shadow_pass = false;
      if (v == 2) variant.light.enabled = false;
      if (v == 3) variant.options.bump_mapping = false;
      if (v == 4) {
        variant.burns.clear();
        variant.objects.erase(std::remove_if(variant.objects.begin(), variant.objects.end(),
                                             [](const auto& object) { return object.id == vrm_render::kLaserAimId; }),
                              variant.objects.end());
      }
      renderers.push_back(std::make_unique<StereoRenderer>(variant.options, variant.rig));
      renderers.back()->restoreState(variant, false);
      StereoFrame warm;
      renderers.back()->render(&warm);
      renderers.back()->render(&warm);
    }
    std::vector<double> total[kVariants], shadow[kVariants], scene[kVariants], dof[kVariants], cpu[kVariants];
    std::vector<double> drawn[kVariants], layers[kVariants];
    StereoFrame frame;
    for (int i = 0; i < frames; ++i) {
      for (int v = 0; v < kVariants; ++v) {
        for (const auto& object : state.objects) {  // the session streams its deformable meshes every frame
          if (object.has_mesh && object.style.deformable)
            renderers[v]->updateMesh(object.id, object.mesh.view(), object.version + 1 + i);
        }
        const double cpu_start = processCpuMs();
        if (v == 5) {  // one more burn every frame, 0.6 mm apart along a line through the fundus
          std::vector<vrm_render::FundusBurn> burns = state.burns;
          for (int k = 0; k <= i; ++k) {
            vrm_render::FundusBurn burn;
            const float x = -0.004f + 0.0006f * static_cast<float>(k % 14), y = 0.0006f * static_cast<float>(k / 14);
            const float r = state.fundus.eye_radius > 0.0f ? state.fundus.eye_radius : 0.012f;
            burn.position = Eigen::Vector3f(x, y, -std::sqrt(r * r - x * x - y * y));
            burn.diameter = 0.0005f;
            burn.whiteness = 0.6f;
            burns.push_back(burn);
          }
          renderers[v]->setFundusBurns(burns);
        }
        renderers[v]->render(&frame);
        cpu[v].push_back(processCpuMs() - cpu_start);
        total[v].push_back(frame.timings.ms_total);
        shadow[v].push_back(frame.timings.ms_shadow);
        scene[v].push_back(frame.timings.ms_scene);
        dof[v].push_back(frame.timings.ms_dof);
        drawn[v].push_back(static_cast<double>(frame.timings.triangles_drawn));
        layers[v].push_back(frame.timings.static_layers_drawn);
      }
    }
    const std::string name = std::filesystem::path(prefixes[f]).filename().string();
    for (int v = 0; v < kVariants; ++v) {
      std::printf("%-44s %-13s %6zu %7.2f %7.2f %7.2f %7.2f %8.2f  drawn %.0f layers %.1f\n", name.c_str(), names[v],
                  renderers[v]->triangleCount(), median(shadow[v]), median(scene[v]), median(dof[v]), median(total[v]),
                  median(cpu[v]), median(drawn[v]), median(layers[v]));
      json << (f || v ? ",\n" : "\n") << "{\"frame\":\"" << name << "\",\"variant\":\"" << names[v]
           << "\",\"light_in_frame\":" << (state.light.enabled ? "true" : "false")
           << ",\"ms_shadow\":" << median(shadow[v]) << ",\"ms_scene\":" << median(scene[v])
           << ",\"ms_dof\":" << median(dof[v]) << ",\"ms_total\":" << median(total[v])
           << ",\"cpu_ms_per_frame\":" << median(cpu[v]) << "}";
    }
    std::vector<double> lit_minus_off;
    for (int i = 0; i < frames; ++i) lit_minus_off.push_back(total[0][i] - total[2][i]);
    std::printf("%-44s paired lit - off: %.2f ms per stereo frame (median of %d)\n", name.c_str(),
                median(lit_minus_off), frames);
    std::vector<double> laser_cost, new_burn_cost;
    for (int i = 0; i < frames; ++i) {
      laser_cost.push_back(total[0][i] - total[4][i]);
      new_burn_cost.push_back(total[5][i] - total[0][i]);
    }
    std::printf("%-44s paired: burns + aim %.2f ms, a new burn every frame %+.2f ms (max %.2f) per stereo frame; %zu burns\n",
                name.c_str(), median(laser_cost), median(new_burn_cost),
                *std::max_element(new_burn_cost.begin(), new_burn_cost.end()), state.burns.size());
  }
  json << "]}\n";
  if (!out.empty()) {
    std::ofstream file(out);
    if (!file) {
      std::fprintf(stderr, "bench_render: cannot write %s\n", out.c_str());
      return 1;
    }
    file << json.str();
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string out;
  std::string png_dir;
  std::string only_case;
  int frames_override = 0;
  std::vector<std::string> saved_frames;
  bool current_light = false;
  std::string command = "bench_render";
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    command += " " + arg;
    if (arg == "--quick") {
      quick = true;
    } else if (arg == "--out" && i + 1 < argc) {
      out = argv[++i];
      command += " " + out;
    } else if (arg == "--png" && i + 1 < argc) {
      png_dir = argv[++i];
      command += " " + png_dir;
    } else if (arg == "--case" && i + 1 < argc) {
      only_case = argv[++i];
      command += " " + only_case;
    } else if (arg == "--current-light") {  // --frame: today's endoilluminator() cone instead of the saved one
      current_light = true;
    } else if (arg == "--frame" && i + 1 < argc) {
      saved_frames.push_back(argv[++i]);
      command += " " + saved_frames.back();
    } else if (arg == "--frames" && i + 1 < argc) {
      frames_override = std::atoi(argv[++i]);
      command += " " + std::to_string(frames_override);
    } else {
      std::fprintf(stderr,
                   "usage: bench_render [--quick] [--out FILE] [--png DIR] [--case NAME] [--frames N]\n"
                   "       bench_render --frame PREFIX_OR_DIR [--current-light] [--frames N] [--out FILE]\n");
      return 2;
    }
  }
  vrm_render::retainFreedHeapMemory();
  if (!saved_frames.empty())
    return benchSavedFrames(saved_frames, frames_override > 0 ? frames_override : 30, out, command, current_light);
  const char* threads = std::getenv("LP_NUM_THREADS");
  const std::string lp_threads = threads ? threads : "default";
  // name, w, h, stereo, shadow, lighting, dof, stream, time_passes
  // The plain reference first: every row's ratio_to_plain is against it, measured in the same run.
  std::vector<Case> cases = {
      plainReference("stereo_800x600_plain_reference", 800, 600),
      {"stereo_800x600_all", 800, 600, true, true, true, true, true, true},
      {"stereo_800x600_all_nobarrier", 800, 600, true, true, true, true, true, false},
      {"stereo_800x600_all_dof_half", 800, 600, true, true, true, true, true, true, 512, 2},
      {"stereo_800x600_all_shadow1024", 800, 600, true, true, true, true, true, true, 1024, 4},
      {"stereo_800x600_all_lit_everywhere", 800, 600, true, true, true, true, true, true, 512, 4, false},
      {"stereo_800x600_noshadow", 800, 600, true, false, true, true, true, true},
      {"stereo_800x600_nofundus", 800, 600, true, true, true, true, true, true},
      {"stereo_800x600_nometal", 800, 600, true, true, true, true, true, true},
      {"stereo_800x600_nocache", 800, 600, true, true, true, true, true, true},
      {"stereo_800x600_all_eye_moving", 800, 600, true, true, true, true, true, true},
      {"stereo_800x600_nodof", 800, 600, true, true, true, false, true, true},
      {"stereo_800x600_flat", 800, 600, true, false, false, false, true, true},
      {"stereo_800x600_static", 800, 600, true, true, true, true, false, true},
      {"mono_800x600_all", 800, 600, false, true, true, true, true, true},
      {"stereo_640x480_all", 640, 480, true, true, true, true, true, true},
      {"stereo_400x300_all", 400, 300, true, true, true, true, true, true},
      {"mono_400x300_all", 400, 300, false, true, true, true, true, true},
  };
  int frames = 30;
  if (quick) {
    cases = {plainReference("stereo_320x240_plain_reference", 320, 240),
             {"stereo_320x240_all", 320, 240, true, true, true, true, true, true}};
    frames = 5;
  }
  if (!only_case.empty()) {
    // One case of the table in use (for profiling).
    std::vector<Case> all = cases;
    cases.clear();
    // A comma-separated list: e.g. the plain reference and one row, for their ratio in one run.
    std::stringstream names(only_case);
    for (std::string name; std::getline(names, name, ',');) {
      for (const Case& c : all) {
        if (c.name == name) cases.push_back(c);
      }
    }
    if (cases.empty()) {
      std::fprintf(stderr, "bench_render: no case named %s\n", only_case.c_str());
      return 2;
    }
  }
  for (Case& c : cases) {
    if (c.name.find("nofundus") != std::string::npos) c.fundus = false;
    if (c.name.find("nometal") != std::string::npos) c.metal = false;
    if (c.name.find("nocache") != std::string::npos) c.cache_static = false;
    if (c.name.find("eye_moving") != std::string::npos) c.eye_moving = true;
  }
  if (frames_override > 0) frames = frames_override;
  // Set-up cost of the fundus (baked once per scene, not per frame).
  const auto bake_start = std::chrono::steady_clock::now();
  const vrm_render::FundusMap fundus_map;
  const double fundus_bake_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - bake_start).count();
  std::printf("fundus bake (once per scene): %.1f ms, %zu vessel segments, %dx%d texels\n", fundus_bake_ms,
              fundus_map.vessels().size(), fundus_map.textureSize(), fundus_map.textureSize());
  std::vector<Row> rows;
  std::printf("LP_NUM_THREADS=%s, %d frames per case (median)\n", lp_threads.c_str(), frames);
  std::printf("%-34s %5s %4s %8s %7s %7s %7s %7s %7s %7s %8s %8s %10s %6s\n", "case", "size", "eyes", "tris", "upload",
              "shadow", "scene", "dof", "readbk", "total", "min", "cpu_ms", "Mtris/s", "/plain");
  // A row's cost against the plain reference frame of its size measured in this run (0 when there is none).
  auto ratioToPlain = [&](const Row& r) {
    for (const Row& p : rows) {
      if (p.c.plain && p.c.width == r.c.width && p.c.height == r.c.height && p.ms_total > 0) {
        return r.ms_total / p.ms_total;
      }
    }
    return 0.0;
  };
  for (const Case& c : cases) {
    Row r = run(c, frames, png_dir);
    rows.push_back(r);
    std::printf("%-34s %4dx%-4d %d %8zu %7.2f %7.2f %7.2f %7.2f %7.2f %7.2f %8.2f %8.2f %10.2f %6.3f\n", c.name.c_str(),
                c.width, c.height, c.stereo ? 2 : 1, r.triangles, r.ms_upload, r.ms_shadow, r.ms_scene, r.ms_dof,
                r.ms_readback, r.ms_total, r.ms_total_min, r.cpu_ms_per_frame, r.tris_per_s * 1e-6, ratioToPlain(r));
    std::fflush(stdout);
  }
  // The headline ratio, paired frame by frame against the plain reference (see pairedRatio).
  double paired_ratio = 0.0;
  std::string paired_case;
  for (const Row& p : rows) {
    if (!p.c.plain) continue;
    for (const Row& r : rows) {
      if (r.c.plain || r.c.width != p.c.width || r.c.height != p.c.height || !r.c.stereo || r.c.name.size() < 4 ||
          r.c.name.compare(r.c.name.size() - 4, 4, "_all") != 0) {
        continue;
      }
      paired_case = r.c.name;
      paired_ratio = pairedRatio(p.c, r.c, frames);
      std::printf("paired (frame by frame, median of %d ratios): %s / %s = %.3f (target <= 0.40)\n", frames,
                  r.c.name.c_str(), p.c.name.c_str(), paired_ratio);
      break;
    }
    break;
  }
  // The cost of each element of the full frame, paired against the row without it (stereo 800x600 only).
  std::vector<std::pair<std::string, double>> element_costs;
  for (const Row& all : rows) {
    if (all.c.name != "stereo_800x600_all") continue;
    for (const Row& r : rows) {
      const std::string prefix = "stereo_800x600_no";
      if (r.c.name.compare(0, prefix.size(), prefix) != 0) continue;
      const std::string element = r.c.name.substr(prefix.size());
      element_costs.emplace_back(element, pairedCost(all.c, r.c, frames));
      std::printf("paired cost of %-8s %6.2f ms per stereo frame (%s - %s, median of %d differences)\n",
                  element.c_str(), element_costs.back().second, all.c.name.c_str(), r.c.name.c_str(), frames);
    }
  }
  auto cpuRatioToPlain = [&](const Row& r) {
    for (const Row& p : rows) {
      if (p.c.plain && p.c.width == r.c.width && p.c.height == r.c.height && p.cpu_ms_per_frame > 0) {
        return r.cpu_ms_per_frame / p.cpu_ms_per_frame;
      }
    }
    return 0.0;
  };
  if (!out.empty()) {
    std::ofstream file(out);
    if (!file) {
      std::fprintf(stderr, "bench_render: cannot write %s\n", out.c_str());
      return 1;
    }
    file << "{\"suite\":\"render\",\"command\":\"" << command << "\",\"lp_num_threads\":\"" << lp_threads
         << "\",\"target_ms_total\":33.0,\"target_ratio_to_plain\":0.40,\"paired_case\":\"" << paired_case
         << "\",\"paired_ratio_to_plain\":" << paired_ratio << ",\"paired_cost_ms\":{";
    for (std::size_t i = 0; i < element_costs.size(); ++i) {
      file << (i ? "," : "") << "\"" << element_costs[i].first << "\":" << element_costs[i].second;
    }
    file << "}"
         << ",\"fundus_bake_ms\":" << fundus_bake_ms << ",\"rows\":[\n";
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const Row& r = rows[i];
      file << "{\"suite\":\"render\",\"case\":\"" << r.c.name << "\",\"width\":" << r.c.width
           << ",\"height\":" << r.c.height << ",\"stereo\":" << (r.c.stereo ? "true" : "false") << ",\"passes\":\""
           << passesOf(r.c) << "\",\"triangles\":" << r.triangles << ",\"streamed\":" << (r.c.stream ? "true" : "false")
           << ",\"pass_barriers\":" << (r.c.time_passes ? "true" : "false") << ",\"ms_upload\":" << r.ms_upload
           << ",\"ms_shadow\":" << r.ms_shadow << ",\"ms_scene\":" << r.ms_scene << ",\"ms_dof\":" << r.ms_dof
           << ",\"ms_readback\":" << r.ms_readback << ",\"ms_total\":" << r.ms_total
           << ",\"ms_total_min\":" << r.ms_total_min << ",\"cpu_ms_per_frame\":" << r.cpu_ms_per_frame
           << ",\"tris_per_s\":" << r.tris_per_s << ",\"streamed_tris_per_s\":" << r.streamed_tris_per_s
           << ",\"frames\":" << r.frames << ",\"shadow_map_size\":" << r.c.shadow_map
           << ",\"dof_downsample\":" << r.c.dof_downsample
           << ",\"light_partition\":" << (r.c.light_partition ? "true" : "false") << ",\"lp_num_threads\":\""
           << lp_threads << "\",\"meets_33ms\":" << (r.ms_total <= 33.0 ? "true" : "false")
           << ",\"fundus\":" << (r.c.fundus ? "true" : "false") << ",\"metal\":" << (r.c.metal ? "true" : "false")
           << ",\"plain_reference\":" << (r.c.plain ? "true" : "false") << ",\"ratio_to_plain\":" << ratioToPlain(r)
           << ",\"cpu_ratio_to_plain\":" << cpuRatioToPlain(r) << "}" << (i + 1 < rows.size() ? ",\n" : "\n");
    }
    file << "]}\n";
  }
  return 0;
}
