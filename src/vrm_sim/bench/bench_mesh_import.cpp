// Mesh import in a helper process (issue 39 §3): what the isolation costs per file against importing in this process,
// and against its error (the helper's mesh must equal the in-process one bit for bit), on the test meshes and on large
// generated ones; and the hard cases: an importer that hangs (how long past its time limit the error comes) and one
// that crashes (stand-in helpers through VRM_MESH_IMPORT_HELPER).
// Usage: bench_mesh_import [--quick] [--out FILE]
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "vrm_scene/meshes/eye_meshes.h"
#include "vrm_scene/meshes/mesh_io.h"

using namespace vrm_sim;
using Clock = std::chrono::steady_clock;

namespace {

double ms(Clock::time_point since) { return std::chrono::duration<double, std::milli>(Clock::now() - since).count(); }

double percentile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<std::size_t>(q * static_cast<double>(values.size())))];
}

bool identical(const TriangleMesh& a, const TriangleMesh& b) {
  return a.vertices == b.vertices && a.triangles == b.triangles;
}

std::string writeHelper(const std::string& folder, const std::string& name, const std::string& body) {
  const std::string path = folder + "/" + name;
  std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
  std::filesystem::permissions(path, std::filesystem::perms::owner_all);
  return path;
}

}  // namespace

int main(int argc, char** argv) {
  bench::BenchArgs args;
  if (const auto status = bench::parseBenchArgs(
          argc, argv, "bench_mesh_import",
          "Mesh import in a helper process: its cost per file against in-process import, and its error (none allowed).",
          "bench/results/mesh_import.json", &args)) {
    return *status;
  }
  const std::string folder = std::filesystem::temp_directory_path().string() + "/bench_mesh_import_" +
                             std::to_string(static_cast<long>(::getpid()));
  std::filesystem::create_directories(folder);
  const std::string data = std::string(VRM_SCENE_SOURCE_DIR) + "/test/data/meshes/";
  struct Case {
    std::string name, path, kind;
  };
  std::vector<Case> cases = {{"tetrahedron_ply", data + "tetrahedron.ply", "kind: 4 vertices"},
                             {"cube_quads_obj", data + "cube_quads.obj", "kind: quads triangulated"},
                             {"tetrahedron_stl", data + "tetrahedron_ascii.stl", "kind: STL welded"}};
  for (const int rings : args.quick ? std::vector<int>{24} : std::vector<int>{24, 96, 192}) {
    scene::RetinaParams retina;
    retina.ring_count = rings;
    const std::string path = folder + "/retina_" + std::to_string(rings) + ".obj";
    scene::writeObj(scene::makeRetina(retina), path);
    cases.push_back({"retina_" + std::to_string(rings) + "_rings_obj", path, "large: a generated retina as OBJ"});
  }
  const int repetitions = args.quick ? 3 : 20;
  std::printf("bench_mesh_import (%s): %d imports per case and way\n", args.quick ? "quick" : "full", repetitions);
  std::printf("%-26s %9s %9s %11s %11s %11s %11s %9s\n", "case", "vertices", "triangles", "inproc_p50", "helper_p50",
              "helper_max", "overhead", "identical");
  std::string rows;
  bool all_identical = true;
  double worst_overhead_ms = 0.0;
  for (const Case& c : cases) {
    std::vector<double> here_ms, helper_ms;
    TriangleMesh here, helper;
    for (int i = 0; i < repetitions; ++i) {
      auto start = Clock::now();
      here = scene::importMeshInProcess(c.path);
      here_ms.push_back(ms(start));
      start = Clock::now();
      helper = scene::importMesh(c.path);
      helper_ms.push_back(ms(start));
    }
    const bool same = identical(here, helper);
    all_identical = all_identical && same;
    const double overhead = percentile(helper_ms, 0.5) - percentile(here_ms, 0.5);
    worst_overhead_ms = std::max(worst_overhead_ms, overhead);
    std::printf("%-26s %9zu %9zu %9.2fms %9.2fms %9.2fms %9.2fms %9s\n", c.name.c_str(), here.vertexCount(),
                here.triangleCount(), percentile(here_ms, 0.5), percentile(helper_ms, 0.5),
                *std::max_element(helper_ms.begin(), helper_ms.end()), overhead, same ? "yes" : "NO");
    char line[800];
    std::snprintf(line, sizeof(line),
                  "{\"suite\":\"mesh_import\",\"case\":\"%s\",\"kind\":\"%s\",\"vertices\":%zu,\"triangles\":%zu,"
                  "\"repetitions\":%d,\"in_process_ms_p50\":%.3f,\"in_process_ms_max\":%.3f,\"helper_ms_p50\":%.3f,"
                  "\"helper_ms_max\":%.3f,\"helper_overhead_ms_p50\":%.3f,\"identical\":%s}",
                  c.name.c_str(), c.kind.c_str(), here.vertexCount(), here.triangleCount(), repetitions,
                  percentile(here_ms, 0.5), *std::max_element(here_ms.begin(), here_ms.end()),
                  percentile(helper_ms, 0.5), *std::max_element(helper_ms.begin(), helper_ms.end()), overhead,
                  same ? "true" : "false");
    rows += (rows.empty() ? "\n  " : ",\n  ") + std::string(line);
  }
  // The hard cases: a hanging importer must end in an error shortly after the limit, a crashing one at once.
  struct Fault {
    std::string name, body, expect;
    double limit;
  };
  const std::vector<Fault> faults = {{"hanging_importer", "exec sleep 60", "did not finish within", 0.5},
                                     {"crashing_importer", "kill -SEGV $$", "died of signal", 30.0}};
  bool faults_caught = true;
  for (const Fault& fault : faults) {
    setenv("VRM_MESH_IMPORT_HELPER", writeHelper(folder, fault.name + ".sh", fault.body).c_str(), 1);
    scene::MeshImportOptions options;
    options.time_limit = fault.limit;
    std::string error;
    const auto start = Clock::now();
    try {
      scene::importMesh(data + "tetrahedron.ply", options);
    } catch (const scene::MeshIoError& caught) {
      error = caught.what();
    }
    const double elapsed = ms(start);
    unsetenv("VRM_MESH_IMPORT_HELPER");
    const bool caught = error.find(fault.expect) != std::string::npos;
    faults_caught = faults_caught && caught;
    std::printf("%-26s error after %.1f ms (limit %.1f s): %s\n", fault.name.c_str(), elapsed, fault.limit,
                caught ? error.c_str() : "NOT CAUGHT");
    char line[600];
    std::snprintf(
        line, sizeof(line),
        "{\"suite\":\"mesh_import\",\"case\":\"%s\",\"kind\":\"hard: a stand-in helper\",\"time_limit_s\":%.1f,"
        "\"error_after_ms\":%.1f,\"error_past_limit_ms\":%.1f,\"caught\":%s}",
        fault.name.c_str(), fault.limit, elapsed, fault.name == "hanging_importer" ? elapsed - 1e3 * fault.limit : 0.0,
        caught ? "true" : "false");
    rows += ",\n  " + std::string(line);
  }
  std::filesystem::remove_all(folder);
  std::ofstream out(args.out_path);
  out << "{\"suite\":\"mesh_import\",\"command\":\"rosrun vrm_sim bench_mesh_import" << (args.quick ? " --quick" : "")
      << "\",\"quick\":" << (args.quick ? "true" : "false") << ",\"worst_helper_overhead_ms_p50\":" << worst_overhead_ms
      << ",\"all_identical\":" << (all_identical ? "true" : "false")
      << ",\"faults_caught\":" << (faults_caught ? "true" : "false") << ",\"rows\":[" << rows << "\n]}\n";
  if (!out) {
    std::fprintf(stderr, "bench_mesh_import: cannot write %s\n", args.out_path.c_str());
    return 1;
  }
  std::printf("worst helper overhead %.2f ms (median per file); identical: %s; faults caught: %s\nwrote %s\n",
              worst_overhead_ms, all_identical ? "yes" : "NO", faults_caught ? "yes" : "NO", args.out_path.c_str());
  return all_identical && faults_caught ? 0 : 1;
}
