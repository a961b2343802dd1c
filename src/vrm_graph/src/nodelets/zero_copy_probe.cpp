// Diagnostics nodelet: load it into a nodelet manager to see whether the graph's messages really travel as shared
// pointers. For each input topic it counts the messages received and how many of them are the very objects a
// publisher handed to vrm_msgs::publishShared() in this process (PublishLedger). A copy anywhere on the way
// (publish(*msg), or a subscriber in another process) shows up as received > zero_copy.
// The ledger records only while enabled (off in production); the probe switches it on when it loads. A publisher
// that read the flag just before that may still be publishing an unrecorded message, so the probe subscribes only
// after ~settle_time (default 0.2 s): every message it receives was then published with the ledger on.
// Latched topics are left out on purpose: roscpp hands a late subscriber in the same process a deserialised copy
// of the latched message (measured by this probe), which is fine for one-off scene data but not for streams.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>

#include <algorithm>
#include <atomic>
#include <boost/make_shared.hpp>
#include <map>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <string>

#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/MicroscopeSettings.h"
#include "vrm_msgs/PedalState.h"
#include "vrm_msgs/publish.h"

namespace vrm_graph {

class ZeroCopyProbe : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    vrm_msgs::PublishLedger::instance().setEnabled(true);
    const double settle = std::max(0.0, getPrivateNodeHandle().param("settle_time", 0.2));
    subscribe_timer_ = nh.createWallTimer(
        ros::WallDuration(std::max(settle, 1e-3)),
        [this](const ros::WallTimerEvent&) {
          ros::NodeHandle& nh = getNodeHandle();
          subscribeTo<vrm_msgs::EyeState>(nh, "eye_state");
          subscribeTo<vrm_msgs::InstrumentState>(nh, "instrument_state");
          subscribeTo<vrm_msgs::PedalState>(nh, "pedals");
          subscribeTo<vrm_msgs::MicroscopeSettings>(nh, "microscope");
        },
        true);
    report_publisher_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("diagnostics", 10);
    const double period = getPrivateNodeHandle().param("report_period", 0.5);
    report_timer_ = nh.createWallTimer(ros::WallDuration(period), [this](const ros::WallTimerEvent&) { report(); });
  }

 private:
  struct Counts {
    std::uint64_t received = 0;
    std::uint64_t zero_copy = 0;
  };

  template <class M>
  void subscribeTo(ros::NodeHandle& nh, const std::string& topic) {
    const std::string resolved = nh.resolveName(topic);
    subscribers_.push_back(nh.subscribe<M>(topic, 100, [this, resolved](const boost::shared_ptr<const M>& message) {
      const bool same_object = vrm_msgs::PublishLedger::instance().contains(message.get());
      std::lock_guard<std::mutex> lock(mutex_);
      Counts& counts = counts_[resolved];
      ++counts.received;
      counts.zero_copy += same_object ? 1 : 0;
    }));
  }

  void report() {
    auto array = boost::make_shared<diagnostic_msgs::DiagnosticArray>();
    array->header.stamp = ros::Time::now();  // diagnostics only, not part of the simulation pipeline
    diagnostic_msgs::DiagnosticStatus status;
    status.name = getName();
    status.hardware_id = "nodelet_manager";
    bool all_zero_copy = true;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const auto& [topic, counts] : counts_) {
        diagnostic_msgs::KeyValue value;
        value.key = topic;
        value.value = std::to_string(counts.received) + " " + std::to_string(counts.zero_copy);
        status.values.push_back(value);
        all_zero_copy = all_zero_copy && counts.received == counts.zero_copy;
      }
    }
    status.level = all_zero_copy ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::WARN;
    status.message = all_zero_copy ? "every message received by pointer" : "some messages arrived as copies";
    array->status.push_back(status);
    vrm_msgs::publishShared(report_publisher_, array);
  }

  std::vector<ros::Subscriber> subscribers_;  // filled once, by subscribe_timer_
  ros::WallTimer subscribe_timer_;
  ros::Publisher report_publisher_;
  ros::WallTimer report_timer_;
  std::mutex mutex_;
  std::map<std::string, Counts> counts_;
};

}  // namespace vrm_graph

PLUGINLIB_EXPORT_CLASS(vrm_graph::ZeroCopyProbe, nodelet::Nodelet)
