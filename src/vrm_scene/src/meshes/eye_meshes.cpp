#include "vrm_scene/meshes/eye_meshes.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/primitive_meshes.h"

namespace vrm_sim {
namespace scene {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

// The caps are generated about +z; half a turn about x takes that pole to the posterior pole (0, 0, -1).
const Eigen::Matrix3d& capPoleToPosteriorPole() {
  static const Eigen::Matrix3d rotation = Eigen::AngleAxisd(kPi, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return rotation;
}

std::uint32_t nearestVertex(const TriangleMesh& mesh, const Eigen::Vector3d& point) {
  std::uint32_t nearest = 0;
  double nearest_distance = std::numeric_limits<double>::infinity();
  for (std::uint32_t i = 0; i < mesh.vertices.size(); ++i) {
    const double distance = (mesh.vertices[i] - point).squaredNorm();
    if (distance < nearest_distance) {
      nearest_distance = distance;
      nearest = i;
    }
  }
  return nearest;
}

}  // namespace

Eigen::Matrix3d posteriorPoleRotation(double offset_deg, double azimuth_deg) {
  // Ry(-offset) tilts (0, 0, -1) towards +x, then Rz turns it to the azimuth.
  return (Eigen::AngleAxisd(azimuth_deg * kDegToRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(-offset_deg * kDegToRad, Eigen::Vector3d::UnitY()))
      .toRotationMatrix();
}

TriangleMesh makeRetina(const RetinaParams& params) {
  if (!(params.coverage_deg > 0.0 && params.coverage_deg < 180.0)) {
    throw std::invalid_argument("retina: coverage_deg must lie in (0, 180)");
  }
  std::vector<std::uint32_t> rim;
  TriangleMesh mesh = makeSphericalCap(params.radius, params.coverage_deg * kDegToRad, params.ring_count,
                                       /*facing_centre=*/true, &rim);
  Eigen::Isometry3d to_eye = Eigen::Isometry3d::Identity();
  to_eye.linear() = capPoleToPosteriorPole();
  transformMesh(mesh, to_eye);
  mesh.name = "retina";
  mesh.fixed_vertices = rim;
  return mesh;
}

TriangleMesh makeMembrane(const MembraneParams& params) {
  const double membrane_radius = params.retina_radius - params.height_above_retina;
  if (!(params.height_above_retina >= 0.0) || !(membrane_radius > 0.0)) {
    throw std::invalid_argument("membrane: height_above_retina must lie in [0, retina_radius)");
  }
  if (!(params.diameter > 0.0)) throw std::invalid_argument("membrane: diameter must be positive");
  const double patch_polar_angle = 0.5 * params.diameter / membrane_radius;
  if (patch_polar_angle >= 0.5 * kPi) {
    throw std::invalid_argument("membrane: diameter must be smaller than half the circumference of its sphere");
  }
  if (params.adhesion_point_count < 0) throw std::invalid_argument("membrane: adhesion_point_count must be >= 0");
  if (!(params.adhesion_ring_fraction >= 0.0 && params.adhesion_ring_fraction <= 1.0)) {
    throw std::invalid_argument("membrane: adhesion_ring_fraction must lie in [0, 1]");
  }
  TriangleMesh mesh = makeSphericalCap(membrane_radius, patch_polar_angle, params.ring_count, /*facing_centre=*/true);

  // Adhesion points are chosen in the cap's own frame (pole at +z), before it is moved into place.
  std::vector<std::uint32_t> adhesion;
  if (params.adhesion_point_count > 0) adhesion.push_back(0);  // the pole vertex is the patch centre
  const int ring_points = params.adhesion_point_count - 1;
  const double ring_polar = params.adhesion_ring_fraction * patch_polar_angle;
  for (int k = 0; k < ring_points; ++k) {
    const double azimuth = 2.0 * kPi * k / ring_points;
    const Eigen::Vector3d ideal =
        membrane_radius * Eigen::Vector3d(std::sin(ring_polar) * std::cos(azimuth),
                                          std::sin(ring_polar) * std::sin(azimuth), std::cos(ring_polar));
    adhesion.push_back(nearestVertex(mesh, ideal));
  }
  if (!(params.adhesion_disc_radius >= 0.0)) throw std::invalid_argument("membrane: adhesion_disc_radius must be >= 0");

  Eigen::Isometry3d to_eye = Eigen::Isometry3d::Identity();
  to_eye.linear() =
      posteriorPoleRotation(params.centre_offset_deg, params.centre_azimuth_deg) * capPoleToPosteriorPole();
  transformMesh(mesh, to_eye);
  const Eigen::Vector3d disc =
      membrane_radius * posteriorPoleRotation(params.adhesion_disc_offset_deg, params.adhesion_disc_azimuth_deg) *
      Eigen::Vector3d(0.0, 0.0, -1.0);
  for (std::uint32_t i = 0; i < mesh.vertices.size(); ++i) {
    if (params.adhere_everywhere ||
        (params.adhesion_disc_radius > 0.0 && (mesh.vertices[i] - disc).norm() <= params.adhesion_disc_radius)) {
      adhesion.push_back(i);
    }
  }
  std::sort(adhesion.begin(), adhesion.end());
  adhesion.erase(std::unique(adhesion.begin(), adhesion.end()), adhesion.end());
  mesh.name = "membrane";
  mesh.fixed_vertices = adhesion;
  return mesh;
}

}  // namespace scene
}  // namespace vrm_sim
