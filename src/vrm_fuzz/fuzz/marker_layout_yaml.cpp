// Marker layout files (vrm_tracking marker_layout.h): an accepted layout builds the detector's lookup table, feeds
// a pose tracker with the default rig, and turns a surgeon snapshot into world markers (camera_rig_sim's path). The
// detector's 64^3 lookup table takes ~60 ms under ASan, so that deep path runs only for inputs whose size is a
// multiple of 8 (the fuzzer reaches both; the parser, the part this target is for, runs ~100x faster).
#include <stdexcept>

#include "fuzz_target.h"
#include "vrm_tracking/marker_detector.h"
#include "vrm_tracking/marker_layout.h"
#include "vrm_tracking/pose_tracker.h"

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

  static const CameraRig rig = makeDefaultRig();
  PoseTracker tracker(rig, layout);
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
