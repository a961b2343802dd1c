#pragma once
// Waiting in the graph tests (the rostest gtests of vrm_sim, vrm_tracking and vrm_render): every wait is a
// condition bounded by a wall-clock timeout that also ends when ROS shuts down, never a fixed sleep that an
// assertion relies on. Header-only (roscpp).
//
// Note: the namespace is vrm_sim::testing; code inside namespace vrm_sim names gtest's as ::testing.

#include <ros/ros.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>

namespace vrm_sim::testing {

// Polls `condition` every `poll_seconds` until it holds, `seconds` of wall time have passed or ROS shuts down, and
// returns its last value. For state that nobody signals: subscriber counts, files, the master's system state (a
// query to the master deserves a longer `poll_seconds`).
template <typename Condition>
bool waitFor(Condition&& condition, double seconds, double poll_seconds = 0.002) {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < deadline) {
    if (condition()) return true;
    ros::WallDuration(poll_seconds).sleep();
  }
  return condition();
}

// Until `publisher` has a subscriber (a nodelet under test has connected to the test's input).
inline bool waitForSubscribers(const ros::Publisher& publisher, double seconds) {
  return waitFor([&publisher] { return publisher.getNumSubscribers() > 0; }, seconds);
}

// Until `subscriber` has a publisher (a nodelet under test advertises the test's output).
inline bool waitForPublishers(const ros::Subscriber& subscriber, double seconds) {
  return waitFor([&subscriber] { return subscriber.getNumPublishers() > 0; }, seconds);
}

// Base of a test's listener whose callbacks collect messages into members guarded by `mutex_`: a callback changes
// them through update() (or under the lock, followed by changed()), and waitFor() evaluates its predicate under the
// lock each time they changed, so a test waits for "enough messages" without polling. The test reads the members
// under `mutex_`, too.
class AwaitedState {
 public:
  // Waits until `predicate` (called with `mutex_` held) holds, `seconds` of wall time have passed or ROS shuts
  // down, and returns its last value. The predicate is also evaluated every 50 ms, so it may look at something no
  // callback changes (a publisher's subscriber count).
  template <typename Predicate>
  bool waitFor(Predicate&& predicate, double seconds) {
    using Clock = std::chrono::steady_clock;
    const Clock::time_point deadline =
        Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
    std::unique_lock<std::mutex> lock(mutex_);
    while (!predicate()) {
      const Clock::time_point now = Clock::now();
      if (!ros::ok() || now >= deadline) return predicate();
      changed_.wait_until(lock, std::min(deadline, now + kRecheck));
    }
    return true;
  }

  std::mutex mutex_;

 protected:
  // Runs `change` under `mutex_`, then wakes the waiters.
  template <typename Change>
  void update(Change&& change) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      change();
    }
    changed();
  }
  // Wakes the waiters (call after releasing `mutex_`).
  void changed() { changed_.notify_all(); }

 private:
  static constexpr std::chrono::milliseconds kRecheck{50};
  std::condition_variable changed_;
};

}  // namespace vrm_sim::testing
