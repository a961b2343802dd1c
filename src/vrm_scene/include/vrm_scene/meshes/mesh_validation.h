#pragma once
// Checks a TriangleMesh before it enters the MGE / tissue simulation, where a NaN or a bad index would crash or
// silently explode the integrator, and an optional cleanup for the fixable problems.

#include <string>

#include "vrm_scene/meshes/triangle_mesh.h"

namespace vrm_sim {
namespace scene {

struct MeshReport {
  std::size_t vertex_count = 0;
  std::size_t triangle_count = 0;
  std::size_t non_finite_vertices = 0;     // a NaN or Inf coordinate
  std::size_t out_of_range_triangles = 0;  // an index >= vertex_count
  std::size_t out_of_range_fixed_vertices = 0;
  std::size_t normal_count_mismatch = 0;  // 1 if normals is neither empty nor vertex_count long
  std::size_t degenerate_triangles = 0;   // a repeated index or (numerically) zero area
  std::size_t duplicate_vertices = 0;     // same position as an earlier vertex
  std::size_t unreferenced_vertices = 0;
  std::size_t boundary_edges = 0;      // used by one triangle
  std::size_t non_manifold_edges = 0;  // used by more than two triangles
  std::size_t inconsistent_edges = 0;  // used twice in the same direction: neighbours disagree on the side

  // Can be handed to a simulation without risking a crash: non-empty, finite, all indices valid.
  bool isUsable() const;
  // Usable, and nothing cleanupMesh() would remove or that breaks a mass-spring model.
  bool isClean() const;
  // Watertight, 2-manifold and consistently oriented (signedVolume() is then meaningful).
  bool isClosed() const;
  // One line, e.g. "120 vertices, 236 triangles, 2 degenerate triangles, 4 boundary edges".
  std::string summary() const;
};

// A triangle is degenerate when twice its area is below `relative_area_tolerance` times its longest edge squared,
// i.e. its smallest angle is (numerically) zero regardless of the mesh's scale.
MeshReport validateMesh(const TriangleMesh& mesh, double relative_area_tolerance = 1e-12);

struct MeshCleanupOptions {
  bool join_duplicate_vertices = true;
  double join_distance = 0.0;  // 0 = only bit-identical positions
  bool remove_degenerate_triangles = true;
  bool remove_unreferenced_vertices = true;
  double relative_area_tolerance = 1e-12;
};
struct MeshCleanupResult {
  std::size_t joined_vertices = 0;
  std::size_t removed_triangles = 0;
  std::size_t removed_vertices = 0;  // unreferenced after joining
};

// Joins duplicates, drops degenerate triangles and unreferenced vertices; keeps fixed_vertices and normals aligned
// with the surviving vertices (a fixed vertex stays fixed when joined). Throws std::invalid_argument if the mesh is
// not usable (cleanup cannot invent a position for a NaN).
MeshCleanupResult cleanupMesh(TriangleMesh& mesh, const MeshCleanupOptions& options = {});

}  // namespace scene
}  // namespace vrm_sim
