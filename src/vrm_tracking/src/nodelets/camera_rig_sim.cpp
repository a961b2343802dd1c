// Camera rig twin (issue 5, thesis §7.3.2): renders the three tracking cameras from the scripted surgeon's ground
// truth and publishes what real cameras would — sensor_msgs/Image + CameraInfo per camera through image_transport —
// plus, for evaluation only, the exact projected centroids (<camera>/markers_exact, the ideal FPGA output).
// The ticks are the VR part's mediator's input frames (vrm_sim/world/mediator.h, issue 31) with the no-wait policy:
// a frame closes as soon as the eye state and every instrument the truth publishes have arrived at its stamp, or a
// later stamp arrives (a slot the script does not play is never waited for; a state that comes late is drawn in the
// next frame). A slot without a state in a frame is drawn at its last state. The images carry the frame's stamp (the
// exposure midpoint), never the wall clock. The wall time the triple took goes to tracking_timing
// (vrm_msgs/StageTiming, stage "camera"; issue 12): the share of the tracking latency a real rig would not spend.
// Lazy (image_proc's pattern): the ground truth is subscribed only while someone subscribes to a camera's image_raw /
// camera_info or markers_exact, and a camera's image is rendered only while its image_raw or camera_info has a
// subscriber (markers_exact alone costs a projection, not a render). tracking_timing does not count: it reports the
// work and never asks for it. (The chessboard views for calibration are calibration_fixture's.)
// Fault injection (tests, issue 14): `stop_camera`/`stop_after` stop one camera for good after a frame count;
// ~fault (std_msgs/String, camera_fault.h) stops cameras for a wall duration or resumes them while running, e.g.
// "stop camera_1 2.0", "stop all 2.0", "resume". A stopped camera publishes nothing (images, markers_exact).
// The scene (issue 32): none is loaded here, so there is nothing to follow on running_scene. The eye's rotation
// centre comes with each ground-truth eye state and an instrument's trocar with its state (tip - depth * axis): the
// scripted surgeon builds both from the running scene. The markers (colours, positions on the eye) are the layout's.

#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <std_msgs/String.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MarkerObservations.h>
#include <vrm_msgs/StageTiming.h>
#include <vrm_msgs/publish.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <pluginlib/class_list_macros.hpp>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "vrm_sim/conversions.h"
#include "vrm_sim/world/mediator.h"
#include "vrm_tracking/camera_fault.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/rig_renderer.h"

namespace vrm_tracking {

class CameraRigSim : public nodelet::Nodelet {
 private:
  // A set-up that throws closes every handle it opened before the exception leaves onInit: Debian's nodelet::Loader
  // frees this nodelet's callback queues when init throws and destroys the nodelet only afterwards, so a subscriber
  // still open then unregisters from a freed queue and takes the manager down with it.
  void onInit() override {
    try {
      init();
    } catch (const std::exception& e) {
      closeRosHandles();
      NODELET_FATAL("camera_rig_sim cannot start: %s", e.what());
      throw;
    } catch (...) {
      closeRosHandles();
      NODELET_FATAL("camera_rig_sim cannot start: an exception that is not a std::exception");
      throw;
    }
  }

  void init() {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::string rig_file, layout_file;
    pnh.param<std::string>("rig_file", rig_file, "");
    pnh.param<std::string>("layout_file", layout_file, "");
    rig_ = rig_file.empty() ? makeDefaultRig() : loadRigYaml(rig_file);
    layout_ = layout_file.empty() ? makeDefaultLayout() : loadLayoutYaml(layout_file);
    RenderConfig config;
    pnh.param("blur_px", config.blur_px, config.blur_px);
    pnh.param("read_noise", config.read_noise, config.read_noise);
    pnh.param("shot_gain", config.shot_gain, config.shot_gain);
    pnh.param("exposure", config.exposure, config.exposure);
    pnh.param("exposure_time", config.exposure_time, config.exposure_time);
    pnh.param("clutter", config.clutter, config.clutter);
    pnh.param("distractors", config.distractors, config.distractors);
    pnh.param("shafts", config.shafts, config.shafts);
    // The earlier full-frame renderer (rig_renderer.h, issue 30 item 4): same images, about 3x the cost.
    pnh.param("reference_renderer", config.reference_path, config.reference_path);
    int seed = 1;
    pnh.param("seed", seed, seed);  // a parameter, so a session's noise is reproducible (§2.4.2)
    config.seed = static_cast<std::uint32_t>(seed);
    // Fault injection for tests: camera `stop_camera` stops publishing after `stop_after` frames.
    pnh.param("stop_camera", stop_camera_, -1);
    pnh.param("stop_after", stop_after_, 0);
    stopped_until_.assign(rig_.size(), ros::WallTime());
    renderer_ = std::make_unique<RigRenderer>(rig_, layout_, config);

    std::vector<std::string> slots;
    for (const InstrumentMarker& m : layout_.instruments) slots.push_back(m.slot);
    pnh.param("instrument_slots", slots, slots);
    expected_slots_ = slots;
    resetMediatorLocked();
    pnh.param<std::string>("optical_frame_suffix", frame_suffix_, "_optical");

    int calibration_views = 0;
    if (pnh.getParam("calibration_views", calibration_views) && calibration_views > 0) {
      throw std::invalid_argument(
          "calibration_views is no longer a mode of the rig twin: load vrm_tracking/calibration_fixture (views, "
          "rate, target_*) instead");
    }
    timing_pub_ = nh.advertise<vrm_msgs::StageTiming>("tracking_timing", 10);
    image_transport::ImageTransport it(nh);
    {
      // Held while advertising, so connectCb cannot subscribe before every publisher exists.
      std::lock_guard<std::mutex> lock(connect_mutex_);
      const image_transport::SubscriberStatusCallback image_cb =
          [this](const image_transport::SingleSubscriberPublisher&) { connectCb(); };
      const ros::SubscriberStatusCallback cb = [this](const ros::SingleSubscriberPublisher&) { connectCb(); };
      for (const CameraModel& cam : rig_.cameras) {
        camera_pubs_.push_back(it.advertiseCamera(cam.name + "/image_raw", 2, image_cb, image_cb, cb, cb));
        exact_pubs_.push_back(nh.advertise<vrm_msgs::MarkerObservations>(cam.name + "/markers_exact", 5, cb, cb));
      }
    }
    fault_sub_ = pnh.subscribe("fault", 10, &CameraRigSim::onFault, this);
    NODELET_INFO("camera_rig_sim: %zu cameras, %zu instrument slots, seed %d", rig_.size(), expected_slots_.size(),
                 seed);
  }

  void closeRosHandles() {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    fault_sub_.shutdown();
    eye_sub_.shutdown();
    instrument_sub_.shutdown();
    for (image_transport::CameraPublisher& pub : camera_pubs_) pub.shutdown();
    for (ros::Publisher& pub : exact_pubs_) pub.shutdown();
    camera_pubs_.clear();
    exact_pubs_.clear();
    timing_pub_.shutdown();
  }

  // Subscribes the ground truth when the first camera output gains a subscriber, drops it when the last one goes.
  void connectCb() {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    bool wanted = false;
    // Over the publishers there are (none once closeRosHandles ran), each camera's image and exact pair.
    for (std::size_t c = 0; c < camera_pubs_.size(); ++c) {
      wanted |= camera_pubs_[c].getNumSubscribers() > 0 || exact_pubs_[c].getNumSubscribers() > 0;
    }
    if (!wanted && eye_sub_) {
      eye_sub_.shutdown();
      instrument_sub_.shutdown();
      std::lock_guard<std::mutex> state_lock(mutex_);
      resetMediatorLocked();
      previous_stamp_ = ros::Time();  // no motion blur across the gap
      NODELET_DEBUG("camera_rig_sim: no subscriber left; ground truth unsubscribed");
    } else if (wanted && !eye_sub_) {
      ros::NodeHandle& nh = getNodeHandle();
      // Queues of about one tick: a camera exposes the present, so a slow render skips ticks instead of queueing
      // them (the tracker and the latency monitor see the gap).
      eye_sub_ = nh.subscribe("ground_truth/eye_state", 2, &CameraRigSim::onEye, this);
      instrument_sub_ = nh.subscribe("ground_truth/instrument_state",
                                     static_cast<std::uint32_t>(2 * std::max<std::size_t>(1, expected_slots_.size())),
                                     &CameraRigSim::onInstrument, this);
    }
  }

  void onFault(const std_msgs::String::ConstPtr& msg) {
    std::vector<std::string> names;
    for (const CameraModel& cam : rig_.cameras) names.push_back(cam.name);
    CameraFault fault;
    try {
      fault = parseCameraFault(msg->data, names);
    } catch (const std::invalid_argument& e) {
      NODELET_WARN("camera_rig_sim: %s; ignored", e.what());
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    // Wall time: the fault is what a person pulling a cable does, whatever the input stamps say.
    const ros::WallTime until = fault.action == CameraFault::Action::kResume ? ros::WallTime()
                                : fault.seconds > 0.0 ? ros::WallTime::now() + ros::WallDuration(fault.seconds)
                                                      : ros::WallTime(std::numeric_limits<std::int32_t>::max(), 0);
    const std::string what = fault.action == CameraFault::Action::kResume ? "resumed"
                             : fault.seconds > 0.0 ? "stopped for " + std::to_string(fault.seconds) + " s (wall)"
                                                   : "stopped until resumed";
    for (std::size_t c : fault.cameras) {
      stopped_until_[c] = until;
      NODELET_INFO("camera_rig_sim: %s %s", rig_.cameras[c].name.c_str(), what.c_str());
    }
  }

  bool stopped(std::size_t c, const ros::WallTime& now) {
    if (static_cast<int>(c) == stop_camera_ && frame_ >= static_cast<std::uint64_t>(stop_after_)) return true;
    if (stopped_until_[c].isZero()) return false;
    if (now < stopped_until_[c]) return true;
    stopped_until_[c] = ros::WallTime();
    NODELET_INFO("camera_rig_sim: %s publishing again", rig_.cameras[c].name.c_str());
    return false;
  }

  // A new mediator: the frames after a gap in the subscription start afresh, with no state held from before it.
  void resetMediatorLocked() {
    vrm_sim::world::MediatorOptions options;
    options.policy = vrm_sim::world::WaitPolicy::kNoWait;  // a camera exposes the present: it never waits
    options.slots = std::set<std::string>(expected_slots_.begin(), expected_slots_.end());
    options.log = [this](vrm_sim::world::Severity severity, const std::string& message) {
      // Repetitions are limited by the mediator (log_every_frames).
      if (severity == vrm_sim::world::Severity::kWarning) {
        NODELET_WARN("camera_rig_sim: ground truth: %s", message.c_str());
      } else {
        NODELET_INFO("camera_rig_sim: ground truth: %s", message.c_str());
      }
    };
    mediator_ = std::make_unique<vrm_sim::world::Mediator>(
        std::move(options), [this](vrm_sim::world::InputFrame& frame) { renderLocked(frame); });
    samples_.clear();
    slot_order_.clear();
    last_samples_.clear();
    last_eye_.reset();
  }

  void onEye(const vrm_msgs::EyeState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    mediator_->handle(vrm_sim::toWorld(*msg));
  }

  void onInstrument(const vrm_msgs::InstrumentState::ConstPtr& msg) {
    const vrm_sim::world::InstrumentState state = vrm_sim::toWorld(*msg);
    std::lock_guard<std::mutex> lock(mutex_);
    // The core state has no trocar (shaft axis, insertion depth), which the shaft's image needs: the sample is kept
    // until the mediator puts this state into a frame.
    try {
      samples_[{state.stamp, state.slot}] = fromMsg(*msg);
      if (std::find(slot_order_.begin(), slot_order_.end(), state.slot) == slot_order_.end()) {
        slot_order_.push_back(state.slot);  // the truth's slot order (the script's), as drawn before
      }
    } catch (const std::invalid_argument& e) {
      NODELET_WARN_THROTTLE(1.0, "camera_rig_sim: ground-truth instrument '%s' not drawn: %s", state.slot.c_str(),
                            e.what());
    }
    if (samples_.size() > kMaxKeptSamples) samples_.erase(samples_.begin());
    // Handed over even when it cannot be drawn, so no frame waits for it.
    mediator_->handle(state);
  }

  // The mediator's sink: renders the frame it closed (its inputs in the order they apply: a late one first).
  void renderLocked(const vrm_sim::world::InputFrame& frame) {
    for (const vrm_sim::world::EyeState& eye : frame.eye_inputs) last_eye_ = eye;
    for (const vrm_sim::world::InstrumentState& state : frame.instrument_inputs) {
      auto sample = samples_.find({state.stamp, state.slot});
      if (sample == samples_.end()) continue;  // not drawable (see onInstrument): the slot keeps its last sample
      if (sample->second.tip.allFinite() && sample->second.trocar.allFinite()) {
        last_samples_[state.slot] = sample->second;
      }
      samples_.erase(sample);
    }
    // States the mediator rejected (stale, implausible) never come in a frame.
    samples_.erase(samples_.begin(), samples_.lower_bound({frame.stamp - kKeptSampleAge, std::string()}));
    if (!last_eye_) return;  // nothing to expose before the first eye state

    std_msgs::Header truth_header;
    truth_header.stamp = toRosTime(frame.stamp);
    SurgeonSnapshot snap;
    snap.eye_rotation = last_eye_->rotation;
    snap.rotation_center = last_eye_->rotation_center;
    if (!snap.eye_rotation.coeffs().allFinite() || !snap.rotation_center.allFinite()) {
      NODELET_WARN_THROTTLE(1.0, "camera_rig_sim: non-finite ground-truth eye state ignored");
      return;
    }
    snap.eye_rotation.normalize();
    for (const std::string& slot : slot_order_) {
      auto sample = last_samples_.find(slot);
      if (sample != last_samples_.end()) snap.instruments.push_back(sample->second);
    }
    WorldScene scene = worldSceneFromSnapshot(snap, layout_);
    // Motion blur from the velocity against the previous truth frame.
    if (!previous_stamp_.isZero() && truth_header.stamp > previous_stamp_ &&
        previous_scene_.markers.size() == scene.markers.size()) {
      setVelocities(previous_scene_, scene, (truth_header.stamp - previous_stamp_).toSec(), &scene);
    }
    previous_scene_ = scene;
    previous_stamp_ = truth_header.stamp;

    const ros::Time start = ros::Time::now();  // measurement only (tracking_timing)
    const ros::WallTime wall_now = ros::WallTime::now();
    for (std::size_t c = 0; c < rig_.size(); ++c) {
      if (stopped(c, wall_now)) continue;
      const CameraModel& cam = rig_.cameras[c];
      std_msgs::Header header;
      header.stamp = truth_header.stamp;
      header.seq = static_cast<std::uint32_t>(frame_);
      header.frame_id = cam.name + frame_suffix_;

      std::vector<ProjectedMarker> truth;
      if (camera_pubs_[c].getNumSubscribers() == 0) {
        // Nobody looks at the images (e.g. the tracker reads markers_exact, the FPGA path): rendering three
        // cameras would cost more than a core at 50 Hz for nothing.
        publishExact(c, header, renderer_->project(c, scene));
        continue;
      }
      // Render straight into the message buffer: no copy between renderer and subscribers in the manager.
      sensor_msgs::ImagePtr image = makeBgr8Image(header, cam.width, cam.height);
      cv::Mat view(cam.height, cam.width, CV_8UC3, image->data.data(), image->step);
      renderer_->render(c, scene, frame_, &view, &truth);

      auto info = boost::make_shared<sensor_msgs::CameraInfo>();
      info->header = header;
      toMsg(cam, info.get());
      camera_pubs_[c].publish(image, info);

      publishExact(c, header, truth);
    }
    publishTiming(truth_header.stamp, start, ros::Time::now());
    ++frame_;
  }

  void publishTiming(const ros::Time& stamp, const ros::Time& start, const ros::Time& end) {
    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = stamp;
    timing->frame = frame_;
    vrm_msgs::StageStamp stage;
    stage.stage = "camera";
    stage.start = start;
    stage.end = end;
    timing->stages.push_back(stage);
    vrm_msgs::publishShared(timing_pub_, timing);
  }

  // The exact projected centroids of the visible markers (ground truth for evaluation; the ideal FPGA output).
  void publishExact(std::size_t c, const std_msgs::Header& header, const std::vector<ProjectedMarker>& truth) {
    const CameraModel& cam = rig_.cameras[c];
    auto exact = boost::make_shared<vrm_msgs::MarkerObservations>();
    exact->header = header;
    exact->camera_name = cam.name;
    exact->image_width = static_cast<std::uint32_t>(cam.width);
    exact->image_height = static_cast<std::uint32_t>(cam.height);
    std::vector<Blob> blobs;
    for (const ProjectedMarker& p : truth) {
      if (!p.visible) continue;
      Blob b;
      b.class_id = p.class_id;
      b.u = p.pixel.x();
      b.v = p.pixel.y();
      b.area = M_PI * p.radius_px * p.radius_px;
      b.quality = 1.0;
      blobs.push_back(b);
    }
    toMsg(blobs, exact.get());
    vrm_msgs::publishShared(exact_pubs_[c], exact);
  }

  CameraRig rig_;
  MarkerLayout layout_;
  std::unique_ptr<RigRenderer> renderer_;
  std::vector<std::string> expected_slots_;
  std::string frame_suffix_;
  std::vector<image_transport::CameraPublisher> camera_pubs_;
  std::vector<ros::Publisher> exact_pubs_;
  ros::Publisher timing_pub_;
  ros::Subscriber eye_sub_, instrument_sub_, fault_sub_;
  std::mutex mutex_;  // guards the mediator and everything below (its sink renders)
  std::unique_ptr<vrm_sim::world::Mediator> mediator_;
  // The truth's instrument samples until their state is in a frame, by (stamp, slot).
  std::map<std::pair<vrm_sim::world::Stamp, std::string>, InstrumentSample> samples_;
  static constexpr std::size_t kMaxKeptSamples = 1024;
  static constexpr vrm_sim::world::Stamp kKeptSampleAge = 2'000'000'000;  // ns; beyond the mediator's stale limit
  std::vector<std::string> slot_order_;                   // slots in the order the truth first delivered them
  std::map<std::string, InstrumentSample> last_samples_;  // per slot, the newest drawn
  std::optional<vrm_sim::world::EyeState> last_eye_;
  WorldScene previous_scene_;
  ros::Time previous_stamp_;
  std::uint64_t frame_ = 0;
  int stop_camera_ = -1;
  int stop_after_ = 0;
  std::vector<ros::WallTime> stopped_until_;  // per camera; zero = running (~fault)
  std::mutex connect_mutex_;                  // subscribe / unsubscribe (connectCb)
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::CameraRigSim, nodelet::Nodelet)
