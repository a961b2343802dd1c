// Mesh import (vrm_sim scene/mesh_io.h) through assimp, then validation and cleanup (mesh_validation.h), as a scene
// with `mesh: {file: ...}` does. The first byte picks the file extension (assimp chooses the reader by it and by
// the content), the rest is the file; the scale option comes from the second byte.
#include <stdexcept>

#include "fuzz_target.h"
#include "vrm_scene/meshes/mesh_io.h"
#include "vrm_scene/meshes/mesh_validation.h"

VRM_FUZZ_TARGET(mesh_import) {
  using namespace vrm_sim::scene;
  if (size < 2) return 0;
  static const char* const kExtensions[] = {"obj", "ply", "stl"};
  const std::string name = std::string("mesh.") + kExtensions[data[0] % 3];
  const bool join = (data[1] & 1) != 0;
  const std::string path = vrm_fuzz::writeScratchFile(name, data + 2, size - 2);
  MeshImportOptions options;
  options.join_identical_vertices = join;
  vrm_sim::TriangleMesh mesh;
  try {
    mesh = importMeshInProcess(path, options);  // assimp itself, under ASan (importMesh would run it in a helper)
  } catch (const MeshIoError&) {
    return 0;
  }
  const MeshReport report = validateMesh(mesh);
  (void)report.summary();
  if (report.isUsable()) {
    cleanupMesh(mesh);  // throws only for an unusable mesh, which was just ruled out
    validateMesh(mesh);
  } else {
    try {
      cleanupMesh(mesh);
    } catch (const std::invalid_argument&) {
    }
  }
  return 0;
}
