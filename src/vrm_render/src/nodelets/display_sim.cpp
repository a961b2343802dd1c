// The station's display, as a simulated twin (every device of the station has one). A real station always shows the
// stereo microscope view on its display, so its renderer renders every frame; a headless session without this twin
// would render only its snapshots (the renderer is lazy: it renders while its images are watched). The twin watches
// as the display would, in the manager: it receives the renderer's own image pointers (zero copy; it neither copies
// nor keeps an image), pairs the eyes by header.stamp, and per stereo frame shown publishes when it was shown. Its
// cost is a map lookup per image.
//
// Subscribes (node handle namespace): stereo/left/image_raw, stereo/right/image_raw (image_transport, raw). A
//   renderer that publishes only the left eye (~stereo false) is shown eye by eye.
// Publishes: display_timing (vrm_msgs/StageTiming per stereo frame shown: header.stamp = the images' stamp = the input
//   stamp of the frame; one stage "displayed": start = the first eye arrived, end = both eyes had arrived, on the
//   graph's clock like render_timing's stages — wall time in a live session).
// Logs at shutdown, and every ~report_period s (default 0: only at shutdown), one line: frames shown, their rate and
//   input stamp -> shown p50 / p99, e.g. "display: 412 stereo frames in 20.0 s = 20.6 fps; input stamp -> shown p50
//   48 ms, p99 81 ms". The percentiles cover the last ~kLatencySamples frames.

#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <vrm_msgs/StageTiming.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <string>

#include "vrm_sim/world/latency.h"

namespace vrm_render {

namespace {

// Frames whose latency the percentiles cover (about an hour at 20 fps; the memory stays bounded).
constexpr std::size_t kLatencySamples = 1 << 16;
// Stamps waiting for their second eye: an eye the transport dropped must not hold frames forever.
constexpr std::size_t kMaxPending = 8;

enum class Eye { kLeft, kRight };

}  // namespace

class DisplaySim : public nodelet::Nodelet {
 public:
  ~DisplaySim() override {
    report_timer_.stop();
    left_sub_.shutdown();
    right_sub_.shutdown();
    report();
  }

  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    const double report_period = pnh.param("report_period", 0.0);
    timing_pub_ = nh.advertise<vrm_msgs::StageTiming>("display_timing", 10);
    image_transport::ImageTransport it(nh);
    const image_transport::TransportHints raw("raw", ros::TransportHints(), pnh);
    left_sub_ = it.subscribe(
        "stereo/left/image_raw", 2,
        [this](const sensor_msgs::ImageConstPtr& image) { onImage(Eye::kLeft, image->header.stamp); }, {}, raw);
    right_sub_ = it.subscribe(
        "stereo/right/image_raw", 2,
        [this](const sensor_msgs::ImageConstPtr& image) { onImage(Eye::kRight, image->header.stamp); }, {}, raw);
    if (report_period > 0.0) {
      report_timer_ =
          nh.createWallTimer(ros::WallDuration(report_period), [this](const ros::WallTimerEvent&) { report(); });
    }
    const std::string reports =
        report_period > 0.0 ? "every " + std::to_string(report_period) + " s and at shutdown" : "at shutdown";
    NODELET_INFO("display_sim: showing %s and %s; frame rate and latency logged %s", left_sub_.getTopic().c_str(),
                 right_sub_.getTopic().c_str(), reports.c_str());
  }

 private:
  struct Pending {
    ros::Time first_arrival;
    bool left = false, right = false;
  };

  void onImage(Eye eye, const ros::Time& stamp) {
    const ros::Time arrived = ros::Time::now();  // the graph's clock, as render_timing's stages
    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (eye == Eye::kRight) right_seen_ = true;
      if (stamp <= last_shown_stamp_) return;  // the other eye of a frame shown alone, or a late frame
      Pending& pending = pending_[stamp];
      if (pending.first_arrival.isZero()) pending.first_arrival = arrived;
      (eye == Eye::kLeft ? pending.left : pending.right) = true;
      const bool mono = !right_seen_ && right_sub_.getNumPublishers() == 0;
      if (!(pending.left && (pending.right || mono))) {
        while (pending_.size() > kMaxPending) {
          pending_.erase(pending_.begin());
          ++unpaired_;
        }
        return;
      }
      vrm_msgs::StageStamp shown;
      shown.stage = "displayed";
      shown.start = pending.first_arrival;
      shown.end = arrived;
      // Older stamps still waiting lost an eye: a display never shows them.
      const auto next = pending_.upper_bound(stamp);
      for (auto it = pending_.begin(); it != next; ++it) {
        if (it->first != stamp) ++unpaired_;
      }
      pending_.erase(pending_.begin(), next);
      last_shown_stamp_ = stamp;
      if (frames_ == 0) first_shown_ = arrived;
      last_shown_ = arrived;
      ++frames_;
      latency_.add(static_cast<vrm_sim::world::Nanoseconds>(arrived.toNSec()), 1e-6 * (arrived - stamp).toNSec());
      timing->header.stamp = stamp;
      timing->frame = frames_;
      timing->stages.push_back(shown);
    }
    vrm_msgs::publishShared(timing_pub_, timing);
  }

  void report() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (frames_ == 0) {
      NODELET_INFO("display: no stereo frames shown");
      return;
    }
    const double seconds = (last_shown_ - first_shown_).toSec();
    const double fps = frames_ > 1 && seconds > 0.0 ? static_cast<double>(frames_ - 1) / seconds : 0.0;
    const vrm_sim::world::LatencySummary latency = latency_.summary();
    char unpaired[64] = "";
    if (unpaired_ > 0) {
      std::snprintf(unpaired, sizeof(unpaired), "; %llu frames lost an eye",
                    static_cast<unsigned long long>(unpaired_));
    }
    NODELET_INFO("display: %llu stereo frames in %.1f s = %.1f fps; input stamp -> shown p50 %.0f ms, p99 %.0f ms%s",
                 static_cast<unsigned long long>(frames_), seconds, fps, latency.p50, latency.p99, unpaired);
  }

  std::mutex mutex_;
  std::map<ros::Time, Pending> pending_;  // stamps with one eye arrived
  bool right_seen_ = false;
  ros::Time last_shown_stamp_;
  ros::Time first_shown_, last_shown_;  // when the first and the newest stereo frame were shown
  std::uint64_t frames_ = 0, unpaired_ = 0;
  vrm_sim::world::SlidingWindow latency_{std::numeric_limits<vrm_sim::world::Nanoseconds>::max() / 2, kLatencySamples};

  image_transport::Subscriber left_sub_, right_sub_;
  ros::Publisher timing_pub_;
  ros::WallTimer report_timer_;
};

}  // namespace vrm_render

PLUGINLIB_EXPORT_CLASS(vrm_render::DisplaySim, nodelet::Nodelet)
