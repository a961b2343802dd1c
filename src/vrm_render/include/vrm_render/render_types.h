#pragma once
// Plain data exchanged with the ROS-free stereo microscope renderer (thesis §6, §7.4.2). SI units (metres),
// images top row first, RGB8.

#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace vrm_render {

// Any rejected input (empty or non-finite mesh, index out of range, huge size, unknown object) or GL failure. The
// renderer validates before it changes state, so after a RenderError it keeps its previous, consistent state.
class RenderError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A non-owning view of packed mesh arrays, laid out as in vrm_msgs/TissueMesh, so deformable meshes stream straight
// from the MGE arrays / message buffers into GPU buffers without an intermediate copy.
struct MeshView {
  const float* positions = nullptr;  // 3 per vertex
  std::size_t vertex_count = 0;
  const float* normals = nullptr;            // 3 per vertex, optional (computed from the triangles when null)
  const float* colors = nullptr;             // 4 per vertex (rgba 0..1), optional (white)
  const float* injury = nullptr;             // 1 per vertex (0..1 bleeding intensity), optional (0)
  const std::uint32_t* triangles = nullptr;  // 3 per triangle
  std::size_t triangle_count = 0;
};

// Owning counterpart of MeshView for tests and benchmarks.
struct MeshData {
  std::vector<float> positions;
  std::vector<float> normals;
  std::vector<float> colors;
  std::vector<float> injury;
  std::vector<std::uint32_t> triangles;

  MeshView view() const {
    MeshView v;
    v.positions = positions.data();
    v.vertex_count = positions.size() / 3;
    v.normals = normals.empty() ? nullptr : normals.data();
    v.colors = colors.empty() ? nullptr : colors.data();
    v.injury = injury.empty() ? nullptr : injury.data();
    v.triangles = triangles.data();
    v.triangle_count = triangles.size() / 3;
    return v;
  }
};

struct Material {
  Eigen::Vector4f diffuse{0.8f, 0.8f, 0.8f, 1.0f};  // alpha < 1: drawn translucent after the opaque objects
  Eigen::Vector3f specular{0.2f, 0.2f, 0.2f};
  float shininess = 16.0f;
  // Issue 16. 0..1: a metal's highlights take its own colour and it mirrors the eye's interior (the glow of the lit
  // fundus below, the dark pupil above) and the microscope's coaxial light; metals are lit everywhere (small).
  float metallic = 0.0f;
  // Grazing-angle (Fresnel-like) reflex of the light pipe's light on a wet, translucent film: where the membrane is
  // lifted its surface tilts and the sheen appears (the surgeon's cue of a lifted edge).
  float sheen = 0.0f;
  // Light pipe: the fibre end glows — fragments within this distance (m) behind the object's z = 0 tip plane are
  // emissive (instrument frame of vrm_sim's instrument_meshes.h: tip at z = 0, shaft along -z).
  float glow_tip_length = 0.0f;
  // Issue 37: light the object gives off itself (linear RGB added to its shaded colour): the laser's aiming beam on the
  // retina. An emissive object is never cached in the static layer (the aim moves every frame).
  Eigen::Vector3f emission = Eigen::Vector3f::Zero();
};

// Issue 37: a laser burn painted into the fundus texture (vrm_sim scenario::LaserBurn): a whitened disc on the retina.
struct FundusBurn {
  Eigen::Vector3f position = Eigen::Vector3f::Zero();  // eye frame, on the retina
  float diameter = 0.0f;                               // m, the visible lesion
  float whiteness = 0.0f;                              // 0..1
};

struct ObjectStyle {
  Material material;
  bool casts_shadow = false;  // §7.4.2: only the interacting instrument and abstract objects cast shadows
  bool bump_mapped = false;   // procedural normal perturbation (the retina)
  bool fundus = false;        // the retina: albedo from the fundus texture (FundusMap, sampled at object x, y)
  bool ghost = false;         // translucent replay of an instructor's instrument
  bool deformable = false;    // GL_STREAM_DRAW buffers re-filled whenever the version changes
};

// The light pipe's fibre end: a spotlight at `tip` shining along `direction` (thesis §7.4.2, pass 2).
struct LightPipe {
  bool enabled = false;
  Eigen::Vector3f tip = Eigen::Vector3f::Zero();
  Eigen::Vector3f direction{0.0f, 0.0f, -1.0f};
  float cone_half_angle_rad = 0.6f;  // outer edge of the cone
  float cone_softness = 0.25f;       // fraction of the cone over which the edge fades
  float intensity = 1.6f;
  float range = 0.012f;  // distance at which the light has fallen to half (1 / (1 + (d / range)^2))
  float shadow_near = 0.0003f;
  float shadow_far = 0.04f;
};

// Microscope knobs (vrm_msgs/MicroscopeSettings, EyeSi: focus, zoom, ambient light; reduced disparity, §6).
struct MicroscopeState {
  double focus_distance = 0.2;  // m, objective to focal plane
  double zoom = 1.0;
  double ambient_light = 0.3;    // 0..1
  double disparity_scale = 1.0;  // 0..1
};

// Fixed optics of the microscope, in the renderer's world frame (the ROS "world" frame in the nodelet).
struct MicroscopeRig {
  // Objective above the eye on the optical axis; 0.188 m puts the default 0.2 m focal plane on the posterior pole
  // of a 12 mm eye centred at the origin.
  Eigen::Vector3f objective{0.0f, 0.0f, 0.188f};
  Eigen::Vector3f view_direction{0.0f, 0.0f, -1.0f};
  Eigen::Vector3f up{0.0f, 1.0f, 0.0f};
  float field_width = 0.03f;       // m, width of the field at the focal plane at zoom 1
  float stereo_baseline = 0.022f;  // m between the two optical paths of a surgical stereo microscope
  float near_plane = 0.1f;
  float far_plane = 0.3f;
  // Depth of field from the objective's circle of confusion (issue 16): a point at distance z from the objective,
  // focused at s, blurs to a disc of diameter aperture * |z - s| / z in the focal plane (thin lens, object side),
  // i.e. aperture * |z - s| / z * width * zoom / field_width pixels. Defaults of a surgical stereo microscope: the
  // objective f = 200 mm (working distance = default focus), each stereo channel's entrance pupil ~10 mm (NA
  // ~0.025; geometric depth of field ~2 mm at a 50 µm acceptable blur, as quoted for ophthalmic microscopes at
  // medium magnification).
  float objective_focal_length = 0.2f;
  float aperture_diameter = 0.010f;
};

enum class Eye { kLeft = 0, kRight = 1 };

struct RenderOptions {
  int width = 800;  // per eye
  int height = 600;
  bool stereo = true;  // false: mono, only the left image (from the objective's centre)
  bool shadow_pass = true;
  bool lighting = true;  // spotlight + Phong; off: flat material colour scaled by the ambient light
  bool bump_mapping = true;
  bool fundus = true;  // the fundus texture on objects styled `fundus` (off: their material colour)
  bool dof_pass = true;
  // Lit shader only for the triangles the spotlight may reach (the shadow lookup only for those a shadow may reach),
  // the ambient-only one for the rest (same image; off: the lit shader everywhere, for comparison).
  bool light_partition = true;
  // Issue 30: the opaque static objects (not deformable, not metal, not casting shadows: the retina) are kept per eye
  // as an ambient-only layer (colour, DOF weight, depth) and re-drawn only when they, the eye's camera, the
  // microscope or the fundus change; each frame starts from a copy of it and draws only the triangles the spotlight
  // may reach lit over it (same image; off: every triangle every frame, for comparison). Needs light_partition.
  bool cache_static = true;
  // cache_static: a static object is drawn at its previous (anchor) pose while its new pose moves no point of it by
  // more than this many pixels (at the focal plane): the tracker's sub-pixel jitter of the eye then keeps the layer.
  float static_pose_tolerance_px = 0.5f;
  int shadow_map_size = 512;
  int dof_downsample = 4;     // blur at 1/4 (or 1/2, 1) resolution, separable 9 taps: §7.4.2 pass 3 is the costliest
  float dof_sigma_px = 1.5f;  // Gaussian sigma at the reduced resolution (x dof_downsample at full resolution)
  int dof_taps = 9;           // 9 or 13 (the plain reference frame of bench_render: 13 taps at full resolution)
  float ghost_alpha = 0.35f;
  Eigen::Vector3f background{0.02f, 0.02f, 0.02f};
  Eigen::Vector3f blood_colour{0.55f, 0.02f, 0.02f};
  bool time_passes = true;  // glFinish between passes so per-pass times are meaningful (costs a little overlap)
};

struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> data;  // RGB8, top row first
  const std::uint8_t* pixel(int x, int y) const { return data.data() + (static_cast<std::size_t>(y) * width + x) * 3; }
};

struct PassTimings {
  double ms_upload = 0.0;  // streaming changed deformable meshes
  double ms_shadow = 0.0;
  double ms_scene = 0.0;  // both eyes
  double ms_dof = 0.0;    // both eyes: reduced-resolution blur + the CPU blend
  double ms_readback = 0.0;
  double ms_total = 0.0;
  std::size_t triangles_drawn = 0;  // scene pass, both eyes
  std::size_t objects_culled = 0;
  int static_layers_drawn = 0;  // eyes whose static layer was (re)drawn this frame (cache_static: 0 while unchanged)
};

struct StereoFrame {
  std::array<RgbImage, 2> images;  // [left, right]; mono: only images[0]
  PassTimings timings;
};

}  // namespace vrm_render
