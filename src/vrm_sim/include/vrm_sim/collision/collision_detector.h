#pragma once
// Collision detection between an instrument and a surface (thesis §4). One interface, several detectors chosen by
// name (thesis §4.2.7: ZCOLL/F, RAPID and SOLID sit behind one base class so they can be swapped):
//
//   zcoll_f_cpu   ZCOLL/F (Alg. 4.3) on a small software rasterizer (depth + triangle id arrays); front face only.
//   zcoll_cpu     ZCOLL (Alg. 4.2) on the same rasterizer; the stencil parity pass is replaced by counting the
//                 cached depth layers of the instrument in front of the surface (same result as the stencil).
//   myszkowski_cpu  the two-pass stencil test of Myszkowski et al. 1995 (Alg. 4.1) for a closed z-convex object
//                 (e.g. a rigid primitive): collision yes/no and triangles, no deformation vectors.
//   zcoll_f_gl    ZCOLL/F on OpenGL (OSMesa, vrm_gl::GlContext): tissue rendered with 24-bit colour ids
//                 (gl_PrimitiveID + 1), depth + colour readback of the ROI, analysis on the CPU.
//   zcoll_gl      ZCOLL on OpenGL: additionally the instrument's stencil pass (increment on z pass) and stencil
//                 readback; odd parity = collision.
//   geometric     exact primitives (sphere, capsule, box, cylinder, cone, plane) of InstrumentModel::primitives vs the
//                 surface triangles.
//   fcl, fcl_aabb, fcl_obbrss, fcl_kios   FCL 0.7 BVH mesh-mesh test with refit of the deformed surface; "fcl" is
//                 OBBRSS. Full contact set; no deformation vectors (FCL gives none for mesh-mesh).
//   zcoll, zcoll_f   aliases of zcoll_cpu / zcoll_f_cpu (the scene YAML names), the fastest path on this machine.
//   none          never collides.
//
// Frames and units (SI): the surface's node positions and every output vector/point are in the surface's frame
// (e.g. tissue coordinates); `instrument_pose` maps instrument coordinates to that frame. Instrument frame as in
// scene/instrument_meshes.h: origin at the tip, +z from the handle to the tip. The image-space detectors project
// along the instrument-fixed direction InstrumentModel::projection_direction (default +z, i.e. deformation along the
// shaft towards the tip), with an orthographic volume fitted around the tip region (thesis Fig. 4.8: V and z are
// object-fixed).
//
// Use from a simulation (e.g. world::World, which the scenario_manager nodelet wraps):
//   auto detector = makeCollisionDetector("zcoll_f_cpu");
//   detector->setInstrument(model);                        // once, and whenever the jaws move
//   CollisionResult r = detector->collide(pose, SurfaceView::of(membrane));
//   for (size_t i = 0; i < r.nodes.size(); ++i) positions[r.nodes[i]] += r.deformations[i];
// A detector keeps caches (instrument depth, BVHs) and is not thread-safe; use one per thread.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_scene/registry.h"

namespace vrm_sim {
namespace mge {
class Membrane;
}
namespace collision {

// Exact convex solids for the geometric detector and as test references; in instrument coordinates.
//   sphere    centre a, radius
//   capsule   segment a-b swept by a sphere of radius
//   box       centre a, half_extents in the box frame, rotation box -> instrument
//   cylinder  axis a-b (flat caps at a and b), radius
//   cone      apex a, base centre b (flat base), base radius `radius`
//   plane     the half-space {x : normal . (x - a) <= 0} (normal unit, pointing out of the solid)
// A cylinder or cone with a == b has no axis and is empty (never overlaps); NaN / negative sizes are invalid and
// never overlap either (see primitives.h isValid()).
struct Primitive {
  enum class Type { kSphere, kCapsule, kBox, kCylinder, kCone, kPlane };
  Type type = Type::kSphere;
  Eigen::Vector3d a = Eigen::Vector3d::Zero();             // sphere/box centre; capsule/cylinder start; cone apex
  Eigen::Vector3d b = Eigen::Vector3d::Zero();             // capsule/cylinder end; cone base centre
  double radius = 0.0;                                     // sphere, capsule, cylinder, cone base
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();  // box, in the box frame
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // box frame -> instrument frame
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();       // plane

  static Primitive sphere(const Eigen::Vector3d& centre, double radius);
  static Primitive capsule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius);
  static Primitive box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half_extents,
                       const Eigen::Matrix3d& rotation = Eigen::Matrix3d::Identity());
  static Primitive cylinder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius);
  static Primitive cone(const Eigen::Vector3d& apex, const Eigen::Vector3d& base_centre, double base_radius);
  static Primitive plane(const Eigen::Vector3d& point, const Eigen::Vector3d& normal);
};

// The instrument: its closed surface mesh (image-space and FCL detectors) and optionally an exact primitive
// description (geometric detector). Rigid: a change of shape (jaw angle) is a new setInstrument() call.
struct InstrumentModel {
  TriangleMesh mesh;
  std::vector<Primitive> primitives;
  // Image-space projection direction in instrument coordinates (deformation vectors are parallel to it, thesis
  // §4.2.2: choose it along the instrument motion if needed). Changing it invalidates the cached depth.
  Eigen::Vector3d projection_direction = Eigen::Vector3d::UnitZ();
  // Depth of the rendering volume behind the most distal point [m]: only this tip region can collide.
  double tip_region_length = 0.002;
};

// A non-owning view of a triangle surface: contiguous node positions and triangle node-index triples. Works on the
// MGE membrane's arrays (no copy) and on a TriangleMesh. Rigid objects are surfaces too (static_geometry = true lets
// BVH detectors skip the refit).
struct SurfaceView {
  const Eigen::Vector3d* positions = nullptr;
  std::size_t node_count = 0;
  const std::array<std::uint32_t, 3>* triangles = nullptr;
  std::size_t triangle_count = 0;
  bool static_geometry = false;

  static SurfaceView of(const TriangleMesh& mesh);
  static SurfaceView of(mge::Membrane& membrane);
};

enum class DeformationReduction { kMax, kMean };  // thesis §4.2.2: per node, max or mean of the set D_v

// Thesis §4.2.5: skip readback work that is not needed.
enum class ReadbackMode {
  kFull,              // triangles, deformation vectors, contacts
  kDeformationsOnly,  // deformation vectors and triangles, no contacts (on the CPU the ids come for free)
  kTrianglesOnly,     // colliding triangles only (no deformation vectors)
  kYesNo,             // collision yes/no only, by OR-folding the collision mask
};

struct CollisionOptions {
  int resolution = 64;  // image-space buffer edge in pixels (r x r)
  // If > 0: raise the resolution (up to max_resolution) until the pixel size is at most this [m] (bounded error).
  double max_pixel_size = 0.0;
  int max_resolution = 512;
  DeformationReduction reduction = DeformationReduction::kMax;
  ReadbackMode readback = ReadbackMode::kFull;
  int fcl_max_contacts = 100000;
  // GL backends: reduce the collision mask on the GPU before reading back (§4.2.5: yes/no by OR-folded quadrants,
  // ROI by OR-folded rows/columns, then only the collision's ROI). false: read depth, colour and stencil of the
  // instrument's whole footprint and build the mask on the CPU (for comparison; on llvmpipe, where "GPU" memory is
  // host memory, the extra passes can cost more than the bytes they save).
  bool gpu_reductions = true;
};

enum class CollisionStatus {
  kOk,                  // query ran (colliding or not)
  kEmptyInput,          // instrument or surface has no triangles: not colliding
  kInvalidInput,        // NaN/Inf pose or positions, or out-of-range triangle indices: not colliding
  kNoInstrument,        // setInstrument() was not called (or, for geometric, no primitives)
  kOutsideVolume,       // surface entirely outside the rendering volume / bounding volume: not colliding
  kBackendUnavailable,  // the GL backends could not create their OSMesa context: not colliding
};
const char* toString(CollisionStatus status);

struct PhaseTiming {
  double ms_raster = 0.0;    // geometry transfer + rasterization (image space), BVH build/refit (FCL)
  double ms_readback = 0.0;  // buffer readback (GL), buffer reductions (CPU)
  double ms_analysis = 0.0;  // pixel analysis / narrow phase
  double ms_total = 0.0;
};

struct CollisionResult {
  CollisionStatus status = CollisionStatus::kOk;
  bool colliding = false;
  std::vector<std::uint32_t> triangles;  // colliding surface triangles, sorted, unique
  // Surface nodes with a deformation vector, sorted, and per entry the displacement [m] that resolves the contact.
  // Image space: parallel to the projection direction (Eq. 4.2); per node the max / mean (CollisionOptions::
  // reduction) over all colliding pixels of the node's adjacent triangles (§4.2.2). geometric: exact, only for
  // nodes inside the instrument, moving them along z onto its front surface. fcl: empty.
  std::vector<std::uint32_t> nodes;
  std::vector<Eigen::Vector3d> deformations;
  // Image space: one per colliding triangle (its deepest pixel on the instrument's front surface), normal = the
  // projection direction. geometric: closest triangle point to the primitive's centre. fcl: FCL's contact set.
  std::vector<Eigen::Vector3d> contact_points;   // surface frame
  std::vector<Eigen::Vector3d> contact_normals;  // unit, pointing from the instrument into the surface
  double pixel_size = 0.0;                       // [m/pixel] for image-space detectors, 0 otherwise
  int resolution = 0;                            // pixels per edge actually used
  std::size_t readback_bytes = 0;                // GL backends: bytes read back from the framebuffer per query
  PhaseTiming timing;
};

class CollisionDetector {
 public:
  virtual ~CollisionDetector() = default;
  virtual std::string name() const = 0;
  // Sets (or changes) the instrument; invalidates cached instrument data (thesis Alg. 4.2 line 4).
  virtual void setInstrument(const InstrumentModel& instrument) = 0;
  virtual void setOptions(const CollisionOptions& options) { options_ = options; }
  const CollisionOptions& options() const { return options_; }
  // Instrument (at `instrument_pose` in the surface frame) vs surface. Never throws for bad geometry: a status.
  virtual CollisionResult collide(const Eigen::Isometry3d& instrument_pose, const SurfaceView& surface) = 0;
  // Whether this detector's deformation vectors are meant as the tissue's response (ZCOLL's image-space answer,
  // thesis §4.2.5: push each colliding node along the projection direction): the simulation core then moves the
  // tissue by them. The others report contacts (and the exact detector its z-line depths), and the tissue simulator's
  // own contact with the instrument's capsules is their response.
  virtual bool producesDeformations() const { return false; }

 protected:
  CollisionOptions options_;
};

// The detectors by name (the list at the top): what makeCollisionDetector builds from and the scene schema checks.
using DetectorFactory = std::unique_ptr<CollisionDetector> (*)();
const Registry<DetectorFactory>& detectorRegistry();
std::vector<std::string> collisionDetectorNames();  // detectorRegistry().names()
// Throws std::invalid_argument naming the known detectors for an unknown name.
std::unique_ptr<CollisionDetector> makeCollisionDetector(const std::string& name, const CollisionOptions& options = {});

}  // namespace collision
}  // namespace vrm_sim
