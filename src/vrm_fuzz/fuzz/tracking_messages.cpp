// Every message handler of vrm_tracking's nodelets and the latency monitor with arbitrary field values, through the
// same conversions and ROS-free core calls as the nodelets:
//   tracker          MarkerObservations -> fromMsg -> PoseTracker::update (frames assembled per stamp as the
//                    nodelet does) -> toMsg(EyeEstimate / InstrumentEstimate with the latest instrument_sensors);
//                    InstrumentState (instrument_sensors)
//   marker_detector  CameraInfo -> updateIntrinsics (rig_calibrator and tracker read intrinsics the same way)
//   camera_rig_sim   EyeState, InstrumentState (ground truth) -> fromMsg -> worldSceneFromSnapshot
//   microscope_sim   PedalState -> fromMsg -> MicroscopeKnobs::update; MicroscopeSettings (setpoint, with the
//                    nodelet's finite check)
//   latency_monitor  StageTiming -> world::StageChain / SlidingWindow / DropCounter
// The first byte selects the pose filter of the tracker (none / one_euro / alpha_beta).
#include <vrm_msgs/StageTiming.h>

#include <cmath>
#include <map>

#include "ros_messages.h"
#include "vrm_sim/world/latency.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/marker_layout.h"
#include "vrm_tracking/microscope_knobs.h"
#include "vrm_tracking/pose_tracker.h"

namespace {

using namespace vrm_tracking;

void publishTracking(const TrackingResult& result, const std::map<std::string, vrm_msgs::InstrumentState>& sensors) {
  vrm_msgs::EyeState eye;
  toMsg(result.eye, &eye);
  for (const InstrumentEstimate& estimate : result.instruments) {
    vrm_msgs::InstrumentState msg;
    const auto sensor = sensors.find(estimate.slot);
    toMsg(estimate, sensor == sensors.end() ? nullptr : &sensor->second, &msg);
  }
}

}  // namespace

VRM_FUZZ_TARGET(tracking_messages) {
  vrm_fuzz::Bytes in(data, size);
  if (in.empty()) return 0;
  static const CameraRig rig = makeDefaultRig();
  static const MarkerLayout layout = makeDefaultLayout();
  TrackerConfig config;
  const std::uint8_t filter = in.take<std::uint8_t>() % 3;
  config.filter.type = filter == 0 ? FilterType::kNone : (filter == 1 ? FilterType::kOneEuro : FilterType::kAlphaBeta);
  PoseTracker tracker(rig, layout, config);
  MicroscopeKnobs knobs{MicroscopeLimits{}};
  MicroscopeSample setpoint;
  std::map<std::string, vrm_msgs::InstrumentState> sensors;
  std::map<ros::Time, std::map<std::size_t, CameraObservations>> pending;
  vrm_sim::world::StageChain chain;
  vrm_sim::world::SlidingWindow window(1'000'000'000, 256);
  vrm_sim::world::DropCounter drops;
  SurgeonSnapshot snapshot;

  vrm_fuzz::Frame frame;
  int messages = 0;
  while (messages++ < 64 && vrm_fuzz::nextFrame(in, &frame)) {
    switch (frame.kind % 8) {
      case 0:
      case 1: {  // the tracker's markers, on camera (kind / 8) % 4: a fourth, unknown camera included
        vrm_msgs::MarkerObservations msg;
        if (!vrm_fuzz::deserialize(frame, &msg)) break;
        const std::size_t camera = (frame.kind / 8) % 4;
        if (camera >= rig.size()) break;  // the nodelet subscribes to the rig's cameras only
        pending[msg.header.stamp][camera] = CameraObservations{camera, fromMsg(msg)};
        // Frames are reconstructed once every camera reported, or older ones when a newer stamp arrives.
        while (!pending.empty() &&
               (pending.begin()->second.size() == rig.size() || pending.begin()->first < msg.header.stamp)) {
          std::vector<CameraObservations> observations;
          for (auto& entry : pending.begin()->second) observations.push_back(entry.second);
          const double stamp = pending.begin()->first.toSec();
          pending.erase(pending.begin());
          publishTracking(tracker.update(observations, stamp), sensors);
        }
        break;
      }
      case 2: {  // tracker: instrument_sensors; camera_rig_sim: ground truth
        vrm_msgs::InstrumentState msg;
        if (!vrm_fuzz::deserialize(frame, &msg)) break;
        sensors[msg.instrument_id] = msg;
        try {
          snapshot.instruments.push_back(fromMsg(msg));
          if (snapshot.instruments.size() > 4) snapshot.instruments.erase(snapshot.instruments.begin());
        } catch (const std::invalid_argument&) {  // an unknown instrument type (fromMsg)
        }
        worldSceneFromSnapshot(snapshot, layout);
        break;
      }
      case 3: {  // camera_rig_sim: ground-truth eye
        vrm_msgs::EyeState msg;
        if (!vrm_fuzz::deserialize(frame, &msg)) break;
        snapshot.eye_rotation = toEigen(msg.rotation);
        snapshot.rotation_center = toEigen(msg.rotation_center);
        worldSceneFromSnapshot(snapshot, layout);
        break;
      }
      case 4: {  // marker_detector / tracker: camera_info
        sensor_msgs::CameraInfo msg;
        if (!vrm_fuzz::deserialize(frame, &msg)) break;
        CameraModel camera = rig.cameras[0];
        try {
          updateIntrinsics(msg, &camera);
          Eigen::Vector2d pixel;
          if (camera.project(Eigen::Vector3d::Zero(), &pixel)) camera.normalise(pixel);
        } catch (const std::invalid_argument&) {
        }
        break;
      }
      case 5: {  // microscope_sim: pedals
        vrm_msgs::PedalState msg;
        if (!vrm_fuzz::deserialize(frame, &msg)) break;
        const double dt = static_cast<double>(msg.header.stamp.nsec) * 1e-9;
        vrm_msgs::MicroscopeSettings settings;
        toMsg(knobs.update(setpoint, fromMsg(msg), dt), &settings);
        break;
      }
      case 6: {  // microscope_sim: setpoint
        vrm_msgs::MicroscopeSettings msg;
        if (!vrm_fuzz::deserialize(frame, &msg)) break;
        if (!std::isfinite(msg.zoom) || !std::isfinite(msg.focus_distance) || !std::isfinite(msg.ambient_light) ||
            !std::isfinite(msg.disparity_scale)) {
          break;
        }
        setpoint = fromMsg(msg);
        knobs.reset();
        break;
      }
      case 7: {  // latency_monitor
        vrm_msgs::StageTiming msg;
        if (!vrm_fuzz::deserialize(frame, &msg)) break;
        const auto stamp = static_cast<vrm_sim::world::Nanoseconds>(msg.header.stamp.toNSec());
        std::vector<vrm_sim::world::StageSpan> spans;
        for (const vrm_msgs::StageStamp& stage : msg.stages) {
          spans.push_back({stage.stage, static_cast<vrm_sim::world::Nanoseconds>(stage.start.toNSec()),
                           static_cast<vrm_sim::world::Nanoseconds>(stage.end.toNSec())});
        }
        for (const vrm_sim::world::StageSample& sample : chain.add(stamp, spans)) {
          window.add(stamp, sample.latency_ms);
          if (sample.stage == vrm_sim::world::kCameraStage) drops.offer(stamp);
          if (sample.stage == vrm_sim::world::kTrackingStage) drops.take(stamp);
        }
        window.summary();
        break;
      }
    }
  }
  return 0;
}
