#pragma once
// Shared by the graph tests that drive scenario_manager with a scripted input sequence; waiting itself is
// vrm_sim/testing/graph_test.h.

#include <gtest/gtest.h>
#include <ros/ros.h>

#include <boost/make_shared.hpp>
#include <functional>
#include <map>
#include <optional>
#include <vector>

#include "vrm_msgs/InstrumentState.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/testing/graph_test.h"
#include "vrm_sim/world/world.h"

namespace vrm_sim {

// Publishes `inputs` tick by tick: all states of one stamp, then it waits until the frame of the previous stamp has
// closed (`last_frame` returns the stamp of the newest simulation_state), so no subscriber queue overflows and
// nothing is dropped. `after_tick(stamp, index)` runs after each tick and returns false to stop early; played to the
// end, it also waits for the last tick's frame. `before_tick(stamp)`, when given, runs before a tick's states are
// published (e.g. to publish the pedal of that stamp).
inline ::testing::AssertionResult playTicks(
    const ros::Publisher& instruments, const std::vector<world::InstrumentState>& inputs,
    const std::function<world::Stamp()>& last_frame,
    const std::function<bool(world::Stamp, std::size_t)>& after_tick = [](world::Stamp, std::size_t) { return true; },
    const std::function<void(world::Stamp)>& before_tick = {}) {
  std::map<world::Stamp, std::vector<world::InstrumentState>> ticks;
  for (const auto& input : inputs) ticks[input.stamp].push_back(input);
  std::optional<world::Stamp> previous;
  std::size_t index = 0;
  for (const auto& [stamp, tick] : ticks) {
    if (before_tick) before_tick(stamp);
    for (const auto& input : tick) instruments.publish(boost::make_shared<vrm_msgs::InstrumentState>(toMsg(input)));
    if (previous && !testing::waitFor([&] { return last_frame() >= *previous; }, 10.0)) {
      return ::testing::AssertionFailure() << "no frame for stamp " << *previous;
    }
    previous = stamp;
    if (!after_tick(stamp, ++index)) return ::testing::AssertionSuccess();
  }
  if (previous && !testing::waitFor([&] { return last_frame() == *previous; }, 10.0)) {
    return ::testing::AssertionFailure() << "the last tick's frame did not close";
  }
  return ::testing::AssertionSuccess();
}

}  // namespace vrm_sim
