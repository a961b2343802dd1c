#include "vrm_scene/meshes/instrument_meshes.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/surface_builders.h"

namespace vrm_sim {
namespace scene {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

void requirePositive(const char* instrument, const char* field, double value) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw std::invalid_argument(std::string(instrument) + ": " + field + " must be a positive finite number");
  }
}

void checkShaft(const char* instrument, const ShaftParams& shaft) {
  requirePositive(instrument, "shaft.diameter", shaft.diameter);
  requirePositive(instrument, "shaft.length", shaft.length);
  if (shaft.segments < 3) throw std::invalid_argument(std::string(instrument) + ": shaft.segments must be >= 3");
}

// A ring right-handed about `direction` (which must be perpendicular to y): u = y x direction, v = y.
std::vector<Eigen::Vector3d> ringAround(const Eigen::Vector3d& centre, const Eigen::Vector3d& direction, double radius,
                                        int segments, double first_angle = 0.0) {
  const Eigen::Vector3d v = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d u = v.cross(direction).normalized();
  std::vector<Eigen::Vector3d> ring;
  for (int i = 0; i < segments; ++i) {
    const double angle = first_angle + 2.0 * kPi * i / segments;
    ring.push_back(centre + radius * (std::cos(angle) * u + std::sin(angle) * v));
  }
  return ring;
}

// Hexahedron from its 8 corners (bit 0: x side, bit 1: y side, bit 2: z side); must be convex.
TriangleMesh makeConvexHexahedron(const std::array<Eigen::Vector3d, 8>& corners) {
  TriangleMesh mesh;
  mesh.vertices.assign(corners.begin(), corners.end());
  mesh.triangles = {{0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}, {0, 4, 5}, {0, 5, 1},
                    {2, 3, 7}, {2, 7, 6}, {0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}};
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& corner : corners) centroid += corner / 8.0;
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    if (triangleAreaVector(mesh, i).dot(mesh.vertices[mesh.triangles[i][0]] - centroid) < 0.0) {
      std::swap(mesh.triangles[i][1], mesh.triangles[i][2]);
    }
  }
  return mesh;
}

}  // namespace

TriangleMesh makeShaft(const ShaftParams& params, double distal_z) {
  checkShaft("shaft", params);
  if (!(distal_z > -params.length)) throw std::invalid_argument("shaft: distal end must lie beyond -length");
  const double radius = 0.5 * params.diameter;
  TubeRings tube;
  tube.rings = {ringAround(Eigen::Vector3d(0, 0, -params.length), Eigen::Vector3d::UnitZ(), radius, params.segments),
                ringAround(Eigen::Vector3d(0, 0, distal_z), Eigen::Vector3d::UnitZ(), radius, params.segments)};
  tube.start_pole = Eigen::Vector3d(0.0, 0.0, -params.length);
  tube.end_pole = Eigen::Vector3d(0.0, 0.0, distal_z);
  TriangleMesh mesh = makeTube(tube);
  mesh.name = "shaft";
  return mesh;
}

TriangleMesh makeLightPipe(const LightPipeParams& params) {
  checkShaft("light_pipe", params.shaft);
  requirePositive("light_pipe", "tip_length", params.tip_length);
  if (params.tip_length >= params.shaft.length) throw std::invalid_argument("light_pipe: tip_length >= shaft length");
  if (params.tip_rings < 1) throw std::invalid_argument("light_pipe: tip_rings must be >= 1");
  const double radius = 0.5 * params.shaft.diameter;
  const Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  TubeRings tube;
  tube.rings.push_back(ringAround(-params.shaft.length * axis, axis, radius, params.shaft.segments));
  // The dome's rings: an ellipse quadrant from the shaft wall (angle 0) towards the tip pole (angle 90 deg).
  for (int k = 0; k < params.tip_rings; ++k) {
    const double angle = 0.5 * kPi * k / params.tip_rings;
    const double z = -params.tip_length + params.tip_length * std::sin(angle);
    tube.rings.push_back(ringAround(z * axis, axis, radius * std::cos(angle), params.shaft.segments));
  }
  tube.start_pole = -params.shaft.length * axis;
  tube.end_pole = Eigen::Vector3d::Zero();
  TriangleMesh mesh = makeTube(tube);
  mesh.name = "light_pipe";
  return mesh;
}

TriangleMesh makeLaserProbe(const LaserProbeParams& params) {
  checkShaft("laser_probe", params.shaft);
  if (!(params.fibre_diameter > 0.0) || !(params.fibre_diameter <= params.shaft.diameter)) {
    throw std::invalid_argument("laser_probe: fibre_diameter must be positive and fit in the shaft");
  }
  if (!(params.numerical_aperture > 0.0) || !(params.numerical_aperture < 1.0)) {
    throw std::invalid_argument("laser_probe: numerical_aperture must lie in (0, 1)");
  }
  if (!(params.power_mw > 0.0) || !(params.duration_ms > 0.0) || !(params.interval_ms >= 0.0)) {
    throw std::invalid_argument("laser_probe: power_mw and duration_ms must be positive, interval_ms >= 0");
  }
  TriangleMesh mesh = makeShaft(params.shaft, 0.0);  // the flat, polished fibre end at the tip
  mesh.name = "laser_probe";
  return mesh;
}

TriangleMesh makeForcepsJaw(const ForcepsParams& params, ForcepsJaw jaw) {
  requirePositive("forceps", "jaw_length", params.jaw_length);
  requirePositive("forceps", "jaw_base_width", params.jaw_base_width);
  requirePositive("forceps", "jaw_tip_width", params.jaw_tip_width);
  requirePositive("forceps", "jaw_thickness", params.jaw_thickness);
  if (!(params.jaw_angle_deg >= 0.0 && params.jaw_angle_deg <= 180.0)) {
    throw std::invalid_argument("forceps: jaw_angle_deg must lie in [0, 180]");
  }
  // In the hinge frame the jaw runs from z = 0 to z = jaw_length; its inner face (y = 0) meets the other jaw.
  const double side = jaw == ForcepsJaw::kUpper ? 1.0 : -1.0;
  std::array<Eigen::Vector3d, 8> corners;
  for (int corner = 0; corner < 8; ++corner) {
    const bool at_tip = corner & 4;
    const double half_width = 0.5 * (at_tip ? params.jaw_tip_width : params.jaw_base_width);
    corners[corner] =
        Eigen::Vector3d((corner & 1) ? half_width : -half_width, (corner & 2) ? side * params.jaw_thickness : 0.0,
                        at_tip ? params.jaw_length : 0.0);
  }
  // Opening rotates each jaw by half the angle about the hinge's x axis, away from the other jaw.
  const double half_opening = 0.5 * params.jaw_angle_deg * kDegToRad;
  Eigen::Isometry3d hinge_to_instrument = Eigen::Isometry3d::Identity();
  hinge_to_instrument.translation() = Eigen::Vector3d(0.0, 0.0, -params.jaw_length);
  hinge_to_instrument.linear() = Eigen::AngleAxisd(-side * half_opening, Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (auto& corner : corners) corner = hinge_to_instrument * corner;
  TriangleMesh mesh = makeConvexHexahedron(corners);
  mesh.name = jaw == ForcepsJaw::kUpper ? "forceps_upper_jaw" : "forceps_lower_jaw";
  return mesh;
}

ForcepsMeshes makeForcepsParts(const ForcepsParams& params) {
  checkShaft("forceps", params.shaft);
  if (params.jaw_length >= params.shaft.length) throw std::invalid_argument("forceps: jaw_length >= shaft length");
  ForcepsMeshes parts;
  parts.shaft = makeShaft(params.shaft, -params.jaw_length);
  parts.shaft.name = "forceps_shaft";
  parts.upper_jaw = makeForcepsJaw(params, ForcepsJaw::kUpper);
  parts.lower_jaw = makeForcepsJaw(params, ForcepsJaw::kLower);
  return parts;
}

TriangleMesh makeForceps(const ForcepsParams& params) {
  ForcepsMeshes parts = makeForcepsParts(params);
  TriangleMesh mesh = std::move(parts.shaft);
  appendMesh(mesh, parts.upper_jaw);
  appendMesh(mesh, parts.lower_jaw);
  mesh.name = "forceps";
  return mesh;
}

TriangleMesh makeVitrector(const VitrectorParams& params) {
  checkShaft("vitrector", params.shaft);
  const double radius = 0.5 * params.shaft.diameter;
  requirePositive("vitrector", "port_distance_from_tip", params.port_distance_from_tip);
  requirePositive("vitrector", "port_length", params.port_length);
  requirePositive("vitrector", "port_depth", params.port_depth);
  if (params.port_depth >= radius) throw std::invalid_argument("vitrector: port_depth must be below the shaft radius");
  if (!(params.port_width_deg > 0.0 && params.port_width_deg < 180.0)) {
    throw std::invalid_argument("vitrector: port_width_deg must lie in (0, 180)");
  }
  const double port_distal_z = -params.port_distance_from_tip;
  const double port_proximal_z = port_distal_z - params.port_length;
  if (port_proximal_z <= -params.shaft.length) throw std::invalid_argument("vitrector: port beyond the shaft");

  // The pocket's walls slope over a tenth of the port size so that no triangle of the grid degenerates.
  const double wall_z = 0.1 * params.port_length;
  const std::vector<double> ring_z = {-params.shaft.length,   port_proximal_z, port_proximal_z + wall_z,
                                      port_distal_z - wall_z, port_distal_z,   0.0};
  const double half_width = 0.5 * params.port_width_deg * kDegToRad;
  const double wall_angle = 0.1 * half_width;
  // Angles: the port edges and its floor samples first, then the rest of the circle at about the shaft spacing.
  std::vector<double> angles = {-half_width, -half_width + wall_angle};
  const int floor_steps =
      std::max(2, static_cast<int>(std::ceil((2.0 * half_width) / (2.0 * kPi / params.shaft.segments))));
  for (int k = 1; k < floor_steps; ++k) {
    angles.push_back(-half_width + wall_angle + (2.0 * half_width - 2.0 * wall_angle) * k / floor_steps);
  }
  angles.push_back(half_width - wall_angle);
  angles.push_back(half_width);
  const std::size_t floor_begin = 1, floor_end = angles.size() - 2;  // inclusive range of floor angle indices
  const double outside_span = 2.0 * kPi - 2.0 * half_width;
  const int outside_steps =
      std::max(3, static_cast<int>(std::ceil(outside_span / (2.0 * kPi / params.shaft.segments))));
  for (int k = 1; k < outside_steps; ++k) angles.push_back(half_width + outside_span * k / outside_steps);

  TubeRings tube;
  for (std::size_t ring = 0; ring < ring_z.size(); ++ring) {
    const bool on_floor_level = ring == 2 || ring == 3;
    std::vector<Eigen::Vector3d> vertices;
    for (std::size_t i = 0; i < angles.size(); ++i) {
      const bool in_pocket = on_floor_level && i >= floor_begin && i <= floor_end;
      const double r = in_pocket ? radius - params.port_depth : radius;
      vertices.emplace_back(r * std::cos(angles[i]), r * std::sin(angles[i]), ring_z[ring]);
    }
    tube.rings.push_back(vertices);
  }
  tube.start_pole = Eigen::Vector3d(0.0, 0.0, -params.shaft.length);
  tube.end_pole = Eigen::Vector3d::Zero();
  TriangleMesh mesh = makeTube(tube);
  mesh.name = "vitrector";
  return mesh;
}

TriangleMesh makeNeedle(const NeedleParams& params) {
  checkShaft("needle", params.shaft);
  if (!(params.bevel_angle_deg > 0.0 && params.bevel_angle_deg <= 90.0)) {
    throw std::invalid_argument("needle: bevel_angle_deg must lie in (0, 90]");
  }
  const double radius = 0.5 * params.shaft.diameter;
  const double bevel_slope = 1.0 / std::tan(params.bevel_angle_deg * kDegToRad);  // dz per dx across the bevel
  if (2.0 * radius * bevel_slope >= params.shaft.length) throw std::invalid_argument("needle: bevel longer than shaft");
  // Bevel plane z = -(x + r) * cot(angle): through the point (-r, 0, 0), down to the heel at x = +r. The first ring
  // vertex sits at angle pi so that the point itself is a vertex.
  const Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  std::vector<Eigen::Vector3d> heel_ring =
      ringAround(Eigen::Vector3d::Zero(), axis, radius, params.shaft.segments, kPi);
  for (auto& vertex : heel_ring) vertex.z() = -(vertex.x() + radius) * bevel_slope;
  TubeRings tube;
  tube.rings = {ringAround(-params.shaft.length * axis, axis, radius, params.shaft.segments, kPi), heel_ring};
  tube.start_pole = -params.shaft.length * axis;
  tube.end_pole = Eigen::Vector3d(0.0, 0.0, -radius * bevel_slope);  // the bevel ellipse's centre, in its plane
  TriangleMesh mesh = makeTube(tube);
  mesh.name = "needle";
  return mesh;
}

Eigen::Vector3d needlePoint(const NeedleParams& params) { return {-0.5 * params.shaft.diameter, 0.0, 0.0}; }

namespace {

struct HookPath {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3d> directions;
};

// Centre line of the hook wire from the shaft's end (at z = 0 before the final shift).
HookPath hookWirePath(const HookParams& params) {
  HookPath path;
  const auto add = [&path](const Eigen::Vector3d& point, const Eigen::Vector3d& direction) {
    path.points.push_back(point);
    path.directions.push_back(direction);
  };
  add(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
  const double bend = params.bend_angle_deg * kDegToRad;
  for (int k = 0; k <= params.path_samples_per_bend; ++k) {
    const double angle = bend * k / params.path_samples_per_bend;
    add(Eigen::Vector3d(params.bend_radius * (1.0 - std::cos(angle)), 0.0,
                        params.neck_length + params.bend_radius * std::sin(angle)),
        Eigen::Vector3d(std::sin(angle), 0.0, std::cos(angle)));
  }
  add(path.points.back() + params.hook_length * path.directions.back(), path.directions.back());
  return path;
}

void checkHook(const HookParams& params) {
  checkShaft("hook", params.shaft);
  requirePositive("hook", "hook_diameter", params.hook_diameter);
  requirePositive("hook", "bend_radius", params.bend_radius);
  requirePositive("hook", "hook_length", params.hook_length);
  requirePositive("hook", "neck_length", params.neck_length);
  if (params.hook_diameter > params.shaft.diameter) throw std::invalid_argument("hook: wire thicker than the shaft");
  if (params.bend_radius <= 0.5 * params.hook_diameter) {
    throw std::invalid_argument("hook: bend_radius must exceed the wire radius (else the wire folds into itself)");
  }
  if (!(params.bend_angle_deg > 0.0 && params.bend_angle_deg <= 180.0)) {
    throw std::invalid_argument("hook: bend_angle_deg must lie in (0, 180]");
  }
  if (params.path_samples_per_bend < 1) throw std::invalid_argument("hook: path_samples_per_bend must be >= 1");
}

TriangleMesh makeUnshiftedHook(const HookParams& params) {
  checkHook(params);
  const Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  const int segments = params.shaft.segments;
  TubeRings tube;
  tube.rings.push_back(ringAround(-params.shaft.length * axis, axis, 0.5 * params.shaft.diameter, segments));
  tube.rings.push_back(ringAround(Eigen::Vector3d::Zero(), axis, 0.5 * params.shaft.diameter, segments));
  const HookPath path = hookWirePath(params);
  for (std::size_t k = 0; k < path.points.size(); ++k) {
    tube.rings.push_back(ringAround(path.points[k], path.directions[k], 0.5 * params.hook_diameter, segments));
  }
  tube.start_pole = -params.shaft.length * axis;
  tube.end_pole = path.points.back();
  return makeTube(tube);
}

}  // namespace

TriangleMesh makeHook(const HookParams& params) {
  TriangleMesh mesh = makeUnshiftedHook(params);
  // The frame convention puts the most distal point of the instrument in z = 0.
  const double max_z = boundingBox(mesh).max().z();
  for (auto& vertex : mesh.vertices) vertex.z() -= max_z;
  mesh.name = "hook";
  return mesh;
}

Eigen::Vector3d hookTipPoint(const HookParams& params) {
  const double max_z = boundingBox(makeUnshiftedHook(params)).max().z();
  return hookWirePath(params).points.back() - Eigen::Vector3d(0.0, 0.0, max_z);
}

}  // namespace scene
}  // namespace vrm_sim
