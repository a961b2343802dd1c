#pragma once
// Topological building blocks for the procedural assets: tubes (rings of vertices swept along a path, optionally
// closed by a pole vertex at each end) and concentric rings (caps, discs, spheres) triangulated without slivers.
// Every generator in primitive_meshes.h, eye_meshes.h and instrument_meshes.h is built from these two, so the
// orientation rules live in one place.

#include <optional>
#include <vector>

#include "vrm_scene/meshes/triangle_mesh.h"

namespace vrm_sim {
namespace scene {

// A tube whose rings all have the same vertex count (>= 3). Each ring must run counter-clockwise seen from the
// end of the tube (looking back along the path), i.e. right-handed about the path direction; then the generated
// triangles face away from the path. A pole closes the tube at that end with a fan (a flat cap when the pole lies
// in the plane of the end ring, a cone or dome otherwise).
struct TubeRings {
  std::vector<std::vector<Eigen::Vector3d>> rings;
  std::optional<Eigen::Vector3d> start_pole;
  std::optional<Eigen::Vector3d> end_pole;
};
TriangleMesh makeTube(const TubeRings& tube);

// A ring of `vertex_count` vertices (1 = a pole) at angles 2*pi*(i + angle_offset)/vertex_count, i = 0..count-1;
// vertices of ring k are stored consecutively starting at `first_vertex`.
struct AngularRing {
  std::uint32_t first_vertex = 0;
  std::uint32_t vertex_count = 1;
  double angle_offset = 0.0;  // in units of one angular step
};
// Triangulates the band between consecutive rings by always advancing the ring whose next vertex has the smaller
// angle (a merge of the two angular sequences). Rings with different vertex counts therefore join without slivers.
// Triangles are ordered (inner_i, outer_j, inner_i+1) / (inner_i, outer_j, outer_j+1), where "inner" is rings[k]
// and "outer" rings[k+1]; with angles increasing counter-clockwise about an axis n and rings progressing away from
// that axis' pole, the normals point along e_theta x e_phi (outward on a sphere about its +n pole).
std::vector<std::array<std::uint32_t, 3>> triangulateConcentricRings(const std::vector<AngularRing>& rings);

}  // namespace scene
}  // namespace vrm_sim
