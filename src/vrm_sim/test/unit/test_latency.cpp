// Latency statistics and the thesis' pattern predictions (world/latency.h) against hand-computed values.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "vrm_sim/world/latency.h"

namespace vrm_sim {
namespace world {
namespace {

constexpr Nanoseconds kMs = 1'000'000;

const StageSample* find(const std::vector<StageSample>& samples, const std::string& stage) {
  for (const StageSample& sample : samples) {
    if (sample.stage == stage) return &sample;
  }
  return nullptr;
}

TEST(LatencySummary, NearestRankPercentilesOfOneToHundred) {
  std::vector<double> values;
  for (int i = 100; i >= 1; --i) values.push_back(i);  // unsorted on purpose
  const LatencySummary summary = summarizeLatencies(values);
  EXPECT_EQ(summary.count, 100u);
  EXPECT_DOUBLE_EQ(summary.p50, 50.0);
  EXPECT_DOUBLE_EQ(summary.p95, 95.0);
  EXPECT_DOUBLE_EQ(summary.p99, 99.0);
  EXPECT_DOUBLE_EQ(summary.max, 100.0);
  EXPECT_DOUBLE_EQ(summary.mean, 50.5);
}

TEST(LatencySummary, SmallAndEmptySamples) {
  EXPECT_EQ(summarizeLatencies({}).count, 0u);
  EXPECT_DOUBLE_EQ(summarizeLatencies({}).p99, 0.0);
  const LatencySummary one = summarizeLatencies({7.0});
  EXPECT_DOUBLE_EQ(one.p50, 7.0);
  EXPECT_DOUBLE_EQ(one.p99, 7.0);
  // Three values: p50 is the 2nd (ceil(1.5)), p95 and p99 the 3rd.
  const LatencySummary three = summarizeLatencies({3.0, 1.0, 2.0});
  EXPECT_DOUBLE_EQ(three.p50, 2.0);
  EXPECT_DOUBLE_EQ(three.p95, 3.0);
  EXPECT_DOUBLE_EQ(three.p99, 3.0);
}

TEST(SlidingWindow, KeepsOnlyTheLastWindowAndCountsTheRate) {
  SlidingWindow window(1000 * kMs, 1000);
  // 50 Hz for 3 s, latency = 10 ms in the first two seconds and 30 ms in the last.
  for (int i = 0; i < 150; ++i) window.add(i * 20 * kMs, i < 100 ? 10.0 : 30.0);
  const LatencySummary summary = window.summary();
  // Samples at 1980 ms .. 2980 ms: 51 of them, one of the 10 ms ones.
  EXPECT_EQ(summary.count, 51u);
  EXPECT_DOUBLE_EQ(summary.p50, 30.0);
  EXPECT_NEAR(window.rate(2980 * kMs), 51.0, 1e-9);
  // No new samples for two seconds: the window empties.
  window.expire(5000 * kMs);
  EXPECT_EQ(window.size(), 0u);
  EXPECT_DOUBLE_EQ(window.rate(5000 * kMs), 0.0);
}

TEST(SlidingWindow, CapsTheSampleCount) {
  SlidingWindow window(100'000 * kMs, 10);
  for (int i = 0; i < 25; ++i) window.add(i * kMs, i);
  EXPECT_EQ(window.size(), 10u);
  EXPECT_DOUBLE_EQ(window.summary().max, 24.0);
  EXPECT_DOUBLE_EQ(window.summary().p50, 19.0);  // 15..24
}

TEST(StageChain, SimulationFrameGivesCollisionAndSimulationStages) {
  StageChain chain;
  const Nanoseconds stamp = 1000 * kMs;
  // The world's stages of one frame: collision of two objects, tissue step, bleeding, scenario.
  const std::vector<StageSample> samples = chain.add(stamp, {{"collision_retina", stamp + 3 * kMs, stamp + 4 * kMs},
                                                             {"collision_membrane", stamp + 4 * kMs, stamp + 6 * kMs},
                                                             {"tissue_membrane", stamp + 6 * kMs, stamp + 9 * kMs},
                                                             {"bleeding_retina", stamp + 9 * kMs, stamp + 10 * kMs},
                                                             {"scenario", stamp + 10 * kMs, stamp + 11 * kMs}});
  const StageSample* collision = find(samples, kCollisionStage);
  ASSERT_NE(collision, nullptr);
  EXPECT_NEAR(*collision->time_ms, 3.0, 1e-9);  // 1 + 2 ms
  EXPECT_NEAR(collision->latency_ms, 6.0, 1e-9);
  const StageSample* simulation = find(samples, kSimulationStage);
  ASSERT_NE(simulation, nullptr);
  EXPECT_NEAR(*simulation->time_ms, 8.0, 1e-9);  // 3 → 11 ms
  EXPECT_NEAR(simulation->latency_ms, 11.0, 1e-9);
  EXPECT_EQ(find(samples, kEndToEndStage), nullptr);
}

TEST(StageChain, TrackingSumsCameraDetectionAndReconstructionOfOneStamp) {
  StageChain chain;
  const Nanoseconds stamp = 2000 * kMs, other = 2020 * kMs;
  EXPECT_NE(find(chain.add(stamp, {{"camera", stamp + 1 * kMs, stamp + 10 * kMs}}), kCameraStage), nullptr);
  chain.add(other, {{"camera", other + 1 * kMs, other + 2 * kMs}});  // another frame's camera must not count
  chain.add(stamp, {{"detection_camera_0", stamp + 10 * kMs, stamp + 11 * kMs}});
  chain.add(stamp, {{"detection_camera_1", stamp + 11 * kMs, stamp + 12 * kMs}});
  chain.add(stamp, {{"detection_camera_2", stamp + 12 * kMs, stamp + 13 * kMs}});
  const std::vector<StageSample> samples = chain.add(stamp, {{"reconstruction", stamp + 14 * kMs, stamp + 15 * kMs}});
  const StageSample* tracking = find(samples, kTrackingStage);
  ASSERT_NE(tracking, nullptr);
  EXPECT_NEAR(*tracking->time_ms, 9.0 + 3.0 + 1.0, 1e-9);
  EXPECT_NEAR(tracking->latency_ms, 15.0, 1e-9);
  // A reconstruction without camera spans (markers from real cameras' FPGA): tracking = reconstruction alone.
  const std::vector<StageSample> alone =
      chain.add(3000 * kMs, {{"reconstruction", 3000 * kMs + 1 * kMs, 3000 * kMs + 3 * kMs}});
  EXPECT_NEAR(*find(alone, kTrackingStage)->time_ms, 2.0, 1e-9);
}

TEST(StageChain, RenderTimingGivesEndToEndFromBothStamps) {
  StageChain chain;
  const Nanoseconds stamp = 5000 * kMs, shown_simulation = stamp - 20 * kMs;
  const std::vector<StageSample> samples = chain.add(stamp, {{"render_scene", stamp + 2 * kMs, stamp + 20 * kMs},
                                                             {"render", stamp + 1 * kMs, stamp + 26 * kMs},
                                                             {"image_published", stamp + 26 * kMs, stamp + 27 * kMs},
                                                             {"simulation_input", shown_simulation, shown_simulation}});
  EXPECT_NEAR(*find(samples, kRenderStage)->time_ms, 25.0, 1e-9);
  EXPECT_NEAR(find(samples, kRenderStage)->latency_ms, 26.0, 1e-9);
  EXPECT_NEAR(*find(samples, kImagePublishedStage)->time_ms, 1.0, 1e-9);
  const StageSample* end_to_end = find(samples, kEndToEndStage);
  ASSERT_NE(end_to_end, nullptr);
  EXPECT_FALSE(end_to_end->time_ms.has_value());
  EXPECT_NEAR(end_to_end->latency_ms, 27.0, 1e-9);
  EXPECT_NEAR(find(samples, kEndToEndWorldStage)->latency_ms, 47.0, 1e-9);
}

TEST(DropCounter, CountsOfferedFramesThatWereNeverTaken) {
  DropCounter counter(100 * kMs);
  for (int i = 0; i < 10; ++i) {
    counter.offer(i * 20 * kMs);
    if (i % 3 == 0) counter.take(i * 20 * kMs);  // frames 0, 3, 6, 9 used; 1, 2, 4, 5, 7, 8 skipped
  }
  // Offers older than 100 ms before the newest (180 ms): 0..60 ms are settled; of those, 1 and 2 were dropped.
  EXPECT_EQ(counter.offered(), 10u);
  EXPECT_EQ(counter.dropped(), 2u);
  for (int i = 10; i < 20; ++i) counter.offer(i * 20 * kMs);
  EXPECT_EQ(counter.dropped(), 10u);  // 1 2 4 5 7 8 and 10..13 (14..19 are still open)
}

TEST(DropCounter, ATakeBeforeItsOfferIsNotADrop) {
  DropCounter counter(100 * kMs);
  counter.take(20 * kMs);
  counter.offer(20 * kMs);
  for (int i = 2; i < 20; ++i) {
    counter.offer(i * 20 * kMs);
    counter.take(i * 20 * kMs);
  }
  EXPECT_EQ(counter.dropped(), 0u);
  EXPECT_EQ(counter.offered(), 19u);
}

TEST(LatencyThreshold, ClassifiesByTheChosenStatistic) {
  LatencySummary latency;
  latency.count = 100;
  latency.p50 = 30.0;
  latency.p99 = 60.0;
  latency.max = 120.0;
  const LatencySummary time;
  LatencyThreshold threshold;
  threshold.warn_ms = 57.0;
  threshold.error_ms = 90.0;
  std::string why;
  EXPECT_EQ(classify(latency, time, 50.0, threshold, &why), LatencyLevel::kWarn);
  EXPECT_EQ(why, "p99 latency 60.0 ms > 57 ms");
  threshold.statistic = "max";
  EXPECT_EQ(classify(latency, time, 50.0, threshold, &why), LatencyLevel::kError);
  threshold.statistic = "p50";
  EXPECT_EQ(classify(latency, time, 50.0, threshold, &why), LatencyLevel::kOk);
  EXPECT_TRUE(why.empty());
  threshold.min_fps = 25.0;
  EXPECT_EQ(classify(latency, time, 15.0, threshold, &why), LatencyLevel::kWarn);
  EXPECT_EQ(why, "15.0 fps < 25 fps");
  // No samples: nothing to judge.
  EXPECT_EQ(classify(LatencySummary{}, time, 0.0, threshold, &why), LatencyLevel::kOk);
  threshold.statistic = "p42";
  EXPECT_THROW(classify(latency, time, 50.0, threshold, &why), std::invalid_argument);
}

TEST(LatencyThreshold, OnComputeTime) {
  LatencySummary latency, time;
  latency.count = time.count = 10;
  latency.p99 = 40.0;
  time.p99 = 2.5;
  LatencyThreshold budget;
  budget.of_time = true;
  budget.warn_ms = 2.0;  // the tissue's time budget (scene time_budget_ms)
  std::string why;
  EXPECT_EQ(classify(latency, time, 50.0, budget, &why), LatencyLevel::kWarn);
  EXPECT_EQ(why, "p99 time 2.5 ms > 2 ms");
}

// Fig. 2.6 with T_S = 20, T_B = 10, T_R = 30 ms.
TEST(ThesisPatterns, Equations) {
  EXPECT_DOUBLE_EQ(syncLatencyWorst(50.0), 0.02);            // eq. 2.1
  EXPECT_DOUBLE_EQ(syncLatencyMean(50.0), 0.01);             // eq. 2.2
  EXPECT_DOUBLE_EQ(sequentialLatency(20, 10, 30), 60.0);     // eq. 2.3
  EXPECT_DOUBLE_EQ(parallelAsyncLatency(20, 10, 30), 75.0);  // eq. 2.4: + (20 + 10) / 2
  EXPECT_DOUBLE_EQ(useProbability(10, 30), 1.0 / 3.0);       // eq. 2.5: a faster producer's results are lost
  EXPECT_DOUBLE_EQ(useProbability(30, 10), 1.0);
  EXPECT_DOUBLE_EQ(pipelinedLatency({30, 30}), 60.0);      // eq. 2.6: 2 T_R when T_R dominates
  EXPECT_DOUBLE_EQ(pipelinedLatency({20, 10, 30}), 90.0);  // eq. 2.7: n max T_i
  EXPECT_DOUBLE_EQ(pipelinedLatency({}), 0.0);
}

}  // namespace
}  // namespace world
}  // namespace vrm_sim
