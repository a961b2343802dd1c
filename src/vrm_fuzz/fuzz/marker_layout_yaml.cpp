// Marker layout files (vrm_tracking marker_layout.h): an accepted layout builds the detector's lookup table, feeds
// a pose tracker with the default rig, and turns a surgeon snapshot into world markers (camera_rig_sim's path). The
// detector's 64^3 lookup table takes ~60 ms under ASan, so that deep path runs only for inputs whose size is a
// multiple of 8 (the fuzzer reaches both; the parser, the part this target is for, runs ~100x faster). The deep path
// applies the default scene's trocars first, as the tracker nodelet does.
#include <memory>
#include <stdexcept>

#include "fuzz_target.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/marker_detector.h"
#include "vrm_tracking/marker_layout.h"
#include "vrm_tracking/pose_tracker.h"
#include "vrm_tracking/scene_trocars.h"

VRM_FUZZ_TARGET(marker_layout_yaml) {
  using namespace vrm_tracking;
  const std::string text(reinterpret_cast<const char*>(data), size);
  MarkerLayout layout;
  try {
    layout = layoutFromYamlString(text, "fuzzed_layout.yaml");
  } catch (const std::runtime_error&) {
    return 0;
  }
  for (const ColourClass& colour : layout.classes) layout.findClass(colour.id);
  for (const InstrumentMarker& instrument : layout.instruments) layout.findSlot(instrument.slot);
  if (size % 8 != 0) return 0;
  MarkerDetector detector(layout.classes);
  detector.classify(0, 0, 255);
  detector.classify(255, 0, 0);

  // As the tracker nodelet takes a layout (loadLayout): the default scene decides the eye centre and the trocars a
  // layout leaves to it (applyScene), before the PoseTracker, which refuses a slot without a trocar, gets it.
  // A layout the scene or the tracker refuses ends the nodelet's start-up with that message (NODELET_FATAL): a clear
  // error, not a crash.
  static const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(sceneOrDefault(""));
  static const CameraRig rig = makeDefaultRig();
  std::unique_ptr<PoseTracker> built;
  try {
    applyScene(scene, &layout);
    built = std::make_unique<PoseTracker>(rig, layout);
  } catch (const std::exception&) {
    return 0;
  }
  PoseTracker& tracker = *built;
  std::vector<CameraObservations> frame;
  for (std::size_t c = 0; c < rig.size(); ++c) {
    CameraObservations observations{c, {}};
    for (const ColourClass& colour : layout.classes) {
      Blob blob;
      blob.class_id = colour.id;
      blob.u = 320.0 + 10.0 * static_cast<double>(c);
      blob.v = 240.0 - 7.0 * colour.id;
      blob.area = 20.0;
      blob.quality = 1.0;
      observations.blobs.push_back(blob);
    }
    frame.push_back(observations);
  }
  tracker.update(frame, 0.0);

  SurgeonSnapshot snapshot;
  for (const InstrumentMarker& instrument : layout.instruments) {
    InstrumentSample sample;
    sample.slot = instrument.slot;
    sample.trocar = instrument.trocar;
    sample.tip = Eigen::Vector3d(0.0, 0.0, -0.005);
    snapshot.instruments.push_back(sample);
  }
  worldSceneFromSnapshot(snapshot, layout);
  return 0;
}
