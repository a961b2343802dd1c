// Issue 37: the laser's beam, burn model, trigger and injury checks (scenario/laser.h) against closed-form values, and
// the hard cases: beams that miss, non-finite poses, a pedal held down, settings out of range.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "vrm_scene/anatomy/fundus_anatomy.h"
#include "vrm_scene/instrument_model.h"
#include "vrm_sim/scenario/laser.h"

namespace vrm_sim {
namespace scenario {
namespace {

constexpr double kRadius = 0.012;
const double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(LaserAim, MeetsTheSphereWhereTheRayDoes) {
  // From the centre straight back: the posterior pole, one radius away.
  auto aim = laserAim(Eigen::Vector3d::Zero(), -Eigen::Vector3d::UnitZ(), kRadius);
  ASSERT_TRUE(aim.has_value());
  EXPECT_NEAR((aim->point - Eigen::Vector3d(0, 0, -kRadius)).norm(), 0.0, 1e-15);
  EXPECT_NEAR(aim->distance, kRadius, 1e-15);
  // An oblique beam from an off-centre tip lands on the sphere, along the beam (the axis need not be unit).
  const Eigen::Vector3d tip(0.003, -0.002, -0.004);
  const Eigen::Vector3d axis(-0.5, 0.2, -1.0);
  aim = laserAim(tip, 3.0 * axis, kRadius);
  ASSERT_TRUE(aim.has_value());
  EXPECT_NEAR(aim->point.norm(), kRadius, 1e-15);
  EXPECT_NEAR((tip + aim->distance * axis.normalized() - aim->point).norm(), 0.0, 1e-15);
}

TEST(LaserAim, NothingOutsideTheEyeOrFromBadValues) {
  EXPECT_FALSE(laserAim(Eigen::Vector3d(0, 0, 0.013), -Eigen::Vector3d::UnitZ(), kRadius));    // outside
  EXPECT_FALSE(laserAim(Eigen::Vector3d(0, 0, kRadius), -Eigen::Vector3d::UnitZ(), kRadius));  // on the wall
  EXPECT_FALSE(laserAim(Eigen::Vector3d(kNaN, 0, 0), -Eigen::Vector3d::UnitZ(), kRadius));
  EXPECT_FALSE(laserAim(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), kRadius));  // no direction
  EXPECT_FALSE(laserAim(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, kNaN, -1), kRadius));
  EXPECT_FALSE(laserAim(Eigen::Vector3d::Zero(), -Eigen::Vector3d::UnitZ(), 0.0));
}

TEST(BurnModel, SpotGrowsWithTheBeamsHalfAngle) {
  LaserSetting setting;
  EXPECT_DOUBLE_EQ(spotDiameter(setting, 0.0), setting.fibre_diameter);
  const double slope = 2.0 * std::tan(std::asin(setting.numerical_aperture / kVitreousIndex));
  EXPECT_NEAR(spotDiameter(setting, 0.002), setting.fibre_diameter + 0.002 * slope, 1e-15);
  EXPECT_NEAR(spotDiameter(setting, 0.002), 5.6e-4, 1e-5);                // the header's example: 0.56 mm at 2 mm
  EXPECT_DOUBLE_EQ(spotDiameter(setting, -1.0), setting.fibre_diameter);  // a tip on the retina
}

TEST(BurnModel, GradeIsTheRadiantExposureOfAModerateBurn) {
  LaserSetting setting;  // 200 mW, 100 ms
  EXPECT_NEAR(burnGrade(setting, 0.002), 1.0, 0.01);
  // H = P t / (pi d^2 / 4), exactly.
  const double d = spotDiameter(setting, 0.003);
  EXPECT_NEAR(burnGrade(setting, 0.003), 0.02 / (M_PI * d * d / 4.0) / kModerateFluence, 1e-12);
  // Linear in power and in exposure, falling with distance.
  LaserSetting doubled = setting;
  doubled.power *= 2.0;
  EXPECT_NEAR(burnGrade(doubled, 0.002), 2.0 * burnGrade(setting, 0.002), 1e-12);
  doubled = setting;
  doubled.duration *= 2.0;
  EXPECT_NEAR(burnGrade(doubled, 0.002), 2.0 * burnGrade(setting, 0.002), 1e-12);
  double previous = std::numeric_limits<double>::infinity();
  for (double z = 0.0; z < 0.01; z += 2.5e-4) {
    EXPECT_LT(burnGrade(setting, z), previous) << z;
    previous = burnGrade(setting, z);
  }
  EXPECT_GT(burnGrade(setting, 0.0005), 3.0);  // chalk-white up close
  EXPECT_LT(burnGrade(setting, 0.004), 0.45);  // barely visible from 4 mm
}

TEST(BurnModel, LesionAppearsAtTheVisibleGradeAndSpreadsWithStrength) {
  LaserSetting setting;
  const Eigen::Vector3d point(0, 0, -kRadius);
  const LaserBurn weak = makeBurn(setting, point, 0.008, 1.0);
  EXPECT_LT(weak.grade, kVisibleGrade);
  EXPECT_EQ(weak.diameter, 0.0);
  EXPECT_EQ(weak.whiteness, 0.0);
  const LaserBurn moderate = makeBurn(setting, point, 0.002, 1.0);
  EXPECT_NEAR(moderate.diameter, moderate.spot * (0.6 + 0.4 * moderate.grade), 1e-15);
  EXPECT_NEAR(moderate.whiteness, 1.0 - std::exp(-moderate.grade), 1e-15);
  const LaserBurn strong = makeBurn(setting, point, 0.0, 1.0);
  EXPECT_DOUBLE_EQ(strong.diameter, 1.6 * strong.spot);  // heat spread, capped
  EXPECT_GT(strong.whiteness, 0.99);
  EXPECT_EQ(moderate.power, 0.2);
  EXPECT_EQ(moderate.duration, 0.1);
  EXPECT_EQ(moderate.time, 1.0);
}

TEST(LaserTrigger, OneShotPerPressUnlessRepeating) {
  LaserSetting single;
  LaserTrigger trigger;
  int shots = 0;
  for (int frame = 0; frame < 200; ++frame) {  // 4 s at 50 Hz, the pedal held from 0.2 s
    shots += trigger.update(frame >= 10 ? 1.0 : 0.0, frame * 0.02, single);
  }
  EXPECT_EQ(shots, 1);
  EXPECT_TRUE(trigger.update(0.0, 4.0, single) == false);
  EXPECT_TRUE(trigger.update(0.6, 4.02, single));    // pressed again
  EXPECT_FALSE(trigger.update(0.49, 4.04, single));  // below kPressTravel: released
  EXPECT_TRUE(trigger.update(0.5, 4.06, single));

  LaserSetting repeat;
  repeat.interval = 0.2;  // a shot every 0.1 + 0.2 s while held
  LaserTrigger repeating;
  shots = 0;
  for (int frame = 0; frame <= 100; ++frame) shots += repeating.update(1.0, frame * 0.01, repeat);  // 1 s held
  EXPECT_EQ(shots, 4);  // at 0, 0.3, 0.6, 0.9 s
  LaserTrigger broken;
  EXPECT_FALSE(broken.update(kNaN, 0.0, single));  // a non-finite pedal fires nothing
}

TEST(BurnCheck, OverlapVesselAndMacula) {
  const anatomy::FundusAnatomy fundus;
  LaserSetting setting;
  // In the macula: a burn at the fovea.
  const LaserBurn at_fovea = makeBurn(setting, Eigen::Vector3d(0, 0, -kRadius), 0.002, 0.0);
  EXPECT_TRUE(checkBurn(at_fovea, {}, fundus, 2.5e-5).in_macula);
  // On a vessel: the middle of the thickest trunk segment.
  const anatomy::VesselSegment* trunk = nullptr;
  for (const auto& segment : fundus.vessels()) {
    if (segment.generation == 0 && (trunk == nullptr || segment.radius_a > trunk->radius_a)) trunk = &segment;
  }
  ASSERT_NE(trunk, nullptr);
  const Eigen::Vector3d on_vessel = fundus.toEye(0.5f * (trunk->a + trunk->b)).cast<double>();
  const LaserBurn vessel_burn = makeBurn(setting, on_vessel, 0.002, 0.0);
  EXPECT_TRUE(checkBurn(vessel_burn, {}, fundus, 2.5e-5).on_vessel);
  EXPECT_FALSE(checkBurn(vessel_burn, {}, fundus, 1e-3).on_vessel) << "no vessel is 2 mm wide";
  // Overlap: the same spot twice; a burn a lesion width away does not overlap.
  const Eigen::Vector3d far_point = fundus.toEye(Eigen::Vector2f(-0.006f, -0.004f)).cast<double>();
  const LaserBurn first = makeBurn(setting, far_point, 0.002, 0.0);
  EXPECT_TRUE(checkBurn(first, {first}, fundus, 2.5e-5).overlaps);
  const Eigen::Vector3d beside =
      fundus.toEye(Eigen::Vector2f(-0.006f + static_cast<float>(1.05 * first.diameter), -0.004f)).cast<double>();
  EXPECT_FALSE(checkBurn(makeBurn(setting, beside, 0.002, 0.0), {first}, fundus, 2.5e-5).overlaps);
  // A shot that left no lesion injures nothing.
  const LaserBurn invisible = makeBurn(setting, Eigen::Vector3d(0, 0, -kRadius), 0.009, 0.0);
  const BurnCheck none = checkBurn(invisible, {first}, fundus, 2.5e-5);
  EXPECT_FALSE(none.in_macula || none.on_vessel || none.overlaps);
}

TEST(BurnRow, SectorsAroundTheLesionAndTheBand) {
  const anatomy::FundusAnatomy fundus;
  const Eigen::Vector3d lesion = fundus.toEye(Eigen::Vector2f(-0.006f, -0.004f)).cast<double>();
  const BurnRow row(fundus, lesion, 0.00135, 0.0006, 0.0003, 2.5e-5);
  EXPECT_EQ(row.sectors(), static_cast<std::size_t>(std::lround(2.0 * M_PI * 0.00135 / 0.0006)));
  for (std::size_t k = 0; k < row.sectors(); ++k) {
    EXPECT_NEAR(row.point(k).norm(), kRadius, 1e-6);
    EXPECT_EQ(row.sectorOf(row.point(k)), k);
  }
  EXPECT_FALSE(row.sectorOf(lesion).has_value()) << "the lesion's centre is off the row";
  std::size_t excused = 0;
  for (std::size_t k = 0; k < row.sectors(); ++k) excused += row.excused(k);
  EXPECT_EQ(row.countable() + excused, row.sectors());
}

TEST(LaserSettings, TheConsoleChangesPowerAndExposureWithinTheSchemasRanges) {
  scene::InstrumentDescription probe;
  probe.type = scene::InstrumentType::kLaserProbe;
  probe.params = scene::LaserProbeParams{};
  EXPECT_EQ(scene::applyInstrumentSettings(probe, "power_mw=250,duration_ms=150,interval_ms=0"), "");
  const auto& laser = std::get<scene::LaserProbeParams>(probe.params);
  EXPECT_EQ(laser.power_mw, 250.0);
  EXPECT_EQ(laser.duration_ms, 150.0);
  for (const char* bad : {"power_mw=0", "power_mw=4000", "duration_ms=nan", "power=200", "power_mw=20x",
                          "power_mw=", "", "power_mw=200,,duration_ms=100", "interval_ms=-1"}) {
    EXPECT_NE(scene::applyInstrumentSettings(probe, bad), "") << bad;
  }
  EXPECT_EQ(laser.power_mw, 250.0) << "a refused setting changes nothing";
  EXPECT_NE(scene::applyInstrumentSettings(probe, "power_mw=300,duration_ms=0"), "");
  EXPECT_EQ(laser.power_mw, 250.0) << "not even the valid part of a refused command";
  scene::InstrumentDescription forceps;
  forceps.type = scene::InstrumentType::kForceps;
  forceps.params = scene::ForcepsParams{};
  EXPECT_NE(scene::applyInstrumentSettings(forceps, "power_mw=200"), "");
}

}  // namespace
}  // namespace scenario
}  // namespace vrm_sim
