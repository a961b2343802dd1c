// The input monitor (issue 20): what the simulator tells a user who started it without devices.
#include <gtest/gtest.h>

#include <cmath>

#include "vrm_sim/world/input_monitor.h"

namespace vrm_sim {
namespace world {
namespace {

std::vector<ExpectedInput> inputs() {
  return {{"eye_state", 50.0, "the tracker (tracking:=true)"},
          {"pedals", 100.0, "the pedal driver"},
          {"scenario_command", 0.0, "the console"}};
}

TEST(InputMonitor, NoPublisherIsReportedAtOnceWithTheHint) {
  InputMonitor monitor(inputs(), {}, 0.0);
  const auto reports = monitor.evaluate(0.5, {0, 0, 0});
  ASSERT_EQ(reports.size(), 3u);
  for (const auto& report : reports) EXPECT_EQ(report.health, InputHealth::kNoPublisher) << report.topic;
  EXPECT_EQ(reports[0].message, "waiting for eye_state: no publisher (expected from the tracker (tracking:=true))");
}

TEST(InputMonitor, HealthyInputsAreOk) {
  InputMonitor monitor(inputs(), {}, 0.0);
  for (int k = 0; k < 300; ++k) {
    monitor.onMessage(0, k * 0.02);
    monitor.onMessage(1, k * 0.01);
  }
  const auto reports = monitor.evaluate(3.0, {1, 1, 1});
  EXPECT_EQ(reports[0].health, InputHealth::kOk);
  EXPECT_NEAR(reports[0].rate_hz, 50.0, 1.0);
  EXPECT_EQ(reports[1].health, InputHealth::kOk);
  EXPECT_EQ(reports[2].health, InputHealth::kOk) << "an on-change input needs only its publisher";
}

TEST(InputMonitor, APublisherThatNeverSendsIsSilentAfterTheGrace) {
  InputMonitor monitor(inputs(), {}, 10.0);
  EXPECT_EQ(monitor.evaluate(11.0, {1, 1, 1})[0].health, InputHealth::kStarting);
  const auto reports = monitor.evaluate(13.0, {1, 1, 1});
  EXPECT_EQ(reports[0].health, InputHealth::kSilent);
  EXPECT_NE(reports[0].message.find("no message since the start 3 s ago"), std::string::npos) << reports[0].message;
}

TEST(InputMonitor, ADeviceThatStopsBecomesSilent) {
  InputMonitor monitor(inputs(), {}, 0.0);
  for (int k = 0; k < 150; ++k) monitor.onMessage(0, k * 0.02);  // until 2.98 s
  EXPECT_EQ(monitor.evaluate(3.5, {1, 1, 1})[0].health, InputHealth::kOk);
  const auto report = monitor.evaluate(4.5, {1, 1, 1})[0];
  EXPECT_EQ(report.health, InputHealth::kSilent);
  EXPECT_NEAR(report.seconds_since_last, 1.52, 1e-9);
}

TEST(InputMonitor, ARateBelowHalfTheExpectedIsSlow) {
  InputMonitor monitor(inputs(), {}, 0.0);
  for (int k = 0; k < 100; ++k) monitor.onMessage(0, k * 0.05);  // 20 Hz of an expected 50
  const auto report = monitor.evaluate(5.0, {1, 1, 1})[0];
  EXPECT_EQ(report.health, InputHealth::kSlow);
  EXPECT_NEAR(report.rate_hz, 20.0, 1.0);
  EXPECT_NE(report.message.find("below the expected 50 Hz"), std::string::npos) << report.message;
}

TEST(InputMonitor, BadConfigurationIsRefused) {
  EXPECT_THROW(InputMonitor({{"", 50.0, ""}}, {}, 0.0), std::invalid_argument);
  EXPECT_THROW(InputMonitor({{"x", -1.0, ""}}, {}, 0.0), std::invalid_argument);
  EXPECT_THROW(InputMonitor({{"x", std::nan(""), ""}}, {}, 0.0), std::invalid_argument);
  InputMonitor monitor(inputs(), {}, 0.0);
  EXPECT_THROW(monitor.evaluate(1.0, {1}), std::invalid_argument);
}

}  // namespace
}  // namespace world
}  // namespace vrm_sim
