#include <gtest/gtest.h>

#include "vrm_render/microscope_camera.h"

namespace vrm_render {
namespace {

TEST(MicroscopeCamera, FocalPlanePointsHaveNoDisparityAndNearerPointsDo) {
  MicroscopeRig rig;
  MicroscopeState state;  // focal plane at z = 0.188 - 0.2 = -0.012
  const CameraView left = microscopeCamera(rig, state, 800, 600, Eye::kLeft, true);
  const CameraView right = microscopeCamera(rig, state, 800, 600, Eye::kRight, true);
  Eigen::Vector2f pl, pr;
  ASSERT_TRUE(projectToPixel(left, {0.002f, 0.001f, -0.012f}, &pl));
  ASSERT_TRUE(projectToPixel(right, {0.002f, 0.001f, -0.012f}, &pr));
  EXPECT_NEAR(pl.x(), pr.x(), 1e-2f);
  EXPECT_NEAR(pl.y(), pr.y(), 1e-2f);
  // A point 5 mm nearer the microscope shows crossed disparity (left image further right).
  ASSERT_TRUE(projectToPixel(left, {0.002f, 0.001f, -0.007f}, &pl));
  ASSERT_TRUE(projectToPixel(right, {0.002f, 0.001f, -0.007f}, &pr));
  EXPECT_GT(pl.x() - pr.x(), 5.0f);
  EXPECT_NEAR(pl.y(), pr.y(), 1e-2f);  // parallel optical paths: no vertical parallax
}

TEST(MicroscopeCamera, ReducedDisparityScalesTheDisparityAndMonoHasNone) {
  MicroscopeRig rig;
  MicroscopeState state;
  auto disparity = [&](const MicroscopeState& s, bool stereo) {
    Eigen::Vector2f pl, pr;
    projectToPixel(microscopeCamera(rig, s, 800, 600, Eye::kLeft, stereo), {0.0f, 0.0f, -0.006f}, &pl);
    projectToPixel(microscopeCamera(rig, s, 800, 600, Eye::kRight, stereo), {0.0f, 0.0f, -0.006f}, &pr);
    return pl.x() - pr.x();
  };
  const float full = disparity(state, true);
  state.disparity_scale = 0.5;
  EXPECT_NEAR(disparity(state, true), 0.5f * full, 0.02f * full);
  EXPECT_NEAR(disparity(state, false), 0.0f, 1e-3f);
}

TEST(MicroscopeCamera, ZoomNarrowsTheFieldAtTheFocalPlane) {
  MicroscopeRig rig;
  MicroscopeState state;
  Eigen::Vector2f p1, p2;
  projectToPixel(microscopeCamera(rig, state, 800, 600, Eye::kLeft, false), {0.005f, 0.0f, -0.012f}, &p1);
  state.zoom = 2.0;
  projectToPixel(microscopeCamera(rig, state, 800, 600, Eye::kLeft, false), {0.005f, 0.0f, -0.012f}, &p2);
  // 5 mm right of centre: 400 + 5/30*800 px at zoom 1, twice as far from the centre at zoom 2.
  EXPECT_NEAR(p1.x(), 400.0f + 0.005f / 0.03f * 800.0f, 0.5f);
  EXPECT_NEAR(p2.x() - 400.0f, 2.0f * (p1.x() - 400.0f), 0.5f);
  EXPECT_NEAR(p1.y(), 300.0f, 0.5f);
}

TEST(MicroscopeCamera, RejectsNonFiniteOrNonPositiveKnobs) {
  MicroscopeRig rig;
  MicroscopeState state;
  state.focus_distance = std::nan("");
  EXPECT_THROW(microscopeCamera(rig, state, 8, 8, Eye::kLeft, true), RenderError);
  state.focus_distance = 0.2;
  state.zoom = 0.0;
  EXPECT_THROW(microscopeCamera(rig, state, 8, 8, Eye::kLeft, true), RenderError);
  state.zoom = 1.0;
  EXPECT_THROW(microscopeCamera(rig, state, 0, 8, Eye::kLeft, true), RenderError);
}

}  // namespace
}  // namespace vrm_render
