#include "vrm_scene/surface_target.h"

#include <algorithm>
#include <map>
#include <sstream>
#include <stdexcept>

#include "vrm_scene/scene_loader.h"

namespace vrm_sim {
namespace scene {

namespace {

std::string describeScene(const SceneDescription& scene) {
  return "scene '" + scene.name + "' (" + (scene.source_file.empty() ? std::string("<memory>") : scene.source_file) +
         ")";
}

std::string objectNames(const SceneDescription& scene) {
  std::string names;
  for (const ObjectDescription& object : scene.objects) names += (names.empty() ? "" : ", ") + object.name;
  return names.empty() ? "none" : names;
}

// Real-Time Collision Detection (Ericson 2005), §5.1.5: the Voronoi region of the triangle the point projects into.
Eigen::Vector3d closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + (d1 / (d1 - d3)) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + (d2 / (d2 - d6)) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  const double denominator = 1.0 / (va + vb + vc);
  return a + ab * (vb * denominator) + ac * (vc * denominator);
}

}  // namespace

SurfacePoint closestSurfacePoint(const TriangleMesh& surface, const Eigen::Vector3d& point) {
  // Triangles meeting at the nearest edge or vertex are equally near; averaging their normals keeps the direction
  // of `height` from depending on which of them comes first in the index list.
  constexpr double kTieTolerance = 1e-9;  // m
  struct Candidate {
    Eigen::Vector3d position;
    Eigen::Vector3d inward_normal;
    double distance;
  };
  std::vector<Candidate> candidates;
  candidates.reserve(surface.triangles.size());
  for (const auto& triangle : surface.triangles) {
    const Eigen::Vector3d& a = surface.vertices.at(triangle[0]);
    const Eigen::Vector3d& b = surface.vertices.at(triangle[1]);
    const Eigen::Vector3d& c = surface.vertices.at(triangle[2]);
    Eigen::Vector3d normal = (b - a).cross(c - a);
    if (normal.squaredNorm() < 1e-30) continue;  // degenerate: no normal to measure a height along
    normal.normalize();
    const Eigen::Vector3d position = closestPointOnTriangle(point, a, b, c);
    // The eye centre is the frame origin: "above" is the side facing it, whatever the triangle winding.
    if (normal.dot(-position) < 0.0) normal = -normal;
    const double distance = (point - position).norm();
    candidates.push_back({position, normal, distance});
  }
  if (candidates.empty()) {
    throw std::invalid_argument("mesh '" + surface.name + "' has no triangles to place a point on");
  }
  const Candidate& nearest =
      *std::min_element(candidates.begin(), candidates.end(),
                        [](const Candidate& a, const Candidate& b) { return a.distance < b.distance; });
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
  for (const Candidate& candidate : candidates) {
    if (candidate.distance <= nearest.distance + kTieTolerance) normal_sum += candidate.inward_normal;
  }
  SurfacePoint result;
  result.position = nearest.position;
  result.distance = nearest.distance;
  // Opposite normals only cancel at a fold of zero thickness; the nearest triangle's own normal will do there.
  result.inward_normal = normal_sum.squaredNorm() > 1e-12 ? normal_sum.normalized() : nearest.inward_normal;
  return result;
}

Eigen::Vector3d resolveSurfaceTip(const TriangleMesh& surface, const Eigen::Vector3d& written_tip, double height) {
  const SurfacePoint nearest = closestSurfacePoint(surface, written_tip);
  return nearest.position + height * nearest.inward_normal;
}

std::vector<std::string> surfaceTargetObjects(const ScriptedSession& session) {
  std::vector<std::string> objects;
  for (const ScriptedInstrument& instrument : session.instruments) {
    for (const InstrumentWaypoint& waypoint : instrument.path) {
      if (!waypoint.on.empty() && std::find(objects.begin(), objects.end(), waypoint.on) == objects.end()) {
        objects.push_back(waypoint.on);
      }
    }
  }
  return objects;
}

ScriptedSession resolveSurfaceTargets(const SceneDescription& scene, const ScriptedSession& session,
                                      SurfaceTargetReport* report) {
  ScriptedSession resolved = session;
  SurfaceTargetReport summary;
  std::map<std::string, TriangleMesh> surfaces;  // each object's mesh is built once
  for (ScriptedInstrument& instrument : resolved.instruments) {
    for (InstrumentWaypoint& waypoint : instrument.path) {
      if (waypoint.on.empty()) continue;
      std::ostringstream when;
      when << "waypoint t = " << waypoint.t << " s";
      SourceLocation where = waypoint.location;
      where.field += where.field.empty() ? "on" : ".on";
      const ObjectDescription* object = scene.findObject(waypoint.on);
      if (object == nullptr) {
        if (!resolved.keep_tip_on_missing_object) {
          throw YamlError(where, describeScene(scene) + " has no object '" + waypoint.on + "' (" + when.str() +
                                     "; the scene's objects: " + objectNames(scene) + ")");
        }
        ++summary.kept_waypoints;
        auto& missing = summary.missing_objects;
        if (std::find(missing.begin(), missing.end(), waypoint.on) == missing.end()) missing.push_back(waypoint.on);
        waypoint.on.clear();
        waypoint.height = 0.0;
        continue;
      }
      if (object->frame != ObjectFrame::kEye) {
        throw YamlError(where, "object '" + waypoint.on + "' of " + describeScene(scene) + " is in the " +
                                   toString(object->frame) + " frame (" + when.str() +
                                   "); waypoints can only be written on objects in the eye frame, because tips are "
                                   "in the eye frame and the eye moves in the world");
      }
      auto surface = surfaces.find(waypoint.on);
      if (surface == surfaces.end()) {
        surface = surfaces.emplace(waypoint.on, buildMesh(*object, MeshFrame::kParent)).first;
      }
      waypoint.tip_in_eye = resolveSurfaceTip(surface->second, waypoint.tip_in_eye, waypoint.height);
      waypoint.on.clear();
      waypoint.height = 0.0;
      ++summary.resolved_waypoints;
    }
  }
  if (report != nullptr) *report = std::move(summary);
  return resolved;
}

}  // namespace scene
}  // namespace vrm_sim
