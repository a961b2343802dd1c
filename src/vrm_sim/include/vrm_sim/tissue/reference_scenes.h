#pragma once
// Small analytic test scenes shared by the unit tests and bench_tissue: a linear chain (thesis §5.2.1's stability
// argument) and a square membrane patch with a pinned border (static sag, speed against error).

#include <memory>

#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_sim/mge/membrane.h"

namespace vrm_sim {
namespace tissue {

// n + 1 nodes along +x, spacing `rest_length`, n springs of stiffness k; node 0 pinned; every node of mass m.
std::unique_ptr<mge::Membrane> makeChain(int springs, double stiffness, double mass, double rest_length);

// A (cells+1)² grid of side `size` in the xy plane (centred, facing +z), two triangles per cell, border vertices
// in fixed_vertices when pin_border.
TriangleMesh makeGridMesh(int cells, double size, bool pin_border);

// The grid as a membrane with a uniform node mass and spring stiffness (optionally with bending springs).
std::unique_ptr<mge::Membrane> makeGridMembrane(int cells, double size, double stiffness, double node_mass,
                                                bool pin_border = true, double bending_stiffness = 0.0);

}  // namespace tissue
}  // namespace vrm_sim
