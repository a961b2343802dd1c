#include "vrm_scene/meshes/mesh_utils.h"

#include <stdexcept>

namespace vrm_sim {
namespace scene {

double signedVolume(const TriangleMesh& mesh) {
  double six_volume = 0.0;
  for (const auto& triangle : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices[triangle[0]];
    const Eigen::Vector3d& b = mesh.vertices[triangle[1]];
    const Eigen::Vector3d& c = mesh.vertices[triangle[2]];
    six_volume += a.dot(b.cross(c));
  }
  return six_volume / 6.0;
}

Eigen::Vector3d triangleAreaVector(const TriangleMesh& mesh, std::size_t triangle_index) {
  const auto& triangle = mesh.triangles[triangle_index];
  const Eigen::Vector3d& a = mesh.vertices[triangle[0]];
  return (mesh.vertices[triangle[1]] - a).cross(mesh.vertices[triangle[2]] - a);
}

double surfaceArea(const TriangleMesh& mesh) {
  double twice_area = 0.0;
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) twice_area += triangleAreaVector(mesh, i).norm();
  return 0.5 * twice_area;
}

Eigen::AlignedBox3d boundingBox(const TriangleMesh& mesh) {
  Eigen::AlignedBox3d box;
  for (const auto& vertex : mesh.vertices) box.extend(vertex);
  return box;
}

void transformMesh(TriangleMesh& mesh, const Eigen::Isometry3d& transform) {
  for (auto& vertex : mesh.vertices) vertex = transform * vertex;
  for (auto& normal : mesh.normals) normal = transform.linear() * normal;
}

void scaleMesh(TriangleMesh& mesh, double factor) {
  if (!(factor > 0.0)) throw std::invalid_argument("scaleMesh: the factor must be positive");
  for (auto& vertex : mesh.vertices) vertex *= factor;
}

void appendMesh(TriangleMesh& mesh, const TriangleMesh& part) {
  const bool keep_normals = (mesh.vertices.empty() || !mesh.normals.empty()) && !part.normals.empty();
  const auto offset = static_cast<std::uint32_t>(mesh.vertices.size());
  if (!keep_normals) mesh.normals.clear();
  mesh.vertices.insert(mesh.vertices.end(), part.vertices.begin(), part.vertices.end());
  if (keep_normals) mesh.normals.insert(mesh.normals.end(), part.normals.begin(), part.normals.end());
  for (const auto& triangle : part.triangles) {
    mesh.triangles.push_back({triangle[0] + offset, triangle[1] + offset, triangle[2] + offset});
  }
  for (std::uint32_t fixed : part.fixed_vertices) mesh.fixed_vertices.push_back(fixed + offset);
}

void flipOrientation(TriangleMesh& mesh) {
  for (auto& triangle : mesh.triangles) std::swap(triangle[1], triangle[2]);
  for (auto& normal : mesh.normals) normal = -normal;
}

void computeVertexNormals(TriangleMesh& mesh) {
  mesh.normals.assign(mesh.vertices.size(), Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const Eigen::Vector3d area_vector = triangleAreaVector(mesh, i);
    for (std::uint32_t vertex : mesh.triangles[i]) mesh.normals[vertex] += area_vector;
  }
  for (auto& normal : mesh.normals) {
    const double length = normal.norm();
    if (length > 0.0) normal /= length;
  }
}

Eigen::Matrix3d rotationFromRpy(const Eigen::Vector3d& roll_pitch_yaw) {
  return (Eigen::AngleAxisd(roll_pitch_yaw.z(), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(roll_pitch_yaw.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_pitch_yaw.x(), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

}  // namespace scene
}  // namespace vrm_sim
