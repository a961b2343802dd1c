#pragma once
// The exchange format between mesh import / procedural assets and the MGE membrane model: plain contiguous arrays,
// SI units (metres), triangles counter-clockwise seen from the outside (thesis §3: vertex order gives the normal).

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace vrm_sim {

struct TriangleMesh {
  std::string name;
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  // Optional per-vertex normals (empty = compute from the triangles when needed).
  std::vector<Eigen::Vector3d> normals;
  // Optional indices of vertices that are pinned (adhesion points of a membrane, the rim of the retina).
  std::vector<std::uint32_t> fixed_vertices;

  std::size_t vertexCount() const { return vertices.size(); }
  std::size_t triangleCount() const { return triangles.size(); }
};

}  // namespace vrm_sim
