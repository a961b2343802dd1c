// The mesh import helper (issue 39): reads one mesh file with assimp in its own process and writes the mesh to
// standard output (mesh_import_wire.h), so that scene::importMesh() can stop an importer that hangs and survive one
// that crashes. Started by importMesh() only: vrm_mesh_import [--scale S] [--no-join] -- PATH
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "../src/meshes/mesh_import_wire.h"
#include "vrm_scene/meshes/mesh_io.h"

int main(int argc, char** argv) {
  using namespace vrm_sim::scene;
  MeshImportOptions options;
  std::string path;
  for (int i = 1; i < argc; ++i) {
    const std::string argument = argv[i];
    if (argument == "--scale" && i + 1 < argc) {
      char* end = nullptr;
      options.scale = std::strtod(argv[++i], &end);
      if (end == nullptr || *end != '\0') {
        std::fprintf(stderr, "vrm_mesh_import: --scale needs a number, got '%s'\n", argv[i]);
        return 2;
      }
    } else if (argument == "--no-join") {
      options.join_identical_vertices = false;
    } else if (argument == "--" && i + 1 == argc - 1) {
      path = argv[++i];
    } else {
      path.clear();
      break;
    }
  }
  if (path.empty()) {
    std::fprintf(stderr, "usage: vrm_mesh_import [--scale S] [--no-join] -- PATH (started by scene::importMesh)\n");
    return 2;
  }
  std::string reply;
  try {
    reply = encodeMeshReply(importMeshInProcess(path, options));
  } catch (const MeshIoError& error) {
    // The parent adds the path again: send only the problem.
    const std::string what = error.what();
    const std::string prefix = error.path() + ": ";
    std::fprintf(stderr, "%s\n",
                 what.compare(0, prefix.size(), prefix) == 0 ? what.c_str() + prefix.size() : what.c_str());
    return kMeshImportFailed;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "cannot import: %s\n", error.what());
    return kMeshImportFailed;
  }
  std::size_t written = 0;
  while (written < reply.size()) {
    const ssize_t n = write(1, reply.data() + written, reply.size() - written);
    if (n <= 0) return 4;
    written += static_cast<std::size_t>(n);
  }
  return 0;
}
