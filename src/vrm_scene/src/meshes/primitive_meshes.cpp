#include "vrm_scene/meshes/primitive_meshes.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/surface_builders.h"

namespace vrm_sim {
namespace scene {
namespace {

constexpr double kPi = 3.14159265358979323846;

void requirePositive(const char* generator, const char* field, double value) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw std::invalid_argument(std::string(generator) + ": " + field + " must be a positive finite number");
  }
}
void requireAtLeast(const char* generator, const char* field, int value, int minimum) {
  if (value < minimum) {
    throw std::invalid_argument(std::string(generator) + ": " + field + " must be at least " + std::to_string(minimum));
  }
}

std::vector<Eigen::Vector3d> circle(double radius, double z, int segments) {
  std::vector<Eigen::Vector3d> ring;
  ring.reserve(segments);
  for (int i = 0; i < segments; ++i) {
    const double angle = 2.0 * kPi * i / segments;
    ring.emplace_back(radius * std::cos(angle), radius * std::sin(angle), z);
  }
  return ring;
}

// Box-like hexahedra and other convex solids: orient each triangle away from the centroid.
void orientOutwardConvex(TriangleMesh& mesh) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& vertex : mesh.vertices) centroid += vertex;
  centroid /= static_cast<double>(mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const Eigen::Vector3d to_triangle = mesh.vertices[mesh.triangles[i][0]] - centroid;
    if (triangleAreaVector(mesh, i).dot(to_triangle) < 0.0) std::swap(mesh.triangles[i][1], mesh.triangles[i][2]);
  }
}

}  // namespace

TriangleMesh makeSphericalCap(double radius, double max_polar_angle, int ring_count, bool facing_centre,
                              std::vector<std::uint32_t>* rim_vertices) {
  requirePositive("spherical cap", "radius", radius);
  requireAtLeast("spherical cap", "ring_count", ring_count, 1);
  if (!(max_polar_angle > 0.0 && max_polar_angle <= kPi)) {
    throw std::invalid_argument("spherical cap: the polar angle must lie in (0, pi]");
  }
  const double polar_step = max_polar_angle / ring_count;
  TriangleMesh mesh;
  std::vector<AngularRing> rings;
  rings.push_back({0, 1, 0.0});
  mesh.vertices.emplace_back(0.0, 0.0, radius);
  for (int k = 1; k <= ring_count; ++k) {
    const double polar = k * polar_step;
    AngularRing ring;
    ring.first_vertex = static_cast<std::uint32_t>(mesh.vertices.size());
    if (k == ring_count && max_polar_angle == kPi) {
      ring.vertex_count = 1;
      mesh.vertices.emplace_back(0.0, 0.0, -radius);
      rings.push_back(ring);
      break;
    }
    // Vertex count proportional to the ring's circumference keeps the triangles close to equilateral.
    const double sin_polar = std::sin(polar);
    ring.vertex_count = static_cast<std::uint32_t>(std::max(3L, std::lround(2.0 * kPi * sin_polar / polar_step)));
    ring.angle_offset = 0.5 * (k % 2);
    for (std::uint32_t i = 0; i < ring.vertex_count; ++i) {
      const double azimuth = 2.0 * kPi * (i + ring.angle_offset) / ring.vertex_count;
      mesh.vertices.emplace_back(radius * sin_polar * std::cos(azimuth), radius * sin_polar * std::sin(azimuth),
                                 radius * std::cos(polar));
    }
    rings.push_back(ring);
  }
  mesh.triangles = triangulateConcentricRings(rings);
  if (facing_centre) flipOrientation(mesh);
  if (rim_vertices != nullptr) {
    rim_vertices->clear();
    const AngularRing& rim = rings.back();
    if (rim.vertex_count > 1) {
      for (std::uint32_t i = 0; i < rim.vertex_count; ++i) rim_vertices->push_back(rim.first_vertex + i);
    }
  }
  return mesh;
}

TriangleMesh makeSphere(const SphereParams& params) {
  requireAtLeast("sphere", "ring_count", params.ring_count, 2);
  TriangleMesh mesh = makeSphericalCap(params.radius, kPi, params.ring_count, false);
  mesh.name = "sphere";
  return mesh;
}

TriangleMesh makeBox(const BoxParams& params) {
  for (int axis = 0; axis < 3; ++axis) requirePositive("box", "size", params.size[axis]);
  TriangleMesh mesh;
  mesh.name = "box";
  const Eigen::Vector3d half = 0.5 * params.size;
  for (int corner = 0; corner < 8; ++corner) {  // bit 0: x, bit 1: y, bit 2: z
    mesh.vertices.emplace_back((corner & 1) ? half.x() : -half.x(), (corner & 2) ? half.y() : -half.y(),
                               (corner & 4) ? half.z() : -half.z());
  }
  mesh.triangles = {{0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}, {0, 4, 5}, {0, 5, 1},
                    {2, 3, 7}, {2, 7, 6}, {0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}};
  orientOutwardConvex(mesh);
  return mesh;
}

TriangleMesh makeCylinder(const CylinderParams& params) {
  requirePositive("cylinder", "radius", params.radius);
  requirePositive("cylinder", "length", params.length);
  requireAtLeast("cylinder", "segments", params.segments, 3);
  const double half = 0.5 * params.length;
  TubeRings tube;
  tube.rings = {circle(params.radius, -half, params.segments), circle(params.radius, half, params.segments)};
  tube.start_pole = Eigen::Vector3d(0.0, 0.0, -half);
  tube.end_pole = Eigen::Vector3d(0.0, 0.0, half);
  TriangleMesh mesh = makeTube(tube);
  mesh.name = "cylinder";
  return mesh;
}

TriangleMesh makeCapsule(const CapsuleParams& params) {
  requirePositive("capsule", "radius", params.radius);
  if (!(params.length >= 0.0)) throw std::invalid_argument("capsule: length must be non-negative");
  requireAtLeast("capsule", "segments", params.segments, 3);
  requireAtLeast("capsule", "cap_rings", params.cap_rings, 1);
  const double half = 0.5 * params.length;
  TubeRings tube;
  for (int k = 1; k <= params.cap_rings; ++k) {  // bottom cap, from the pole towards the equator
    const double polar = 0.5 * kPi * k / params.cap_rings;
    tube.rings.push_back(
        circle(params.radius * std::sin(polar), -half - params.radius * std::cos(polar), params.segments));
  }
  const int first_top = params.length > 0.0 ? params.cap_rings : params.cap_rings - 1;  // no duplicate equator
  for (int k = first_top; k >= 1; --k) {
    const double polar = 0.5 * kPi * k / params.cap_rings;
    tube.rings.push_back(
        circle(params.radius * std::sin(polar), half + params.radius * std::cos(polar), params.segments));
  }
  tube.start_pole = Eigen::Vector3d(0.0, 0.0, -half - params.radius);
  tube.end_pole = Eigen::Vector3d(0.0, 0.0, half + params.radius);
  TriangleMesh mesh = makeTube(tube);
  mesh.name = "capsule";
  return mesh;
}

TriangleMesh makeCone(const ConeParams& params) {
  requirePositive("cone", "radius", params.radius);
  requirePositive("cone", "height", params.height);
  requireAtLeast("cone", "segments", params.segments, 3);
  TubeRings tube;
  tube.rings = {circle(params.radius, 0.0, params.segments)};
  tube.start_pole = Eigen::Vector3d::Zero();
  tube.end_pole = Eigen::Vector3d(0.0, 0.0, params.height);
  TriangleMesh mesh = makeTube(tube);
  mesh.name = "cone";
  return mesh;
}

TriangleMesh makeTorus(const TorusParams& params) {
  requirePositive("torus", "major_radius", params.major_radius);
  requirePositive("torus", "minor_radius", params.minor_radius);
  if (params.minor_radius >= params.major_radius) {
    throw std::invalid_argument("torus: minor_radius must be smaller than major_radius (no self-intersection)");
  }
  requireAtLeast("torus", "major_segments", params.major_segments, 3);
  requireAtLeast("torus", "minor_segments", params.minor_segments, 3);
  TriangleMesh mesh;
  mesh.name = "torus";
  const int major = params.major_segments, minor = params.minor_segments;
  for (int i = 0; i < major; ++i) {
    const double u = 2.0 * kPi * i / major;
    const Eigen::Vector3d radial(std::cos(u), std::sin(u), 0.0);
    for (int j = 0; j < minor; ++j) {
      const double v = 2.0 * kPi * j / minor;
      mesh.vertices.push_back((params.major_radius + params.minor_radius * std::cos(v)) * radial +
                              params.minor_radius * std::sin(v) * Eigen::Vector3d::UnitZ());
    }
  }
  const auto index = [major, minor](int i, int j) {
    return static_cast<std::uint32_t>((i % major) * minor + j % minor);
  };
  // d/du x d/dv points away from the tube's centre line (e_u x e_z = e_radial), so (a, b, c) faces outward.
  for (int i = 0; i < major; ++i) {
    for (int j = 0; j < minor; ++j) {
      const std::uint32_t a = index(i, j), b = index(i + 1, j), c = index(i + 1, j + 1), d = index(i, j + 1);
      mesh.triangles.push_back({a, b, c});
      mesh.triangles.push_back({a, c, d});
    }
  }
  return mesh;
}

TriangleMesh makeDisc(const DiscParams& params) {
  requirePositive("disc", "radius", params.radius);
  requireAtLeast("disc", "ring_count", params.ring_count, 1);
  TriangleMesh mesh;
  mesh.name = "disc";
  std::vector<AngularRing> rings{{0, 1, 0.0}};
  mesh.vertices.emplace_back(0.0, 0.0, 0.0);
  for (int k = 1; k <= params.ring_count; ++k) {
    AngularRing ring;
    ring.first_vertex = static_cast<std::uint32_t>(mesh.vertices.size());
    ring.vertex_count = static_cast<std::uint32_t>(std::lround(2.0 * kPi * k));
    ring.angle_offset = 0.5 * (k % 2);
    const double radius = params.radius * k / params.ring_count;
    for (std::uint32_t i = 0; i < ring.vertex_count; ++i) {
      const double angle = 2.0 * kPi * (i + ring.angle_offset) / ring.vertex_count;
      mesh.vertices.emplace_back(radius * std::cos(angle), radius * std::sin(angle), 0.0);
    }
    rings.push_back(ring);
  }
  mesh.triangles = triangulateConcentricRings(rings);  // e_radial x e_phi = +z
  return mesh;
}

TriangleMesh makePlane(const PlaneParams& params) {
  requirePositive("plane", "size_x", params.size_x);
  requirePositive("plane", "size_y", params.size_y);
  requireAtLeast("plane", "subdivisions", params.subdivisions, 1);
  TriangleMesh mesh;
  mesh.name = "plane";
  const int cells = params.subdivisions;
  for (int j = 0; j <= cells; ++j) {
    for (int i = 0; i <= cells; ++i) {
      mesh.vertices.emplace_back(params.size_x * (static_cast<double>(i) / cells - 0.5),
                                 params.size_y * (static_cast<double>(j) / cells - 0.5), 0.0);
    }
  }
  const auto index = [cells](int i, int j) { return static_cast<std::uint32_t>(j * (cells + 1) + i); };
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) {
      mesh.triangles.push_back({index(i, j), index(i + 1, j), index(i + 1, j + 1)});
      mesh.triangles.push_back({index(i, j), index(i + 1, j + 1), index(i, j + 1)});
    }
  }
  return mesh;
}

}  // namespace scene
}  // namespace vrm_sim
