#include "vrm_scene/meshes/mesh_validation.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "vrm_scene/meshes/mesh_utils.h"

namespace vrm_sim {
namespace scene {
namespace {

bool isFinite(const Eigen::Vector3d& vertex) { return vertex.allFinite(); }

bool isDegenerate(const TriangleMesh& mesh, const std::array<std::uint32_t, 3>& triangle,
                  double relative_area_tolerance) {
  if (triangle[0] == triangle[1] || triangle[1] == triangle[2] || triangle[0] == triangle[2]) return true;
  const Eigen::Vector3d& a = mesh.vertices[triangle[0]];
  const Eigen::Vector3d& b = mesh.vertices[triangle[1]];
  const Eigen::Vector3d& c = mesh.vertices[triangle[2]];
  const double longest_squared = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  return (b - a).cross(c - a).norm() <= relative_area_tolerance * longest_squared;
}

bool indicesInRange(const TriangleMesh& mesh, const std::array<std::uint32_t, 3>& triangle) {
  return triangle[0] < mesh.vertices.size() && triangle[1] < mesh.vertices.size() && triangle[2] < mesh.vertices.size();
}

// For each vertex, the first vertex within `distance` (exact equality for 0). Grid hashing with the cell size of
// the join distance finds all candidates in the 27 neighbouring cells.
std::vector<std::uint32_t> findRepresentatives(const std::vector<Eigen::Vector3d>& vertices, double distance) {
  std::vector<std::uint32_t> representative(vertices.size());
  if (distance <= 0.0) {
    std::map<std::array<double, 3>, std::uint32_t> first_at_position;
    for (std::uint32_t i = 0; i < vertices.size(); ++i) {
      representative[i] =
          first_at_position.emplace(std::array<double, 3>{vertices[i].x(), vertices[i].y(), vertices[i].z()}, i)
              .first->second;
    }
    return representative;
  }
  std::map<std::array<long long, 3>, std::vector<std::uint32_t>> cells;
  const auto cell_of = [distance](const Eigen::Vector3d& vertex) {
    return std::array<long long, 3>{static_cast<long long>(std::floor(vertex.x() / distance)),
                                    static_cast<long long>(std::floor(vertex.y() / distance)),
                                    static_cast<long long>(std::floor(vertex.z() / distance))};
  };
  for (std::uint32_t i = 0; i < vertices.size(); ++i) {
    const auto cell = cell_of(vertices[i]);
    representative[i] = i;
    for (long long dx = -1; dx <= 1 && representative[i] == i; ++dx) {
      for (long long dy = -1; dy <= 1 && representative[i] == i; ++dy) {
        for (long long dz = -1; dz <= 1 && representative[i] == i; ++dz) {
          const auto found = cells.find({cell[0] + dx, cell[1] + dy, cell[2] + dz});
          if (found == cells.end()) continue;
          for (std::uint32_t candidate : found->second) {
            if ((vertices[candidate] - vertices[i]).norm() <= distance) {
              representative[i] = candidate;
              break;
            }
          }
        }
      }
    }
    if (representative[i] == i) cells[cell].push_back(i);
  }
  return representative;
}

}  // namespace

bool MeshReport::isUsable() const {
  return vertex_count > 0 && triangle_count > 0 && non_finite_vertices == 0 && out_of_range_triangles == 0 &&
         out_of_range_fixed_vertices == 0 && normal_count_mismatch == 0;
}

bool MeshReport::isClean() const {
  return isUsable() && degenerate_triangles == 0 && duplicate_vertices == 0 && unreferenced_vertices == 0 &&
         non_manifold_edges == 0 && inconsistent_edges == 0;
}

bool MeshReport::isClosed() const {
  return isUsable() && boundary_edges == 0 && non_manifold_edges == 0 && inconsistent_edges == 0;
}

std::string MeshReport::summary() const {
  std::ostringstream text;
  text << vertex_count << " vertices, " << triangle_count << " triangles";
  const std::pair<std::size_t, const char*> problems[] = {
      {non_finite_vertices, "non-finite vertices"},
      {out_of_range_triangles, "triangles with out-of-range indices"},
      {out_of_range_fixed_vertices, "out-of-range fixed vertices"},
      {normal_count_mismatch, "normal arrays of the wrong length"},
      {degenerate_triangles, "degenerate triangles"},
      {duplicate_vertices, "duplicate vertices"},
      {unreferenced_vertices, "unreferenced vertices"},
      {boundary_edges, "boundary edges"},
      {non_manifold_edges, "non-manifold edges"},
      {inconsistent_edges, "inconsistently oriented edges"},
  };
  for (const auto& [count, what] : problems) {
    if (count > 0) text << ", " << count << " " << what;
  }
  return text.str();
}

MeshReport validateMesh(const TriangleMesh& mesh, double relative_area_tolerance) {
  MeshReport report;
  report.vertex_count = mesh.vertices.size();
  report.triangle_count = mesh.triangles.size();
  report.non_finite_vertices = static_cast<std::size_t>(std::count_if(
      mesh.vertices.begin(), mesh.vertices.end(), [](const Eigen::Vector3d& vertex) { return !isFinite(vertex); }));
  report.normal_count_mismatch = (!mesh.normals.empty() && mesh.normals.size() != mesh.vertices.size()) ? 1 : 0;
  for (std::uint32_t fixed : mesh.fixed_vertices) {
    if (fixed >= mesh.vertices.size()) ++report.out_of_range_fixed_vertices;
  }
  const std::vector<std::uint32_t> representative = findRepresentatives(mesh.vertices, 0.0);
  for (std::uint32_t i = 0; i < representative.size(); ++i) {
    if (representative[i] != i && isFinite(mesh.vertices[i])) ++report.duplicate_vertices;
  }

  std::vector<bool> referenced(mesh.vertices.size(), false);
  // Directed edge (from, to) -> number of triangles traversing it in that direction.
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed_edges;
  for (const auto& triangle : mesh.triangles) {
    if (!indicesInRange(mesh, triangle)) {
      ++report.out_of_range_triangles;
      continue;
    }
    for (std::uint32_t index : triangle) referenced[index] = true;
    if (isDegenerate(mesh, triangle, relative_area_tolerance)) ++report.degenerate_triangles;
    for (int corner = 0; corner < 3; ++corner) {
      const std::uint32_t from = triangle[corner], to = triangle[(corner + 1) % 3];
      if (from != to) ++directed_edges[{from, to}];
    }
  }
  report.unreferenced_vertices = static_cast<std::size_t>(std::count(referenced.begin(), referenced.end(), false));
  for (const auto& [edge, forward_count] : directed_edges) {
    const auto reverse = directed_edges.find({edge.second, edge.first});
    const int backward_count = reverse == directed_edges.end() ? 0 : reverse->second;
    if (edge.first > edge.second && backward_count > 0) continue;  // counted once, from its smaller endpoint
    const int uses = forward_count + backward_count;
    if (uses == 1) {
      ++report.boundary_edges;
    } else if (uses > 2) {
      ++report.non_manifold_edges;
    } else if (forward_count == 2 || backward_count == 2) {
      ++report.inconsistent_edges;
    }
  }
  return report;
}

MeshCleanupResult cleanupMesh(TriangleMesh& mesh, const MeshCleanupOptions& options) {
  const MeshReport report = validateMesh(mesh, options.relative_area_tolerance);
  if (!report.isUsable())
    throw std::invalid_argument("cleanupMesh: mesh '" + mesh.name + "' is not usable: " + report.summary());
  MeshCleanupResult result;
  std::vector<std::uint32_t> representative(mesh.vertices.size());
  for (std::uint32_t i = 0; i < representative.size(); ++i) representative[i] = i;
  if (options.join_duplicate_vertices) representative = findRepresentatives(mesh.vertices, options.join_distance);
  for (std::uint32_t i = 0; i < representative.size(); ++i) {
    if (representative[i] != i) ++result.joined_vertices;
  }
  for (auto& triangle : mesh.triangles) {
    for (auto& index : triangle) index = representative[index];
  }
  if (options.remove_degenerate_triangles) {
    const auto first_removed = std::remove_if(mesh.triangles.begin(), mesh.triangles.end(), [&](const auto& triangle) {
      return isDegenerate(mesh, triangle, options.relative_area_tolerance);
    });
    result.removed_triangles = static_cast<std::size_t>(mesh.triangles.end() - first_removed);
    mesh.triangles.erase(first_removed, mesh.triangles.end());
  }
  std::vector<bool> fixed(mesh.vertices.size(), false);
  for (std::uint32_t index : mesh.fixed_vertices) fixed[representative[index]] = true;

  // Compact: keep representatives that are referenced (or all representatives when not removing unreferenced).
  std::vector<bool> keep(mesh.vertices.size(), false);
  if (options.remove_unreferenced_vertices) {
    for (const auto& triangle : mesh.triangles) {
      for (std::uint32_t index : triangle) keep[index] = true;
    }
  } else {
    for (std::uint32_t i = 0; i < keep.size(); ++i) keep[i] = representative[i] == i;
  }
  constexpr std::uint32_t kRemoved = ~0u;
  std::vector<std::uint32_t> new_index(mesh.vertices.size(), kRemoved);
  std::vector<Eigen::Vector3d> vertices, normals;
  std::vector<std::uint32_t> fixed_vertices;
  for (std::uint32_t i = 0; i < mesh.vertices.size(); ++i) {
    if (!keep[i]) continue;
    new_index[i] = static_cast<std::uint32_t>(vertices.size());
    vertices.push_back(mesh.vertices[i]);
    if (!mesh.normals.empty()) normals.push_back(mesh.normals[i]);
    if (fixed[i]) fixed_vertices.push_back(new_index[i]);
  }
  for (std::uint32_t i = 0; i < representative.size(); ++i) {
    if (representative[i] == i && !keep[i]) ++result.removed_vertices;
  }
  for (auto& triangle : mesh.triangles) {
    for (auto& index : triangle) index = new_index[index];
  }
  mesh.vertices = std::move(vertices);
  mesh.normals = std::move(normals);
  mesh.fixed_vertices = std::move(fixed_vertices);
  return result;
}

}  // namespace scene
}  // namespace vrm_sim
