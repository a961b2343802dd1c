// One-handed session (one_hand.test): the rig twin renders a tick as soon as the eye state and the instruments the
// truth publishes have arrived. With a script that plays one hand of a two-slot rig it used to wait for the absent
// slot until the next eye state closed the tick: every camera frame started one input period (20 ms at 50 Hz) after
// its stamp, and so did everything downstream. Conditions are awaited with timeouts (no fixed sleeps).
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <vrm_msgs/StageTiming.h>

#include <algorithm>
#include <mutex>
#include <vector>

#include "vrm_sim/testing/graph_test.h"
#include "vrm_sim/testing/sanitizer.h"

namespace {

class CameraStarts : public vrm_sim::testing::AwaitedState {
 public:
  void onTiming(const vrm_msgs::StageTiming::ConstPtr& timing) {
    for (const auto& stage : timing->stages) {
      if (stage.stage != "camera") continue;
      const double delay_ms = (stage.start - timing->header.stamp).toSec() * 1e3;
      update([&] { delays_ms.push_back(delay_ms); });
    }
  }
  std::vector<double> delays_ms;  // camera stage start - input stamp
};

TEST(OneHand, TheRigTwinRendersEachTickWithoutWaitingForTheAbsentHand) {
  ros::NodeHandle nh;
  CameraStarts starts;
  ros::Subscriber sub = nh.subscribe("tracking_timing", 200, &CameraStarts::onTiming, &starts);
  // Two seconds of ticks after the slot has been absent long enough to be dropped (5 ticks).
  ASSERT_TRUE(starts.waitFor([&] { return starts.delays_ms.size() >= 120; }, 30.0)) << "no camera frames";
  std::lock_guard<std::mutex> lock(starts.mutex_);
  std::vector<double> steady(starts.delays_ms.begin() + 20, starts.delays_ms.end());
  std::nth_element(steady.begin(), steady.begin() + steady.size() / 2, steady.end());
  const double median = steady[steady.size() / 2];
  if (vrm_sim::testing::kUnderSanitizer) {
    // The rig twin's instrumented renderer takes longer than a tick there, so its frames queue: the bound would
    // measure the sanitizer (77 ms measured), not a wait for the absent hand. The frames above still had to come.
    GTEST_SKIP() << "wall-clock bound not checked under ASan (median start " << median << " ms after the stamp)";
  }
  // 20 ms (one input period) when the tick waits for the absent hand; a loaded CI machine adds a few ms.
  EXPECT_LT(median, 12.0) << "the rig twin starts its frames " << median
                          << " ms after their stamp: it waits for an instrument the script does not play";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_one_hand");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return result;
}
