#pragma once
// The reply of the mesh import helper (tools/vrm_mesh_import.cpp) on its standard output, read by importMesh()
// (mesh_import_process.cpp): "VRMMESH1", u64 vertex count, u64 triangle count, the vertices (3 doubles each), the
// triangles (3 u32 each), in this machine's byte order (parent and helper are one build). A failed import exits with
// kMeshImportFailed and the problem on standard error.

#include <cstdint>
#include <string>

#include "vrm_scene/meshes/mesh_io.h"
#include "vrm_scene/meshes/triangle_mesh.h"

namespace vrm_sim {
namespace scene {

constexpr char kMeshReplyMagic[8] = {'V', 'R', 'M', 'M', 'E', 'S', 'H', '1'};
constexpr int kMeshImportFailed = 3;

// Throws MeshIoError for a request no importer needs to see: a missing or irregular file, a bad scale.
void checkImportRequest(const std::string& path, const MeshImportOptions& options);

// The reply bytes of a mesh (vertices and triangles only: the name is the caller's, normals are never imported).
std::string encodeMeshReply(const TriangleMesh& mesh);
// Fills mesh from a reply; returns "" or what is wrong with the bytes.
std::string decodeMeshReply(const std::string& bytes, TriangleMesh* mesh);

}  // namespace scene
}  // namespace vrm_sim
