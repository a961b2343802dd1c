#pragma once
// Mesh files <-> TriangleMesh. Import goes through assimp (OBJ, PLY, STL and whatever else assimp reads); export
// writes Wavefront OBJ, which needs no library and round-trips through importMesh().

#include <stdexcept>
#include <string>

#include "vrm_scene/meshes/triangle_mesh.h"

namespace vrm_sim {
namespace scene {

// Every import or export failure; the message starts with the file path.
class MeshIoError : public std::runtime_error {
 public:
  MeshIoError(const std::string& path, const std::string& problem);
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

struct MeshImportOptions {
  double scale = 1.0;  // applied to the vertices, e.g. 0.001 for files in millimetres
  // Merge vertices with bit-identical positions (after assimp's float conversion). Formats such as STL store every
  // triangle separately; without this, a mesh would fall apart into loose triangles under the tissue simulation.
  bool join_identical_vertices = true;
  std::string name;  // mesh name; empty = the file name without directory and extension
  // importMesh() reads the file in a helper process and kills it after this many seconds, so a file that hangs or
  // crashes assimp is an import error instead of a hung or dead nodelet manager (issue 39).
  double time_limit = 30.0;
};

// Triangulates polygons, flattens the node hierarchy (node transforms are applied) and concatenates all meshes of
// the file; points and lines are dropped. Normals are not imported (they would prevent welding); see
// computeVertexNormals(). Throws MeshIoError for a missing or unreadable file, a syntax error, out-of-range
// indices, NaN/Inf coordinates, or a file without triangles.
//
// The import runs in the helper executable vrm_mesh_import (meshImportHelperPath()), started with posix_spawn: never a
// fork of the caller, which may be a multi-threaded nodelet manager. A helper that outlives options.time_limit is
// killed (MeshIoError "did not finish within"); one that dies of a signal is a MeshIoError too.
TriangleMesh importMesh(const std::string& path, const MeshImportOptions& options = {});

// The same import in this process (no time limit, an importer crash is this process's): the helper itself, the fuzz
// target, and tools that want no child process.
TriangleMesh importMeshInProcess(const std::string& path, const MeshImportOptions& options = {});

// The helper importMesh() runs: $VRM_MESH_IMPORT_HELPER if set, else vrm_scene/vrm_mesh_import next to the library
// that holds this code (devel/lib/vrm_sim/ or <prefix>/lib/vrm_sim/).
std::string meshImportHelperPath();

// Writes vertices with 17 significant digits, normals if present and 1-based faces. Fixed vertices are written as
// a comment only ("# fixed_vertices ..."); OBJ has no element for them. Throws MeshIoError.
void writeObj(const TriangleMesh& mesh, const std::string& path);

}  // namespace scene
}  // namespace vrm_sim
