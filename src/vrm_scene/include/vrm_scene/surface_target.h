#pragma once
// Waypoints written on scene objects (a script's `on:` / `height:`), so a script that touches tissue follows the scene
// file instead of a copy of its geometry: the tip played is the closest point of the object's surface to the written
// tip, moved `height` along the surface normal that points into the eye (towards the eye centre). The offline tools
// (withScript) and vrm_tracking's device twins resolve a script here, so both play the same points.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_scene/scene_description.h"

namespace vrm_sim {
namespace scene {

// A point of a triangle mesh nearest to a query point, with the normal of the triangle it lies on turned towards the
// eye centre (the origin of the mesh's frame): "above" a retina or membrane is the side the instruments come from.
struct SurfacePoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d inward_normal = Eigen::Vector3d::UnitZ();  // unit
  double distance = 0.0;                                     // from the query point, m
};

// Brute force over the triangles (scene objects have a few thousand; this runs once per waypoint at load time).
// Throws std::invalid_argument for a mesh without (non-degenerate) triangles.
SurfacePoint closestSurfacePoint(const TriangleMesh& surface, const Eigen::Vector3d& point);

// Where a waypoint written `on` an object with this surface lands: closest point to `written_tip` plus `height`
// along the inward normal (negative: below the surface).
Eigen::Vector3d resolveSurfaceTip(const TriangleMesh& surface, const Eigen::Vector3d& written_tip, double height);

// What resolveSurfaceTargets did, for the caller's log.
struct SurfaceTargetReport {
  std::size_t resolved_waypoints = 0;
  // On an object the scene lacks (only where ScriptedSession::keep_tip_on_missing_object): they keep their tips.
  std::size_t kept_waypoints = 0;
  std::vector<std::string> missing_objects;  // unique, in order of first use
};

// Names of the scene objects the session's waypoints are written on, unique, in order of first use.
std::vector<std::string> surfaceTargetObjects(const ScriptedSession& session);

// The session with every waypoint `on` an object put on the scene's surface (resolveSurfaceTip on
// buildMesh(object, kParent)) and its `on` cleared. An object the scene lacks is a YamlError at the waypoint naming the
// object and the scene's objects, unless session.keep_tip_on_missing_object; an object in the world frame is a
// YamlError (tips are in the eye frame and the eye moves in the world). `report` may be null.
ScriptedSession resolveSurfaceTargets(const SceneDescription& scene, const ScriptedSession& session,
                                      SurfaceTargetReport* report = nullptr);

}  // namespace scene
}  // namespace vrm_sim
