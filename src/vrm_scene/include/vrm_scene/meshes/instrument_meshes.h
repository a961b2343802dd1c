#pragma once
// Procedural instrument meshes (thesis §7: light pipe, forceps, vitrector, needle, hook).
//
// Instrument frame convention (shared with tracking and collision):
//   * the z axis is the shaft axis and points from the handle towards the tip, so the shaft extends along -z;
//   * the origin lies on the shaft axis in the most distal plane of the instrument: every vertex has z <= 0 and
//     some vertex has z == 0 (for the forceps: with closed jaws; opening the jaws swings them back).
//   * Only the part that enters the eye is modelled (the handle is outside the microscope's view).
// Where the working point is off the axis (needle point, hook tip) a helper returns it.
// Default dimensions: 23 gauge shaft (0.6 mm diameter), 30 mm long. Lengths in metres, angles in degrees.

#include "vrm_scene/meshes/triangle_mesh.h"

namespace vrm_sim {
namespace scene {

struct ShaftParams {
  double diameter = 0.0006;
  double length = 0.030;
  int segments = 24;
};

struct LightPipeParams {
  ShaftParams shaft;
  // Height of the polished, rounded fibre end (an ellipsoidal dome; shaft radius = hemisphere).
  double tip_length = 0.0003;
  int tip_rings = 4;
};

struct ForcepsParams {
  ShaftParams shaft;
  double jaw_length = 0.0015;
  double jaw_base_width = 0.0005;  // at the hinge (inside the shaft diameter)
  double jaw_tip_width = 0.0002;
  double jaw_thickness = 0.00012;
  double jaw_angle_deg = 0.0;  // full opening angle between the jaws; 0 = closed
};
enum class ForcepsJaw { kUpper, kLower };  // opening towards +y / -y

struct VitrectorParams {
  ShaftParams shaft;
  // The cutting port is a pocket in the shaft wall facing +x, near the closed flat tip. It makes the instrument
  // non-z-convex along its own axis (thesis §4: ZCOLL needs z-convexity of one object, here the membrane).
  double port_distance_from_tip = 0.0002;  // from the tip plane to the distal edge of the port
  double port_length = 0.0004;             // along the shaft
  double port_width_deg = 100.0;           // angular width about the shaft axis
  double port_depth = 0.0002;              // radial depth of the pocket (< shaft radius)
};

struct NeedleParams {
  ShaftParams shaft{0.0004, 0.030, 16};  // 27 gauge cannula (solid: the lumen is not modelled)
  double bevel_angle_deg = 20.0;         // between the bevel plane and the shaft axis; the point faces -x
};

// The endolaser probe (issue 37): a straight 23-gauge probe whose flat fibre end (z = 0) emits the treatment and the
// aiming beam along +z. The laser console's settings belong to it (a scene or difficulty level sets them, the console
// changes them: ScenarioCommand SELECT_INSTRUMENT "right:laser_probe:power_mw=250,duration_ms=150").
struct LaserProbeParams {
  ShaftParams shaft{0.00064, 0.030, 16};  // 23 gauge
  double fibre_diameter = 2e-4;           // m: the fibre core, the spot's size at the fibre end
  double numerical_aperture = 0.12;       // of the fibre; in the vitreous the beam's half angle is asin(NA / 1.336)
  double power_mw = 200.0;                // one shot's power
  double duration_ms = 100.0;             // one shot's exposure
  double interval_ms = 0.0;               // 0: one shot per pedal press; > 0: repeats while the pedal is held
};

struct HookParams {
  ShaftParams shaft;
  double hook_diameter = 0.0002;  // the bent wire at the tip
  double bend_radius = 0.0003;    // of the hook wire's centre line
  double bend_angle_deg = 90.0;   // the hook bends towards +x
  double hook_length = 0.0004;    // straight wire after the bend
  double neck_length = 0.0005;    // straight wire between the shaft end and the bend
  int path_samples_per_bend = 8;
};

TriangleMesh makeShaft(const ShaftParams& params, double distal_z);  // closed cylinder from -length to distal_z
TriangleMesh makeLightPipe(const LightPipeParams& params);

// The forceps as separate parts so the jaws can move with the tracked jaw angle; makeForceps() merges them at
// params.jaw_angle_deg.
struct ForcepsMeshes {
  TriangleMesh shaft;
  TriangleMesh upper_jaw;
  TriangleMesh lower_jaw;
};
ForcepsMeshes makeForcepsParts(const ForcepsParams& params);
TriangleMesh makeForcepsJaw(const ForcepsParams& params, ForcepsJaw jaw);
TriangleMesh makeForceps(const ForcepsParams& params);

TriangleMesh makeVitrector(const VitrectorParams& params);
TriangleMesh makeNeedle(const NeedleParams& params);
Eigen::Vector3d needlePoint(const NeedleParams& params);  // the sharp point of the bevel, (-r, 0, 0)
TriangleMesh makeLaserProbe(const LaserProbeParams& params);
TriangleMesh makeHook(const HookParams& params);
Eigen::Vector3d hookTipPoint(const HookParams& params);  // centre of the hook wire's free end face

}  // namespace scene
}  // namespace vrm_sim
