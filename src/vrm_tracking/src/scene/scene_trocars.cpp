#include "vrm_tracking/scene_trocars.h"

#include <algorithm>
#include <map>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "vrm_sim/scene/scene_loader.h"

namespace vrm_tracking {

namespace scene = vrm_sim::scene;

namespace {

std::string describeScene(const scene::SceneDescription& scene) {
  return "scene '" + scene.name + "' (" + (scene.source_file.empty() ? std::string("<memory>") : scene.source_file) +
         ")";
}

std::string objectNames(const scene::SceneDescription& scene) {
  std::string names;
  for (const scene::ObjectDescription& object : scene.objects) names += (names.empty() ? "" : ", ") + object.name;
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

std::string sceneOrDefault(const std::string& spec) { return spec.empty() ? vrm_sim::scene::kDefaultSceneName : spec; }

bool leavesTrocarsToScene(const ScriptDefinition& script) {
  return std::any_of(script.instruments.begin(), script.instruments.end(),
                     [](const InstrumentTrack& track) { return track.trocar_from_scene; });
}

Eigen::Vector3d sceneTrocarForSlot(const scene::SceneDescription& scene, const std::string& slot) {
  std::string trocar_name = slot;
  for (const scene::InstrumentDescription& instrument : scene.instruments) {
    if (slot == scene::toString(instrument.slot)) trocar_name = instrument.trocar;
  }
  if (const scene::Trocar* trocar = scene.findTrocar(trocar_name)) return trocar->position_in_eye;
  std::string available;
  for (const scene::Trocar& trocar : scene.eye.trocars) available += (available.empty() ? "" : ", ") + trocar.name;
  throw std::runtime_error(describeScene(scene) + " has no trocar for instrument slot '" + slot +
                           "' (looked for trocar '" + trocar_name +
                           "'; the scene's trocars: " + (available.empty() ? "none" : available) + ")");
}

SurfacePoint closestSurfacePoint(const vrm_sim::TriangleMesh& surface, const Eigen::Vector3d& point) {
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

Eigen::Vector3d resolveSurfaceTip(const vrm_sim::TriangleMesh& surface, const Eigen::Vector3d& written_tip,
                                  double height) {
  const SurfacePoint nearest = closestSurfacePoint(surface, written_tip);
  return nearest.position + height * nearest.inward_normal;
}

void applyScene(const scene::SceneDescription& scene, ScriptDefinition* script, SceneTargetReport* report) {
  // Work on a copy and commit at the end: a failing keyframe must not leave the script half resolved.
  ScriptDefinition resolved = *script;
  applySceneTrocars(scene, &resolved);
  SceneTargetReport summary;
  std::map<std::string, vrm_sim::TriangleMesh> surfaces;  // each object's mesh is built once
  for (InstrumentTrack& track : resolved.instruments) {
    for (std::size_t i = 0; i < track.keyframes.size(); ++i) {
      InstrumentKeyframe& key = track.keyframes[i];
      SurfaceTarget& target = key.target;
      if (!target.active()) continue;
      const std::string field = "instruments." + track.slot + ".keyframes[" + std::to_string(i) + "].on";
      std::ostringstream when;
      when << "keyframe t = " << key.t << " s";
      const scene::ObjectDescription* object = scene.findObject(target.object);
      if (object == nullptr) {
        if (!resolved.targets_optional) {
          throw ScriptError(resolved.source, key.line, field,
                            describeScene(scene) + " has no object '" + target.object + "' (" + when.str() +
                                "; the scene's objects: " + objectNames(scene) + ")");
        }
        key.tip = target.written_tip;
        target.resolved = false;
        ++summary.kept_keyframes;
        auto& missing = summary.missing_objects;
        if (std::find(missing.begin(), missing.end(), target.object) == missing.end()) missing.push_back(target.object);
        continue;
      }
      if (object->frame != scene::ObjectFrame::kEye) {
        throw ScriptError(resolved.source, key.line, field,
                          "object '" + target.object + "' of " + describeScene(scene) + " is in the " +
                              scene::toString(object->frame) + " frame (" + when.str() +
                              "); keyframes can only be written on objects in the eye frame, because tips are in "
                              "the eye frame and the eye moves in the world");
      }
      auto surface = surfaces.find(target.object);
      if (surface == surfaces.end()) {
        surface = surfaces.emplace(target.object, scene::buildMesh(*object, scene::MeshFrame::kParent)).first;
      }
      key.tip = resolveSurfaceTip(surface->second, target.written_tip, target.height);
      target.resolved = true;
      ++summary.resolved_keyframes;
    }
  }
  *script = std::move(resolved);
  if (report != nullptr) *report = std::move(summary);
}

SurgeonScript applyScene(const scene::SceneDescription& scene, const SurgeonScript& script, SceneTargetReport* report) {
  ScriptDefinition definition = script.definition();
  applyScene(scene, &definition, report);
  return SurgeonScript(std::move(definition));
}

void applySceneTrocars(const scene::SceneDescription& scene, ScriptDefinition* script) {
  std::vector<Eigen::Vector3d> trocars;
  for (const InstrumentTrack& track : script->instruments) trocars.push_back(sceneTrocarForSlot(scene, track.slot));
  for (std::size_t i = 0; i < trocars.size(); ++i) {
    script->instruments[i].trocar = trocars[i];
    script->instruments[i].trocar_from_scene = false;
  }
  if (script->eye.from_scene) {
    script->eye.radius = scene.eye.radius;
    script->eye.rotation_center = scene.eye.centre_in_world;
  }
}

void applySceneTrocars(const scene::SceneDescription& scene, MarkerLayout* layout) {
  std::vector<Eigen::Vector3d> trocars;
  for (const InstrumentMarker& marker : layout->instruments) trocars.push_back(sceneTrocarForSlot(scene, marker.slot));
  for (std::size_t i = 0; i < trocars.size(); ++i) {
    layout->instruments[i].trocar = trocars[i];
    layout->instruments[i].trocar_from_scene = false;
  }
}

Eigen::Vector3d applyScene(const scene::SceneDescription& scene, MarkerLayout* layout) {
  const Eigen::Vector3d layout_centre = layout->rotation_center;
  applySceneTrocars(scene, layout);  // throws before anything changed
  layout->rotation_center = scene.eye.centre_in_world;
  return layout_centre;
}

SceneIdentity sceneIdentity(const scene::SceneDescription& scene) {
  SceneIdentity identity;
  identity.name = scene.name;
  identity.file = scene.source_file;
  identity.difficulty = scene.scenario ? scene.scenario->difficulty : "";
  identity.content_hash = identity.file.empty() ? 0 : scene::sceneContentHash(identity.file, identity.difficulty);
  return identity;
}

bool sameScene(const SceneIdentity& a, const SceneIdentity& b) {
  return a.file == b.file && a.difficulty == b.difficulty && a.content_hash == b.content_hash;
}

SurgeonScript applySceneTrocars(const scene::SceneDescription& scene, const SurgeonScript& script) {
  ScriptDefinition definition = script.definition();
  applySceneTrocars(scene, &definition);
  return SurgeonScript(std::move(definition));
}

SurgeonScript scenarioScript(const scene::SceneDescription& scene, const std::string& name) {
  const scene::SceneDescription scripted = scene::withScript(scene, name);
  ScriptDefinition definition;
  definition.name = scene.name + ":" + name;
  definition.source = scene.source_file + " (scenario.scripts." + name + ")";
  definition.playback = Playback::kOnce;
  definition.eye.radius = scene.eye.radius;
  // The scene's session plays in the scene's eye: the tracker and the VR part put its centre where the scene does.
  definition.eye.rotation_center = scene.eye.centre_in_world;
  constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
  for (const scene::InstrumentDescription& instrument : scripted.instruments) {
    if (instrument.path.empty()) continue;
    InstrumentTrack track;
    track.slot = scene::toString(instrument.slot);
    const scene::Trocar* trocar = scene.findTrocar(instrument.trocar);
    if (trocar == nullptr)
      throw std::invalid_argument("scene '" + scene.name + "': unknown trocar " + instrument.trocar);
    track.trocar = trocar->position_in_eye;
    std::vector<double> times;
    for (const scene::InstrumentWaypoint& waypoint : instrument.path) times.push_back(waypoint.t);
    if (instrument.tremor.amplitude > 0.0) {
      for (double t = 0.0; t < instrument.path.back().t; t += 0.005) times.push_back(t);
      std::sort(times.begin(), times.end());
      times.erase(std::unique(times.begin(), times.end(), [](double a, double b) { return b - a < 1e-9; }),
                  times.end());
    }
    for (double t : times) {
      const scene::InstrumentWaypoint sample = scene::samplePath(instrument.path, t);
      InstrumentKeyframe key;
      key.t = t;
      key.type = instrument.type;
      key.tip = sample.tip_in_eye + instrument.tremor.offset(t);
      key.jaw_angle = sample.jaw_angle_deg * kDegToRad;
      key.suction = sample.suction;
      key.cut_rate = sample.cut_rate_hz;
      track.keyframes.push_back(key);
    }
    definition.instruments.push_back(std::move(track));
  }
  return SurgeonScript(std::move(definition));
}

}  // namespace vrm_tracking
