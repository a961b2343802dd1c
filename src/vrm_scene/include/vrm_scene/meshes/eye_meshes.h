#pragma once
// Procedural eye assets (thesis §7: membrane removal and ILM peeling scenarios).
//
// Eye frame: origin at the centre of the eye ball (its rotation centre), +z along the optical axis pointing out
// through the pupil towards the microscope, +x to the right and +y up in the microscope image. The posterior pole
// (fovea region) is therefore at (0, 0, -radius). Lengths in metres, angles in degrees in the parameter structs.

#include "vrm_scene/meshes/triangle_mesh.h"

namespace vrm_sim {
namespace scene {

struct RetinaParams {
  double radius = 0.012;
  // Polar angle from the posterior pole to the rim (the opening towards the anterior segment); 90 = hemisphere.
  double coverage_deg = 90.0;
  int ring_count = 44;  // 44 rings on a hemisphere give ~10k triangles with ~0.43 mm edges
};

// A spherical shell about the posterior pole whose triangles face the eye centre (the side the surgeon sees).
// The rim vertices (ora serrata / opening) are listed in fixed_vertices: the shell is anchored there.
TriangleMesh makeRetina(const RetinaParams& params);

struct MembraneParams {
  double retina_radius = 0.012;
  double height_above_retina = 0.0003;  // the patch lies on a sphere of radius retina_radius - height
  double diameter = 0.005;              // measured along the curved surface
  int ring_count = 16;                  // concentric rings; triangles ~ 6 * ring_count^2
  // Centre of the patch: angle away from the posterior pole and azimuth about the optical axis (0 = +x).
  double centre_offset_deg = 0.0;
  double centre_azimuth_deg = 0.0;
  // Thesis §7: the membrane adheres to the retina at points; the tissue simulation attaches adhesion springs to
  // these vertices, so they are returned as fixed_vertices.
  int adhesion_point_count = 5;
  double adhesion_ring_fraction = 0.6;  // radius of the adhesion ring as a fraction of the patch radius
  // Every vertex adheres instead (the retina itself, lying on the eye wall: retina relocation).
  bool adhere_everywhere = false;
  // Besides the points: every vertex within adhesion_disc_radius [m] (0 = none) of the point on the patch's sphere
  // adhesion_disc_offset_deg from the posterior pole towards azimuth adhesion_disc_azimuth_deg — the optic disc, where
  // the posterior hyaloid holds fast.
  double adhesion_disc_radius = 0.0;
  double adhesion_disc_offset_deg = 15.0;
  double adhesion_disc_azimuth_deg = 0.0;
};

// A disc-shaped patch following the retina's curvature, facing the eye centre. Adhesion points: the first at the
// patch centre, the remaining (adhesion_point_count - 1) evenly spaced on a ring at adhesion_ring_fraction of the
// patch radius; each snaps to the nearest vertex; plus the disc region, or every vertex (adhere_everywhere). They
// are returned in fixed_vertices (sorted, unique).
TriangleMesh makeMembrane(const MembraneParams& params);

// Rotation that takes the posterior pole direction (0, 0, -1) to the direction `offset_deg` away from it towards
// azimuth `azimuth_deg` (measured about +z from +x). Used to place the membrane patch.
Eigen::Matrix3d posteriorPoleRotation(double offset_deg, double azimuth_deg);

}  // namespace scene
}  // namespace vrm_sim
