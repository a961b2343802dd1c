#pragma once
// Standard edge labels of the VRM scene model (thesis Fig. 3.1). Each label l has the reference label −l
// (referenceLabel()), so e.g. Γ(node, −kSpringNodes) are the springs attached to a node, and Γ(node, −kNodeList) is
// the tissue the node belongs to. Algorithms that add their own relations pick labels ≥ kFirstUserLabel.

#include "vrm_sim/mge/element.h"

namespace vrm_sim {
namespace mge {
namespace labels {

// Scene graph ("GR" edges in Fig. 3.1): parent → child, walked by the renderer in list order.
constexpr Label kSceneChild = 1;
// Tissue MGE g2 → all of its nodes, springs, triangles ("NL", "SL", "TL" in Fig. 3.1).
constexpr Label kNodeList = 2;
constexpr Label kSpringList = 3;
constexpr Label kTriangleList = 4;
// Spring → its two end nodes (ordered).
constexpr Label kSpringNodes = 5;
// Triangle → its three corner nodes, counter-clockwise seen from the front (the order gives the normal, §3.2).
constexpr Label kTriangleNodes = 6;
// Triangle → the springs on its edges (v0v1, v1v2, v2v0); a spring's reference list holds its 1–2 triangles, so
// cutting a triangle finds the springs that lose their last triangle.
constexpr Label kTriangleEdgeSprings = 7;
// Triangle → bending springs that span the edge to a neighbouring triangle; such a spring dies with either triangle.
constexpr Label kTriangleBendingSprings = 8;

constexpr Label kFirstUserLabel = 1000;

}  // namespace labels
}  // namespace mge
}  // namespace vrm_sim
