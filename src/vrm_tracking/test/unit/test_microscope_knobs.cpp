#include <gtest/gtest.h>

#include "vrm_tracking/microscope_knobs.h"

namespace vrm_tracking {
namespace {

TEST(MicroscopeKnobs, FollowsScriptWithoutButtons) {
  MicroscopeKnobs knobs{MicroscopeLimits{}};
  MicroscopeSample scripted;
  scripted.zoom = 1.7;
  scripted.focus_distance = 0.21;
  const MicroscopeSample out = knobs.update(scripted, PedalSample{}, 0.05);
  EXPECT_DOUBLE_EQ(out.zoom, 1.7);
  EXPECT_DOUBLE_EQ(out.focus_distance, 0.21);
}

TEST(MicroscopeKnobs, ButtonsMoveAtRateAndOffsetPersists) {
  MicroscopeLimits limits;
  limits.zoom_rate = 0.5;
  limits.focus_rate = 0.01;
  MicroscopeKnobs knobs(limits);
  MicroscopeSample scripted;  // zoom 1, focus 0.2
  PedalSample buttons;
  buttons.zoom_in = true;
  buttons.focus_near = true;
  MicroscopeSample out;
  for (int i = 0; i < 20; ++i) out = knobs.update(scripted, buttons, 0.05);  // 1 s held
  EXPECT_NEAR(out.zoom, 1.5, 1e-12);
  EXPECT_NEAR(out.focus_distance, 0.19, 1e-12);
  // Released: the knob stays where it was turned, on top of the (moving) script.
  scripted.zoom = 1.2;
  out = knobs.update(scripted, PedalSample{}, 0.05);
  EXPECT_NEAR(out.zoom, 1.7, 1e-12);
  // Both directions at once cancel.
  buttons = PedalSample{};
  buttons.zoom_in = buttons.zoom_out = true;
  EXPECT_NEAR(knobs.update(scripted, buttons, 1.0).zoom, 1.7, 1e-12);
}

TEST(MicroscopeKnobs, ClampsToLimitsWithoutWindUp) {
  MicroscopeLimits limits;
  limits.zoom_max = 2.0;
  limits.zoom_rate = 1.0;
  MicroscopeKnobs knobs(limits);
  MicroscopeSample scripted;
  PedalSample in;
  in.zoom_in = true;
  for (int i = 0; i < 100; ++i) EXPECT_LE(knobs.update(scripted, in, 0.1).zoom, 2.0);
  EXPECT_DOUBLE_EQ(knobs.update(scripted, in, 0.1).zoom, 2.0);
  // Holding against the limit did not store 9 extra units of zoom: one step back leaves the limit at once.
  PedalSample out;
  out.zoom_out = true;
  EXPECT_NEAR(knobs.update(scripted, out, 0.1).zoom, 1.9, 1e-12);
  // Script values outside the limits are clamped too.
  scripted.focus_distance = 1.0;
  EXPECT_DOUBLE_EQ(knobs.update(scripted, PedalSample{}, 0.1).focus_distance, limits.focus_max);
}

TEST(MicroscopeKnobs, RejectsBadLimits) {
  MicroscopeLimits limits;
  limits.zoom_min = 3.0;
  limits.zoom_max = 2.0;
  EXPECT_THROW(MicroscopeKnobs{limits}, std::invalid_argument);
  limits = MicroscopeLimits{};
  limits.focus_rate = -1.0;
  EXPECT_THROW(MicroscopeKnobs{limits}, std::invalid_argument);
}

}  // namespace
}  // namespace vrm_tracking
