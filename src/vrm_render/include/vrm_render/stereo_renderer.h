#pragma once
// The stereo microscope renderer of EyeSi (thesis §6, §7.4.2), ROS-free, OpenGL 3.3 core through the shared OSMesa
// context (vrm_gl). Per frame:
//   pass 1  shadow map from the light pipe; only objects with casts_shadow (the interacting instrument, abstract
//           objects) are drawn into it;
//   pass 2  the scene per eye: Phong shading with a per-pixel spotlight cone from the light pipe tip (shadowed),
//           procedural bump mapping on the retina, vertex colour and injury (bleeding) on the tissue; opaque objects
//           front to back (early depth), translucent ones (membrane, ghost instruments) back to front. llvmpipe runs
//           both sides of every shader branch, so each frame the triangles are partitioned on the CPU: those that
//           may reach into a pyramid around the cone are drawn with the lit shader (with the shadow lookup only if
//           they may also reach the casters' rectangle in the shadow map), the rest with an ambient-only one; each
//           triangle is drawn once, the image is the same (test SpotlightPartition...) at a fraction of the cost.
//           Opaque pixels store their depth-of-field weight in alpha;
//           The retina's albedo comes from the fundus texture (FundusMap: disc, vessels, macula, choroid), baked once;
//           instruments are metallic (mirrored fundus glow, coaxial highlight), the light pipe's fibre end glows;
//           the membrane shows a sheen where it tilts (lifted);
//   pass 3  depth of field (circle of confusion of the objective, MicroscopeRig): the scene is blurred at reduced
//   resolution with a separable Gaussian; the blend with
//           the sharp image by that weight is fused with the readback on the CPU (cheaper than a full-resolution
//           pass on llvmpipe). Both eyes are submitted before either is read back, so one eye's rasterisation
//           overlaps the next eye's binning and the previous eye's blend.
// Static geometry lives in GPU buffers uploaded once; deformable meshes are streamed only when their version
// changes. Objects outside a frustum are not drawn.
// The static layer (issue 30, RenderOptions::cache_static): the opaque static objects (the retina) are kept per eye
// as an ambient-only image with its DOF weight and depth, redrawn only when they, the eye's camera, the microscope or
// the fundus change (and then held still for a frame); a frame starts from a copy of it and pass 2 draws over it
// only the instruments, the translucent objects and the static triangles the spotlight may reach. Same image (test
// StaticLayerCache...); a static object moved by less than static_pose_tolerance_px (tracker jitter) is drawn at
// its anchor pose.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "vrm_render/fundus.h"
#include "vrm_render/microscope_camera.h"
#include "vrm_render/render_state.h"
#include "vrm_render/render_types.h"

namespace vrm_gl {
class GlContext;
}

namespace vrm_render {

class StereoRenderer {
 public:
  // Creates its own OSMesa context. Throws RenderError if no context (or a too large image) can be had.
  explicit StereoRenderer(const RenderOptions& options = {}, const MicroscopeRig& rig = {});
  ~StereoRenderer();
  StereoRenderer(const StereoRenderer&) = delete;
  StereoRenderer& operator=(const StereoRenderer&) = delete;

  // Adds or replaces the mesh of object `id` when `version` differs from the uploaded one (returns true if it
  // uploaded). Throws RenderError for empty meshes, non-finite values, indices out of range or more than
  // kMaxVertices / kMaxTriangles; the object then keeps its previous mesh.
  bool updateMesh(const std::string& id, const MeshView& mesh, std::uint64_t version);
  void setStyle(const std::string& id, const ObjectStyle& style);  // objects may be styled before their mesh exists
  void setPose(const std::string& id, const Eigen::Isometry3f& world_from_object);
  void setVisible(const std::string& id, bool visible);
  bool hasObject(const std::string& id) const;
  std::uint64_t version(const std::string& id) const;  // 0 when unknown
  // Forgets object `id` (mesh, GPU buffers, style, pose); unknown ids are ignored. A scene switch (issue 32) removes
  // the previous scene's objects, so none of them is drawn, culled or cached into the static layer afterwards.
  void removeObject(const std::string& id);
  // Every object the renderer knows (styled, posed or with a mesh), sorted.
  std::vector<std::string> objectIds() const;
  std::size_t triangleCount(const std::string& id) const;  // of its mesh (0 when it has none)

  void setLightPipe(const LightPipe& light) { light_ = light; }
  // The fundus that objects styled `fundus` show (issue 16). Without one, the first frame that needs it bakes the
  // default FundusMap (seed 1). The map is shared, so the simulation can query the same vessel tree.
  void setFundus(std::shared_ptr<const FundusMap> fundus);
  const FundusMap& fundus();
  // Issue 37: the laser burns painted into the fundus texture (eye frame, like the fundus). A list that extends the
  // previous one paints only the new burns and uploads their rectangles; any other list repaints from the baked
  // texture. Burns persist across setFundus (they are painted into the new map). Non-finite burns are skipped.
  void setFundusBurns(const std::vector<FundusBurn>& burns);
  const std::vector<FundusBurn>& fundusBurns() const;
  void setMicroscope(const MicroscopeState& state);  // throws RenderError for non-finite / non-positive knobs
  // Changes size, stereo or passes; throws RenderError (state unchanged) for sizes beyond kMaxImageSide.
  void setOptions(const RenderOptions& options);

  const RenderOptions& options() const { return options_; }
  const MicroscopeRig& rig() const { return rig_; }
  const MicroscopeState& microscope() const { return microscope_; }
  CameraView camera(Eye eye) const;
  std::size_t triangleCount() const;  // of all visible objects

  // Renders all passes for both eyes (or one in mono) and reads the images back into `frame` (buffers reused).
  void render(StereoFrame* frame);

  // Issue 33: what the last frame was drawn from (objects at their drawn poses, meshes read back from the GPU
  // buffers, so nothing is kept on the CPU for it), and the way back: after restoreState(captureState()) a renderer
  // draws the same frame. restoreState removes every other object; it throws RenderStateError when the state is
  // invalid or its fundus texture hash differs from the fundus these parameters bake today (the generator changed).
  // `same_fundus` false accepts a changed fundus generator (then the frame shows today's fundus).
  RenderState captureState() const;
  void restoreState(const RenderState& state, bool same_fundus = true);
  // Every call binds the renderer's context to the calling thread. A thread that is not the one drawing (a nodelet's
  // start-up, a snapshot on a service thread) lets it go afterwards (vrm_gl::GlContext::releaseCurrent).
  static void releaseContext();
  // The last frame's depth buffer of one eye (window depth 0..1, top row first, width x height): the check tools
  // find the visible surface point of each pixel from it (CameraView::viewProjection inverse).
  void readDepth(Eye eye, std::vector<float>* depth) const;

  static constexpr std::size_t kMaxVertices = 4'000'000;
  static constexpr std::size_t kMaxTriangles = 8'000'000;
  static constexpr int kMaxImageSide = 4096;

 private:
  struct Impl;
  struct FrameState;  // per frame: the light pipe's spotlight and shadow map, ambient light, the fundus
  struct SceneDraw;   // per eye: the scene program variants in use and how an object is drawn with them

  // The steps of render(), in order.
  void anchorStaticPoses();                             // static objects: anchor pose within tolerance (cache_static)
  FrameState beginFrame();                              // light set-up; bakes / binds the fundus texture
  void partitionForSpotlight(const FrameState& frame);  // before pass 1: rewrites index buffers
  void renderShadowMap(const FrameState& frame, PassTimings* timings);              // pass 1
  void renderScene(int eye, const FrameState& frame, PassTimings* timings);         // pass 2
  void blurForDepthOfField(int eye, PassTimings* timings);                          // pass 3a, on the GPU
  void readBack(int eye, int eye_count, StereoFrame* frame, PassTimings* timings);  // pass 3b, on the CPU
  void waitForPass() const;  // glFinish when options().time_passes, so that per-pass times mean something

  std::unique_ptr<Impl> impl_;
  RenderOptions options_;
  MicroscopeRig rig_;
  MicroscopeState microscope_;
  LightPipe light_;
};

// llvmpipe allocates and frees its vertex and bin buffers for every draw; with glibc's defaults these large blocks
// go back to the kernel each time and come back as fresh pages (about 3,000 page faults per stereo frame, ~5-10 %
// of the frame's CPU time). This keeps freed memory in the heap (mmap threshold 256 MB, trim threshold 1 GB). It
// changes malloc for the whole process, so the application calls it (the benchmark and the nodelet do); the
// renderer itself does not.
void retainFreedHeapMemory();

}  // namespace vrm_render
