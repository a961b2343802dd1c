#pragma once
// Everything a StereoRenderer frame is drawn from (issue 33): every object's mesh, version, style, pose (as drawn) and
// visibility, the light pipe, the microscope knobs and rig, the fundus parameters and the render options. A saved
// snapshot keeps it beside its PNGs (`<prefix>.frame`), so the frame can be re-rendered later — identically, or with
// one pass switched off (frame_check: shadows, focus, light) — without running the graph again.
//
// File format (little-endian, as written by this machine): the magic "VRMFRAME", a u32 format version, then the
// fields in the order of encodeRenderState; strings and arrays are u64-length-prefixed. The reader checks every
// length against what is left of the file and the renderer's limits, and rejects non-finite poses, lights and knobs:
// a bad or truncated file gives a RenderStateError naming the file and what was being read.

#include <cstdint>
#include <string>
#include <vector>

#include "vrm_render/fundus.h"
#include "vrm_render/render_types.h"

namespace vrm_render {

class RenderStateError : public RenderError {
 public:
  using RenderError::RenderError;
};

struct RenderState {
  struct Object {
    std::string id;
    bool has_mesh = false;
    std::uint64_t version = 0;
    MeshData mesh;  // object frame; normals always present (computed ones included), colours / injury when set
    ObjectStyle style;
    Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();  // as drawn in the frame (a static object's anchor)
    bool visible = true;
  };
  RenderOptions options;
  MicroscopeRig rig;
  MicroscopeState microscope;
  LightPipe light;
  bool has_fundus = false;  // a fundus map was set (else the renderer bakes the default one when it needs it)
  FundusParams fundus;
  std::uint64_t fundus_texture_hash = 0;  // FNV-1a of the baked texture: a restore checks it gets the same fundus
  std::vector<Object> objects;            // sorted by id
  std::vector<FundusBurn> burns;          // issue 37: painted into the fundus (format 2)
};

// 2 (issue 37): materials' emission and the fundus burns. Files of format 1 are read (no emission, no burns).
constexpr std::uint32_t kRenderStateFormatVersion = 2;

// Throws RenderStateError for non-finite poses, light, knobs or mesh values, indices out of range, bad sizes.
void validateRenderState(const RenderState& state);
// The bytes of the file (no validation: tests use it to make bad files).
std::string encodeRenderState(const RenderState& state);
// Parses and validates; `what` names the source in errors (a path).
RenderState decodeRenderState(const std::string& bytes, const std::string& what = "render state");
// validate + encode + write (to a temporary file, renamed into place: a reader never sees half a file).
void writeRenderState(const RenderState& state, const std::string& path);
RenderState readRenderState(const std::string& path);

// FNV-1a (64 bit) of a fundus map's texture.
std::uint64_t fundusTextureHash(const FundusMap& fundus);

}  // namespace vrm_render
