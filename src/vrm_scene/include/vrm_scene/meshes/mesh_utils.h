#pragma once
// Small geometric helpers on TriangleMesh shared by the importers, the procedural assets and their tests.

#include <Eigen/Geometry>

#include "vrm_scene/meshes/triangle_mesh.h"

namespace vrm_sim {
namespace scene {

// Volume enclosed by a closed mesh; positive when the triangles are counter-clockwise seen from outside (outward
// normals). For an open mesh the value depends on the origin and only its sign relative to a known shape is useful.
double signedVolume(const TriangleMesh& mesh);
double surfaceArea(const TriangleMesh& mesh);

// Unnormalised normal (length = 2 * area) of triangle `triangle_index`.
Eigen::Vector3d triangleAreaVector(const TriangleMesh& mesh, std::size_t triangle_index);

Eigen::AlignedBox3d boundingBox(const TriangleMesh& mesh);

// Applies a rigid transform to vertices and normals. Rotations preserve the triangle orientation.
void transformMesh(TriangleMesh& mesh, const Eigen::Isometry3d& transform);
// Scales vertices uniformly; a negative factor is rejected (it would turn the mesh inside out).
void scaleMesh(TriangleMesh& mesh, double factor);
// Appends `part` to `mesh`, re-indexing its triangles and fixed vertices. Normals are kept only if both have them.
void appendMesh(TriangleMesh& mesh, const TriangleMesh& part);
// Reverses the winding of every triangle (and the normals), e.g. to make a shell face its inside.
void flipOrientation(TriangleMesh& mesh);
// Area-weighted vertex normals, stored in mesh.normals.
void computeVertexNormals(TriangleMesh& mesh);

// Roll-pitch-yaw in radians about fixed x, y, z axes (the ROS / URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll)).
Eigen::Matrix3d rotationFromRpy(const Eigen::Vector3d& roll_pitch_yaw);

}  // namespace scene
}  // namespace vrm_sim
