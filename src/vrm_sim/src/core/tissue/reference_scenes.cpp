#include "vrm_sim/tissue/reference_scenes.h"

namespace vrm_sim {
namespace tissue {

std::unique_ptr<mge::Membrane> makeChain(int springs, double stiffness, double mass, double rest_length) {
  mge::MembraneOptions options;
  options.stretch_stiffness = stiffness;
  auto chain = std::make_unique<mge::Membrane>(options);
  chain->reserve(springs + 1, springs, 0);
  mge::Node* previous = &chain->addNode(Eigen::Vector3d::Zero(), mass, /*fixed=*/true);
  for (int i = 1; i <= springs; ++i) {
    mge::Node& node = chain->addNode(Eigen::Vector3d(i * rest_length, 0.0, 0.0), mass);
    chain->addSpring(*previous, node, stiffness);
    previous = &node;
  }
  return chain;
}

TriangleMesh makeGridMesh(int cells, double size, bool pin_border) {
  TriangleMesh mesh;
  mesh.name = "grid";
  const int side = cells + 1;
  mesh.vertices.reserve(static_cast<std::size_t>(side) * side);
  for (int j = 0; j < side; ++j) {
    for (int i = 0; i < side; ++i) {
      mesh.vertices.emplace_back(size * (static_cast<double>(i) / cells - 0.5),
                                 size * (static_cast<double>(j) / cells - 0.5), 0.0);
      if (pin_border && (i == 0 || j == 0 || i == cells || j == cells)) {
        mesh.fixed_vertices.push_back(static_cast<std::uint32_t>(j * side + i));
      }
    }
  }
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) {
      const std::uint32_t a = j * side + i;
      const std::uint32_t b = a + 1;
      const std::uint32_t c = a + side;
      const std::uint32_t d = c + 1;
      // Alternate the diagonal so the patch has no preferred shear direction.
      if ((i + j) % 2 == 0) {
        mesh.triangles.push_back({a, b, d});
        mesh.triangles.push_back({a, d, c});
      } else {
        mesh.triangles.push_back({a, b, c});
        mesh.triangles.push_back({b, d, c});
      }
    }
  }
  return mesh;
}

std::unique_ptr<mge::Membrane> makeGridMembrane(int cells, double size, double stiffness, double node_mass,
                                                bool pin_border, double bending_stiffness) {
  const TriangleMesh mesh = makeGridMesh(cells, size, pin_border);
  mge::MembraneOptions options;
  options.stretch_stiffness = stiffness;
  options.bending_springs = bending_stiffness > 0.0;
  options.bending_stiffness = bending_stiffness;
  // Lumped masses follow the triangle areas (border nodes lighter); the patch's total matches node_mass per node.
  options.total_mass = node_mass * static_cast<double>(mesh.vertexCount());
  return mge::buildMembrane(mesh, options);
}

}  // namespace tissue
}  // namespace vrm_sim
