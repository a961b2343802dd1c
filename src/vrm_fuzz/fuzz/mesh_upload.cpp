// The renderer's mesh upload and scene update path (vrm_render StereoRenderer, issue 39 §3), as the stereo_renderer
// nodelet drives it: TissueMesh messages through conversions.h toMeshView into updateMesh (validation, GPU buffer
// upload, replacement of a previous mesh), poses through toIsometry into setPose, microscope knobs, laser burns
// (toFundusBurns -> setFundusBurns), visibility, removal, and a frame rendered and read back. One renderer per
// process (an OSMesa context costs ~0.1 s): the harness removes every object after each input, so an input starts
// from an empty scene (the fundus texture and the GL context persist, as in the nodelet).
// Input: frames [u8 kind][u16 length][bytes]; kind % 8: 0 TissueMesh, 1 Pose (+ object), 2 MicroscopeSettings,
// 3 SimulationState (burns), 4 light pipe pose (scene_setup.h lightPipeAt), 5 visibility / removal, 6 style, 7 render.
// The object of a frame is chosen by the kind's high bits (4 ids: a deformable membrane, a fundus-textured static, a
// shadow-casting instrument and a ghost).
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/SimulationState.h>
#include <vrm_msgs/TissueMesh.h>

#include <memory>

#include "ros_messages.h"
#include "vrm_render/conversions.h"
#include "vrm_render/scene_setup.h"
#include "vrm_render/stereo_renderer.h"

namespace {

vrm_render::StereoRenderer& renderer() {
  static std::unique_ptr<vrm_render::StereoRenderer> instance = [] {
    vrm_render::RenderOptions options;
    options.width = 64;  // per eye: every pass runs, at a size that keeps a frame cheap
    options.height = 48;
    options.shadow_map_size = 64;
    options.time_passes = false;
    return std::make_unique<vrm_render::StereoRenderer>(options);
  }();
  return *instance;
}

const char* const kIds[] = {"membrane", "retina", "instrument_right", "ghost_left"};

vrm_render::ObjectStyle styleFor(int object, std::uint8_t bits) {
  vrm_render::ObjectStyle style;
  style.deformable = object == 0 || (bits & 1);
  style.fundus = object == 1 || (bits & 2);
  style.bump_mapped = object == 1 || (bits & 4);
  style.casts_shadow = object == 2 || (bits & 8);
  style.ghost = object == 3 || (bits & 16);
  style.material.diffuse.w() = (bits & 32) ? 0.5f : 1.0f;  // alpha < 1: the translucent pass
  return style;
}

}  // namespace

VRM_FUZZ_TARGET(mesh_upload) {
  using namespace vrm_render;
  StereoRenderer& r = renderer();
  vrm_fuzz::Bytes in(data, size);
  vrm_fuzz::Frame frame;
  StereoFrame image;
  int messages = 0, renders = 0;
  while (messages++ < 32 && vrm_fuzz::nextFrame(in, &frame)) {
    const int object = (frame.kind >> 3) & 3;
    const std::string id = kIds[object];
    switch (frame.kind % 8) {
      case 0: {
        vrm_msgs::TissueMesh mesh;
        if (!vrm_fuzz::deserialize(frame, &mesh)) break;
        if (!r.hasObject(id)) r.setStyle(id, styleFor(object, 0));
        try {
          r.updateMesh(id, toMeshView(mesh), mesh.version);
        } catch (const RenderError&) {  // the nodelet logs it; the object keeps its previous mesh
        }
        break;
      }
      case 1: {
        geometry_msgs::Pose pose;
        if (!vrm_fuzz::deserialize(frame, &pose)) break;
        try {
          r.setPose(id, toIsometry(pose));
        } catch (const RenderError&) {  // a non-finite pose: the nodelet warns and skips it
        }
        break;
      }
      case 2: {
        vrm_msgs::MicroscopeSettings settings;
        if (!vrm_fuzz::deserialize(frame, &settings)) break;
        try {
          r.setMicroscope(toMicroscopeState(settings));
        } catch (const RenderError&) {
        }
        break;
      }
      case 3: {
        vrm_msgs::SimulationState state;
        if (vrm_fuzz::deserialize(frame, &state)) r.setFundusBurns(toFundusBurns(state));
        break;
      }
      case 4: {
        geometry_msgs::Pose pose;  // the light pipe instrument's pose, as the nodelet sets the spotlight from it
        if (!vrm_fuzz::deserialize(frame, &pose)) break;
        LightPipe light = lightPipeAt(toIsometry(pose));
        light.enabled = (frame.kind & 0x80) != 0;
        r.setLightPipe(light);
        break;
      }
      case 5:
        if (frame.kind & 0x80) {
          r.removeObject(id);
        } else {
          r.setVisible(id, (frame.kind & 0x20) != 0);
        }
        break;
      case 6:
        r.setStyle(id, styleFor(object, frame.size > 0 ? frame.data[0] : 0));
        break;
      case 7:
        if (renders++ < 1) r.render(&image);  // one frame per input: a frame costs ~10 ms under ASan
        break;
    }
  }
  for (const std::string& id : r.objectIds()) r.removeObject(id);
  return 0;
}
