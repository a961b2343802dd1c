#include "vrm_scene/meshes/surface_builders.h"

#include <stdexcept>

namespace vrm_sim {
namespace scene {

TriangleMesh makeTube(const TubeRings& tube) {
  if (tube.rings.empty()) throw std::invalid_argument("makeTube: no rings");
  const std::size_t ring_size = tube.rings.front().size();
  if (ring_size < 3) throw std::invalid_argument("makeTube: rings need at least 3 vertices");
  TriangleMesh mesh;
  for (const auto& ring : tube.rings) {
    if (ring.size() != ring_size) throw std::invalid_argument("makeTube: rings differ in vertex count");
    mesh.vertices.insert(mesh.vertices.end(), ring.begin(), ring.end());
  }
  const auto index = [ring_size](std::size_t ring, std::size_t i) {
    return static_cast<std::uint32_t>(ring * ring_size + i % ring_size);
  };
  // Side quads: with rings right-handed about the path, (a, b, c) has normal e_phi x e_path = outward.
  for (std::size_t ring = 0; ring + 1 < tube.rings.size(); ++ring) {
    for (std::size_t i = 0; i < ring_size; ++i) {
      const std::uint32_t a = index(ring, i), b = index(ring, i + 1);
      const std::uint32_t c = index(ring + 1, i + 1), d = index(ring + 1, i);
      mesh.triangles.push_back({a, b, c});
      mesh.triangles.push_back({a, c, d});
    }
  }
  if (tube.start_pole) {
    const auto pole = static_cast<std::uint32_t>(mesh.vertices.size());
    mesh.vertices.push_back(*tube.start_pole);
    for (std::size_t i = 0; i < ring_size; ++i) mesh.triangles.push_back({pole, index(0, i + 1), index(0, i)});
  }
  if (tube.end_pole) {
    const auto pole = static_cast<std::uint32_t>(mesh.vertices.size());
    mesh.vertices.push_back(*tube.end_pole);
    const std::size_t last = tube.rings.size() - 1;
    for (std::size_t i = 0; i < ring_size; ++i) mesh.triangles.push_back({pole, index(last, i), index(last, i + 1)});
  }
  return mesh;
}

std::vector<std::array<std::uint32_t, 3>> triangulateConcentricRings(const std::vector<AngularRing>& rings) {
  std::vector<std::array<std::uint32_t, 3>> triangles;
  for (std::size_t k = 0; k + 1 < rings.size(); ++k) {
    const AngularRing& inner = rings[k];
    const AngularRing& outer = rings[k + 1];
    const auto inner_vertex = [&inner](std::uint32_t i) { return inner.first_vertex + i % inner.vertex_count; };
    const auto outer_vertex = [&outer](std::uint32_t j) { return outer.first_vertex + j % outer.vertex_count; };
    if (inner.vertex_count == 1 && outer.vertex_count == 1) throw std::invalid_argument("two consecutive poles");
    if (inner.vertex_count == 1) {
      for (std::uint32_t j = 0; j < outer.vertex_count; ++j) {
        triangles.push_back({inner.first_vertex, outer_vertex(j), outer_vertex(j + 1)});
      }
      continue;
    }
    if (outer.vertex_count == 1) {
      for (std::uint32_t i = 0; i < inner.vertex_count; ++i) {
        triangles.push_back({inner_vertex(i), outer.first_vertex, inner_vertex(i + 1)});
      }
      continue;
    }
    // Angles in turns; both sequences span one full turn, so the merge emits inner + outer triangles and closes.
    const auto inner_angle = [&inner](std::uint32_t i) { return (i + inner.angle_offset) / inner.vertex_count; };
    const auto outer_angle = [&outer](std::uint32_t j) { return (j + outer.angle_offset) / outer.vertex_count; };
    std::uint32_t i = 0, j = 0;
    while (i < inner.vertex_count || j < outer.vertex_count) {
      const bool advance_inner =
          j == outer.vertex_count || (i < inner.vertex_count && inner_angle(i + 1) < outer_angle(j + 1));
      if (advance_inner) {
        triangles.push_back({inner_vertex(i), outer_vertex(j), inner_vertex(i + 1)});
        ++i;
      } else {
        triangles.push_back({inner_vertex(i), outer_vertex(j), outer_vertex(j + 1)});
        ++j;
      }
    }
  }
  return triangles;
}

}  // namespace scene
}  // namespace vrm_sim
