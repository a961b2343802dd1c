#pragma once
// A device twin loaded again into a restarted nodelet manager (issue 39: crash = pause; nodelet_keeper passes
// --reloaded) must not start its script over: scenario_manager resumes the session where the crashed process left it.
// The gate withholds the twin's output until the resume is announced (vrm_msgs/SessionResume, latched on
// simulation_resume) and hands the twin its new script start, so that the script time at the resume stamp is the
// session's script time at the pause (a trainee's hands go on from where the picture froze). Ticks stamped before the
// resume stamp stay withheld. A twin loaded for the first time is never withheld. Without an announcement within
// `timeout` s of wall time (no simulation in the graph) the twin plays on from its own clock, with a warning.

#include <ros/ros.h>
#include <vrm_msgs/SessionResume.h>

#include <algorithm>
#include <atomic>
#include <functional>
#include <string>
#include <vector>

namespace vrm_tracking {

class ResumeGate {
 public:
  // start: the twin's new script start (script time = stamp - start); session_clock: whether it is the session's
  // clock (a START's, moved by the pause) rather than the twin's own first tick. Called once, on a subscriber thread.
  using OnResume = std::function<void(const ros::Time& start, bool session_clock)>;

  void init(ros::NodeHandle& nh, const std::vector<std::string>& argv, const std::string& who, OnResume on_resume,
            double timeout = 60.0) {
    if (std::find(argv.begin(), argv.end(), "--reloaded") == argv.end()) return;
    who_ = who;
    on_resume_ = std::move(on_resume);
    timeout_ = timeout;
    waiting_since_ = ros::WallTime::now();
    waiting_ = true;
    subscriber_ = nh.subscribe("simulation_resume", 1, &ResumeGate::onResume, this);
    ROS_WARN("%s: loaded again after a crash of its manager; holding its inputs until the simulation resumes",
             who_.c_str());
  }

  // Whether the tick stamped `stamp` is withheld.
  bool withholds(const ros::Time& stamp) {
    if (waiting_) {
      if ((ros::WallTime::now() - waiting_since_).toSec() < timeout_) return true;
      waiting_ = false;
      ROS_WARN("%s: no simulation_resume within %.0f s; playing on from its own clock", who_.c_str(), timeout_);
    }
    return stamp.toNSec() < resume_ns_.load();
  }

 private:
  void onResume(const vrm_msgs::SessionResume::ConstPtr& message) {
    if (!waiting_) return;
    const ros::Time& resume_at = message->header.stamp;
    const bool session_clock = message->resumed && !message->session_start.isZero();
    // The script time at the pause, from the resume stamp on.
    const ros::Time start = session_clock ? resume_at - (message->paused_at - message->session_start) : resume_at;
    on_resume_(start, session_clock);
    resume_ns_ = resume_at.toNSec();
    waiting_ = false;
    if (message->resumed) {
      ROS_WARN("%s: the session resumes at %.3f s; script time %.3f s from there", who_.c_str(), resume_at.toSec(),
               session_clock ? (message->paused_at - message->session_start).toSec() : 0.0);
    } else {
      ROS_WARN("%s: nothing to resume (%s); the script starts over at %.3f s", who_.c_str(), message->reason.c_str(),
               resume_at.toSec());
    }
  }

  std::string who_;
  OnResume on_resume_;
  double timeout_ = 60.0;
  ros::WallTime waiting_since_;
  std::atomic<bool> waiting_{false};
  std::atomic<std::uint64_t> resume_ns_{0};
  ros::Subscriber subscriber_;
};

}  // namespace vrm_tracking
