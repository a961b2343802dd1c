#pragma once
// Closed (or, for plane and disc, single-sided) primitive meshes for abstract scenarios and simple colliders
// (thesis §7: navigation and manipulation tasks with spheres, boxes, rings; §4: geometric primitives).
// All lengths in metres. Every primitive is centred at its local origin; axial shapes (cylinder, capsule, cone,
// torus, disc) use the z axis. Closed primitives have outward normals (signedVolume() > 0).

#include "vrm_scene/meshes/triangle_mesh.h"

namespace vrm_sim {
namespace scene {

struct SphereParams {
  double radius = 0.001;
  int ring_count = 12;  // latitude rings from pole to pole; triangles ~ 2.5 * ring_count^2
};
struct BoxParams {
  Eigen::Vector3d size{0.002, 0.002, 0.002};  // full edge lengths along x, y, z
};
struct CylinderParams {
  double radius = 0.0005;
  double length = 0.002;  // along z, centred
  int segments = 24;
};
struct CapsuleParams {
  double radius = 0.0005;
  double length = 0.002;  // of the cylindrical part, along z, centred; total length = length + 2 * radius
  int segments = 24;
  int cap_rings = 6;  // latitude rings per hemispherical cap
};
struct ConeParams {
  double radius = 0.0005;  // base radius; the base lies in z = 0, the apex at z = height
  double height = 0.001;
  int segments = 24;
};
struct TorusParams {
  double major_radius = 0.002;  // ring in the xy plane
  double minor_radius = 0.0003;
  int major_segments = 48;
  int minor_segments = 16;
};
struct DiscParams {
  double radius = 0.002;  // in the xy plane, facing +z (single-sided, open)
  int ring_count = 8;
};
struct PlaneParams {
  double size_x = 0.004;  // in the xy plane, centred, facing +z (single-sided, open)
  double size_y = 0.004;
  int subdivisions = 8;  // cells per side
};

TriangleMesh makeSphere(const SphereParams& params);
TriangleMesh makeBox(const BoxParams& params);
TriangleMesh makeCylinder(const CylinderParams& params);
TriangleMesh makeCapsule(const CapsuleParams& params);
TriangleMesh makeCone(const ConeParams& params);
TriangleMesh makeTorus(const TorusParams& params);
TriangleMesh makeDisc(const DiscParams& params);
TriangleMesh makePlane(const PlaneParams& params);

// A spherical cap about the +z pole: polar angle 0..max_polar_angle (radians, <= pi; pi gives a full sphere),
// `ring_count` rings of near-equilateral triangles with vertex counts proportional to sin(polar angle). Facing
// outward (away from the centre) unless `facing_centre`. The vertices of the last ring (the rim, unless the cap is
// a full sphere) are listed in `rim_vertices` if non-null.
TriangleMesh makeSphericalCap(double radius, double max_polar_angle, int ring_count, bool facing_centre,
                              std::vector<std::uint32_t>* rim_vertices = nullptr);

}  // namespace scene
}  // namespace vrm_sim
