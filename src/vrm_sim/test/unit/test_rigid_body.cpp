// Rigid objects the forceps move (scenario/rigid_body.h, issue 36) against exact references: the shafts' segment
// distances against dense sampling, the resting rule against its definition, the fall against the closed-form solution
// of v' = g - drag v; grasp, hold, hand-over and drop semantics; hard cases (NaN tips, lost instruments, degenerate
// segments); and the World colliding an object where the scenario has moved it.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

#include "vrm_scene/scene_loader.h"
#include "vrm_sim/collision/primitives.h"
#include "vrm_sim/scenario/rigid_body.h"
#include "vrm_sim/world/offline.h"
#include "vrm_sim/world/world.h"

namespace vrm_sim {
namespace {

using scenario::FrameView;
using scenario::InstrumentView;
using scenario::RigidBody;
using scenario::RigidBodyOptions;

double sampledSegmentDistance(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, const Eigen::Vector3d& b0,
                              const Eigen::Vector3d& b1) {
  double best = std::numeric_limits<double>::infinity();
  constexpr int kSamples = 400;
  for (int i = 0; i <= kSamples; ++i) {
    for (int j = 0; j <= kSamples; ++j) {
      const Eigen::Vector3d p = a0 + (a1 - a0) * (static_cast<double>(i) / kSamples);
      const Eigen::Vector3d q = b0 + (b1 - b0) * (static_cast<double>(j) / kSamples);
      best = std::min(best, (p - q).norm());
    }
  }
  return best;
}

// The instrument shafts' distance (bimanual's instrument collisions) is the collision library's segment distance.
double segmentDistance(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, const Eigen::Vector3d& b0,
                       const Eigen::Vector3d& b1) {
  return std::sqrt(collision::segmentSegmentDistanceSquared(a0, a1, b0, b1));
}

TEST(SegmentDistance, MatchesDenseSamplingIncludingParallelAndDegenerateSegments) {
  // Crossing at right angles 1 mm apart.
  EXPECT_NEAR(segmentDistance({-1, 0, 0}, {1, 0, 0}, {0, -1, 1e-3}, {0, 1, 1e-3}), 1e-3, 1e-15);
  // Parallel, overlapping: the gap between the lines.
  EXPECT_NEAR(segmentDistance({0, 0, 0}, {1, 0, 0}, {0.5, 2e-4, 0}, {2, 2e-4, 0}), 2e-4, 1e-15);
  // Parallel, not overlapping: end to end.
  EXPECT_NEAR(segmentDistance({0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}), 1.0, 1e-15);
  // A point (degenerate segment) against a segment, and two points.
  EXPECT_NEAR(segmentDistance({0.5, 1, 0}, {0.5, 1, 0}, {0, 0, 0}, {1, 0, 0}), 1.0, 1e-15);
  EXPECT_NEAR(segmentDistance({0, 0, 0}, {0, 0, 0}, {3, 4, 0}, {3, 4, 0}), 5.0, 1e-15);
  std::mt19937 random(36);
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
  auto point = [&] { return Eigen::Vector3d(coordinate(random), coordinate(random), coordinate(random)); };
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::Vector3d a0 = point(), a1 = point(), b0 = point(), b1 = point();
    const double exact = segmentDistance(a0, a1, b0, b1);
    const double sampled = sampledSegmentDistance(a0, a1, b0, b1);
    EXPECT_LE(exact, sampled + 1e-12) << trial;  // never more than any sampled pair
    EXPECT_NEAR(exact, sampled, 2e-2) << trial;  // sampling step 1/400 of segments up to 3.5 long
  }
}

TEST(RestOnSphere, TheFaceTowardsTheWallLiesOnItAndTheYawIsKept) {
  const double radius = 0.012;
  const Eigen::Vector3d half(5e-4, 2.5e-4, 1.5e-4);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0.001, -0.0005, -0.009);
  // Tilted 20 deg about x and turned 30 deg about z: the -z face points most towards the wall (down).
  pose.linear() =
      (Eigen::AngleAxisd(0.5236, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(0.349, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const Eigen::Isometry3d rest = scenario::restOnSphere(pose, half, {0, 1, 2}, radius);
  const Eigen::Vector3d outward = pose.translation().normalized();
  EXPECT_NEAR(rest.translation().norm(), radius - half.z(), 1e-15);
  EXPECT_TRUE(rest.translation().normalized().isApprox(outward, 1e-12));
  EXPECT_NEAR((-rest.linear().col(2)).dot(outward), 1.0, 1e-12);  // the -z face on the wall
  EXPECT_NEAR(rest.linear().determinant(), 1.0, 1e-12);
  // The smallest rotation: the body turned by the angle between the face normal and the wall normal, no more.
  const double tilt = std::acos((-pose.linear().col(2)).dot(outward));
  const Eigen::AngleAxisd turn(rest.linear() * pose.linear().transpose());
  EXPECT_NEAR(turn.angle(), tilt, 1e-9);
  // Only the listed faces: a ring (z only) lies flat even when its x face points more towards the wall.
  Eigen::Isometry3d on_edge = pose;
  on_edge.linear() = Eigen::AngleAxisd(1.4, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Isometry3d ring = scenario::restOnSphere(on_edge, Eigen::Vector3d(8e-4, 8e-4, 1e-4), {2}, radius);
  EXPECT_NEAR(std::abs(ring.linear().col(2).dot(outward)), 1.0, 1e-12);
  EXPECT_NEAR(ring.translation().norm(), radius - 1e-4, 1e-15);
  // At the eye's centre there is no outward direction: it rests at the posterior pole.
  Eigen::Isometry3d centre = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d pole = scenario::restOnSphere(centre, half, {0, 1, 2}, radius);
  EXPECT_TRUE(pole.translation().isApprox(Eigen::Vector3d(0, 0, -(radius - half.z())), 1e-12));
}

InstrumentView forceps(const std::string& slot, const Eigen::Vector3d& tip, double jaw_angle,
                       const Eigen::Quaterniond& orientation = Eigen::Quaterniond::Identity()) {
  InstrumentView view;
  view.slot = slot;
  view.type = scene::InstrumentType::kForceps;
  view.valid = true;
  view.tip = tip;
  view.orientation = orientation;
  view.axis = orientation * Eigen::Vector3d::UnitZ();
  view.jaw_angle = jaw_angle;
  return view;
}

FrameView frameWith(std::vector<InstrumentView> instruments, double dt = 0.02) {
  FrameView frame;
  frame.dt = dt;
  frame.instruments = std::move(instruments);
  return frame;
}

constexpr double kOpen = 0.5, kClosed = 0.0;

Eigen::Isometry3d at(const Eigen::Vector3d& position) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = position;
  return pose;
}

TEST(RigidBody, FallsLikeTheClosedFormSolutionAndComesToRestOnTheRetina) {
  RigidBodyOptions options;
  options.half_extents = Eigen::Vector3d::Constant(2e-4);
  options.drag = 30.0;
  options.gravity = 9.81;
  const Eigen::Vector3d start(0.0, 0.0, 0.002);
  RigidBody body("cube", at(start), options);
  // Lift it with the forceps and let go there.
  body.update(frameWith({forceps("right", start, kOpen)}), {"right"});
  body.update(frameWith({forceps("right", start, kClosed)}), {"right"});
  ASSERT_TRUE(body.held());
  EXPECT_EQ(body.update(frameWith({forceps("right", start, kOpen)}), {"right"}), std::vector<std::string>{"right"});
  ASSERT_FALSE(body.held());
  // x(t) = g/d t - g/d^2 (1 - exp(-d t)): after two frames (0.04 s, 5.5 mm: still in the vitreous).
  double t = 0.0;
  for (int i = 0; i < 2; ++i, t += 0.02) ASSERT_FALSE(body.fall(frameWith({}, 0.02)));
  const double g = 9.81, d = 30.0;
  const double exact = g / d * t - g / (d * d) * (1.0 - std::exp(-d * t));
  const double fallen = start.z() - body.centre().z();
  EXPECT_NEAR(fallen, exact, 0.02 * exact);  // semi-implicit Euler, 1 ms substeps: first order in the step
  int frames = 0;
  while (!body.fall(frameWith({}, 0.02)) && frames < 1000) ++frames;
  ASSERT_LT(frames, 1000) << "never landed";
  EXPECT_TRUE(body.resting());
  EXPECT_NEAR(body.centre().norm(), options.eye_radius - 2e-4, 1e-12);
  EXPECT_FALSE(body.fall(frameWith({}, 0.02))) << "a resting body does not fall again";
}

TEST(RigidBody, GraspsOnlyWhenTheJawsCloseWithinReachAndFollowsTheJawsRigidly) {
  RigidBodyOptions options;
  options.grasp_reach = 3e-4;
  const Eigen::Vector3d centre(0.001, 0.0, -0.0115);
  RigidBody body("box", at(centre), options);
  // Jaws already closed when they arrive: no grasp (the body would be caught by closed jaws).
  body.update(frameWith({forceps("right", centre, kClosed)}), {"right"});
  body.update(frameWith({forceps("right", centre, kClosed)}), {"right"});
  EXPECT_FALSE(body.held());
  // Open, then closing out of reach: no grasp.
  const Eigen::Vector3d far = centre + Eigen::Vector3d(4e-4, 0, 0);
  body.update(frameWith({forceps("right", far, kOpen)}), {"right"});
  body.update(frameWith({forceps("right", far, kClosed)}), {"right"});
  EXPECT_FALSE(body.held());
  // Open, then closing within reach: held, with its pose relative to the jaws kept through any motion.
  const Eigen::Vector3d near = centre + Eigen::Vector3d(2e-4, 0, 0);
  body.update(frameWith({forceps("right", near, kOpen)}), {"right"});
  body.update(frameWith({forceps("right", near, kClosed)}), {"right"});
  ASSERT_TRUE(body.held());
  EXPECT_EQ(body.holder(), "right");
  const Eigen::Isometry3d jaws_from_body = at(near).inverse() * body.pose();
  const Eigen::Quaterniond turned(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  const Eigen::Vector3d moved(0.0, 0.002, -0.008);
  body.update(frameWith({forceps("right", moved, kClosed, turned)}), {"right"});
  Eigen::Isometry3d jaws = Eigen::Isometry3d::Identity();
  jaws.linear() = turned.toRotationMatrix();
  jaws.translation() = moved;
  EXPECT_TRUE(body.pose().isApprox(jaws * jaws_from_body, 1e-12));
}

TEST(RigidBody, AHandOverKeepsThePoseAndALostOrNaNInstrumentLetsGo) {
  RigidBodyOptions options;
  options.grasp_reach = 1e-3;
  const Eigen::Vector3d centre(0.0, 0.0, -0.008);
  RigidBody body("bar", at(centre), options);
  const Eigen::Vector3d right_tip = centre + Eigen::Vector3d(8e-4, 0, 0);
  const Eigen::Vector3d left_tip = centre - Eigen::Vector3d(8e-4, 0, 0);
  const std::vector<std::string> both = {"right", "left"};
  body.update(
      frameWith({forceps("right", right_tip, kOpen), forceps("left", left_tip + Eigen::Vector3d(0, 0.003, 0), kOpen)}),
      both);
  body.update(frameWith({forceps("right", right_tip, kClosed),
                         forceps("left", left_tip + Eigen::Vector3d(0, 0.003, 0), kOpen)}),
              both);
  ASSERT_EQ(body.holder(), "right");
  // The right moves the bar 1 mm while the left closes on it; the left's grip slides along.
  const Eigen::Vector3d shift(0, 0, 0.001);
  body.update(frameWith({forceps("right", right_tip + shift, kClosed), forceps("left", left_tip + shift, kOpen)}),
              both);
  body.update(frameWith({forceps("right", right_tip + shift, kClosed), forceps("left", left_tip + shift, kClosed)}),
              both);
  EXPECT_EQ(body.holderCount(), 2u);
  EXPECT_EQ(body.holder(), "right") << "the first holder moves the body";
  const Eigen::Isometry3d before = body.pose();
  // The right lets go: a hand-over, not a drop, and the bar does not jump.
  EXPECT_TRUE(
      body.update(frameWith({forceps("right", right_tip + shift, kOpen), forceps("left", left_tip + shift, kClosed)}),
                  both)
          .empty());
  EXPECT_EQ(body.holder(), "left");
  EXPECT_TRUE(body.pose().isApprox(before, 1e-12));
  // The left's tip goes NaN (a corrupt pose): it does not hold anything, the bar drops.
  InstrumentView broken = forceps("left", Eigen::Vector3d::Constant(std::nan("")), kClosed);
  EXPECT_EQ(body.update(frameWith({forceps("right", right_tip, kOpen), broken}), both),
            std::vector<std::string>{"left"});
  EXPECT_FALSE(body.held());
  EXPECT_TRUE(body.pose().matrix().allFinite());
  // Grasped again, then the instrument is lost by the tracker (not valid): it lets go.
  body.update(frameWith({forceps("right", body.centre(), kOpen)}), {"right"});
  body.update(frameWith({forceps("right", body.centre(), kClosed)}), {"right"});
  ASSERT_TRUE(body.held());
  InstrumentView lost = forceps("right", body.centre(), kClosed);
  lost.valid = false;
  EXPECT_EQ(body.update(frameWith({lost}), {"right"}), std::vector<std::string>{"right"});
}

// The World collides an object where the scenario has it: pick_and_place's expert lifts the sphere off the retina;
// with rigid reports on, the forceps holding it collide with the sphere at its carried place.
TEST(RigidBody, TheWorldCollidesAMovedObjectWhereTheScenarioHasIt) {
  const scene::SceneDescription scene =
      scene::withScript(scene::loadScene(scene::shippedScenePath("pick_and_place")), "expert");
  world::WorldOptions options;
  options.auto_start = true;
  world::World world(scene, options);
  world.setRigidReports(true);
  bool carried_and_touching = false;
  Eigen::Vector3d carried = Eigen::Vector3d::Zero();
  world.setFrameObserver([&](const world::FrameResult& frame) {
    if (frame.scenario == nullptr || world::toSeconds(frame.stamp) < 5.5 || world::toSeconds(frame.stamp) > 6.0) return;
    for (const scenario::ObjectPlacement& placement : frame.scenario->placements) {
      if (placement.name == "ball") carried = placement.pose.translation();
    }
    for (const world::CollisionRecord& record : frame.collisions) {
      if (record.object == "ball" && record.instrument == "right" && record.result.colliding)
        carried_and_touching = true;
    }
  });
  for (const world::InstrumentState& input : world::scriptedInputs(scene, 50.0, 6.0)) world.handle(input);
  world.flush();
  EXPECT_GT((carried - scene.findObject("ball")->pose.xyz).norm(), 1e-3) << "the sphere was not carried";
  EXPECT_TRUE(carried_and_touching) << "the held sphere does not collide with the jaws holding it";
}

}  // namespace
}  // namespace vrm_sim

namespace vrm_sim {
namespace {

// The manipulation scenes with one thing broken: each is refused when the World builds its scenario, naming the
// parameter and why (a misconfigured module must not load and silently never complete).
std::string shippedText(const std::string& name) {
  std::ifstream file(scene::shippedScenePath(name));
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

std::string refusal(const std::string& yaml) {
  try {
    world::World world(scene::loadSceneFromString(yaml, "broken.yaml"));
  } catch (const std::exception& error) {
    return error.what();
  }
  return "";
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(ManipulationScenes, BrokenParametersAreRefusedNamingWhy) {
  const std::string manipulation = shippedText("object_manipulation");
  EXPECT_EQ(refusal(manipulation), "");
  // The ring's hole narrower than the post: it could never be threaded.
  EXPECT_NE(refusal(replaced(manipulation, "major_radius: 0.0007, minor_radius: 0.0001",
                             "major_radius: 0.0003, minor_radius: 0.0001"))
                .find("wider than the post"),
            std::string::npos);
  // The key given a sphere: the type needs a box.
  EXPECT_NE(refusal(replaced(manipulation, "mesh: {generator: box, params: {size: [0.0003, 0.00012, 0.0012]}}",
                             "mesh: {generator: sphere, params: {radius: 0.0003}}"))
                .find("must be a box"),
            std::string::npos);
  EXPECT_NE(refusal(replaced(manipulation, "tasks: [box, ring, key]", "tasks: [box, ring, door]")).find("door"),
            std::string::npos);
  EXPECT_NE(refusal(replaced(manipulation, "place_tolerance: 0.0003", "place_tolerance: -1")).find("place_tolerance"),
            std::string::npos);
  const std::string bimanual = shippedText("bimanual");
  EXPECT_EQ(refusal(bimanual), "");
  // A light pipe in one of the two slots: a hand-over needs two forceps.
  EXPECT_NE(refusal(replaced(bimanual,
                             "  - slot: left\n    type: forceps\n    params: {jaw_length: 0.0015, jaw_angle_deg: 0.0}",
                             "  - slot: left\n    type: light_pipe"))
                .find("needs forceps in both slots"),
            std::string::npos);
  EXPECT_NE(refusal(replaced(bimanual, "second: left", "second: right")).find("different slots"), std::string::npos);
}

}  // namespace
}  // namespace vrm_sim
