#pragma once
// The one place where vrm_sim's core types meet ROS messages (STYLE.md point 2). Everything else in the core is
// ROS-free.

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <visualization_msgs/Marker.h>

#include <Eigen/Geometry>
#include <array>
#include <cstdint>

#include "vrm_msgs/TissueMesh.h"
#include "vrm_sim/triangle_mesh.h"

namespace vrm_sim {

Eigen::Isometry3d toEigen(const geometry_msgs::Pose& pose);
geometry_msgs::Pose toPoseMsg(const Eigen::Isometry3d& pose);
geometry_msgs::Transform toTransformMsg(const Eigen::Isometry3d& transform);

// Packs contiguous positions (what the MGE arrays hold) and triangles into a TissueMesh; computes area-weighted
// vertex normals so renderers and RViz need not.
void fillTissueMesh(const Eigen::Vector3d* positions, std::size_t vertex_count,
                    const std::array<std::uint32_t, 3>* triangles, std::size_t triangle_count,
                    vrm_msgs::TissueMesh& message);
void fillTissueMesh(const TriangleMesh& mesh, vrm_msgs::TissueMesh& message);

// A TRIANGLE_LIST marker of the mesh (RViz has no indexed triangles, so vertices are expanded per triangle).
void fillTriangleListMarker(const vrm_msgs::TissueMesh& mesh, const std::array<float, 4>& rgba,
                            visualization_msgs::Marker& marker);

}  // namespace vrm_sim
