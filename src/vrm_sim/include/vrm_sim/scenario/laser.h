#pragma once
// Laser coagulation (issue 37): the endolaser's beam, its shots and the burns they leave on the retina. ROS- and
// GL-free, eye frame, SI units: the laser_coagulation scenario fires and scores with it, the renderer draws the aiming
// beam's spot (laserAim) and paints the burns into the fundus.
//
// The burn model — simple, stated, and calibrated to one clinical anchor, not fitted to tissue data:
//  * Beam. The probe's fibre (core diameter d_f, numerical aperture NA) emits a cone of half angle
//    theta = asin(NA / n) in the vitreous (n = 1.336); a beam that travels z to the retina lights a spot of
//    d = d_f + 2 z tan(theta) (geometrical optics of a multimode fibre: 200 µm, NA 0.12 -> 0.56 mm at 2 mm).
//  * Dose. A shot of power P and exposure t puts the radiant exposure H = P t / (pi d^2 / 4) on the spot. Its grade is
//    g = H / H_moderate; H_moderate = 8.1e4 J/m^2 (8.1 J/cm^2) makes the usual endolaser setting (200 mW, 100 ms)
//    at the usual working distance (2 mm) a moderate, grey-white burn (g = 1). Closer is smaller and hotter, farther
//    larger and weaker: at 0.5 mm the same shot is g = 3.7 (chalk-white), at 4 mm g = 0.37 (barely visible) — the
//    clinical rule "move the probe, not the power".
//  * Lesion. Burns below g = 0.3 leave no visible lesion. A visible one is d * min(1.6, 0.6 + 0.4 g) across (a strong
//    burn spreads beyond its spot by heat conduction) and drawn with whiteness 1 - exp(-g).
// Not modelled: the probe's motion during an exposure (the aim at the trigger is used: 0.1 s at a few mm/s is
// well below a spot), oblique incidence (the spot stays round), pigment variation across the fundus.
//
// Firing follows the laser console: a pedal press (travel rising through kPressTravel) fires one exposure of the set
// duration; with a repeat interval set, holding the pedal fires again every duration + interval. A shot needs the laser
// probe tracked, its tip inside the eye and its beam on the retina within kMaxBeamLength.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "vrm_scene/anatomy/fundus_anatomy.h"
#include "vrm_sim/scenario/scenario.h"
#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace scenario {

constexpr double kVitreousIndex = 1.336;
constexpr double kModerateFluence = 8.1e4;  // J/m^2: g = 1 (see above)
constexpr double kVisibleGrade = 0.3;       // below: no visible lesion
constexpr double kPressTravel = 0.5;        // pedal travel that fires
constexpr double kMaxBeamLength = 0.02;     // m: farther than the eye is deep, nothing is burnt

// Where the beam from `tip` along `axis` (unit) meets the retina, the inside of the eye sphere of `eye_radius` about
// the origin; nullopt when the tip is not inside the sphere or the values are not finite.
struct LaserAim {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double distance = 0.0;  // m from the tip along the beam
};
std::optional<LaserAim> laserAim(const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, double eye_radius);

// The probe's optics and console setting (from scene::LaserProbeParams, in SI units).
struct LaserSetting {
  double power = 0.2;                // W
  double duration = 0.1;             // s
  double interval = 0.0;             // s, 0 = single shots
  double fibre_diameter = 2e-4;      // m
  double numerical_aperture = 0.12;  // of the fibre

  void transferState(StateArchive& archive) { archive(power)(duration)(interval)(fibre_diameter)(numerical_aperture); }
};
LaserSetting laserSetting(const scene::LaserProbeParams& params);

double spotDiameter(const LaserSetting& setting, double distance);  // m
double burnGrade(const LaserSetting& setting, double distance);     // H / H_moderate

// The burn a shot of `setting` from `distance` leaves at `point`.
LaserBurn makeBurn(const LaserSetting& setting, const Eigen::Vector3d& point, double distance, double time);

// The pedal and the console's timing: which frames fire a shot.
class LaserTrigger {
 public:
  // True when this frame starts a shot (the pedal pressed now, or held past the repeat time). `time` in s.
  bool update(double pedal_travel, double time, const LaserSetting& setting);
  void reset() { *this = LaserTrigger(); }
  void hash(std::uint64_t& state) const;
  // A pedal held through a checkpoint must not fire again on its first frame after it.
  void transferState(StateArchive& archive) { archive(pressed_)(next_shot_); }

 private:
  bool pressed_ = false;
  double next_shot_ = 0.0;  // s: the repeat time while the pedal is held (only with an interval)
};

// What a new burn hit. A burn "overlaps" an earlier one when their lesions intersect by more than `overlap_margin` of
// the smaller diameter; it is "on a vessel" when its lesion reaches a vessel of at least `min_vessel_radius`; it is
// "in the macula" when its lesion reaches within the anatomy's macula_radius of the fovea.
struct BurnCheck {
  bool overlaps = false;
  bool on_vessel = false;
  bool in_macula = false;
};
BurnCheck checkBurn(const LaserBurn& burn, const std::vector<LaserBurn>& earlier, const anatomy::FundusAnatomy& fundus,
                    double min_vessel_radius, double overlap_margin = 0.1);

// The row of burns around a lesion (a barrier): the circle of `ring_radius` (measured along the retina, in the
// anatomy's fundus coordinates) about the lesion's centre, cut into sectors about `spacing` long (at least 6). A sector
// where a burn as wide as the spacing would reach a major vessel is excused: the surgeon leaves the gap. The scenario
// scores with it; the tool that writes the scripted sessions aims with it. Keeps a pointer to `fundus`, which must
// outlive it.
class BurnRow {
 public:
  BurnRow(const anatomy::FundusAnatomy& fundus, const Eigen::Vector3d& lesion_centre, double ring_radius,
          double spacing, double band, double min_vessel_radius);
  std::size_t sectors() const { return excused_.size(); }
  Eigen::Vector3d point(std::size_t sector) const;  // the sector's centre on the retina, eye frame
  bool excused(std::size_t sector) const { return excused_[sector]; }
  std::size_t countable() const;  // sectors not excused
  // The sector of a point on the retina within `band` of the row; nullopt off the row.
  std::optional<std::size_t> sectorOf(const Eigen::Vector3d& point) const;
  double ringRadius() const { return ring_radius_; }
  double spacing() const { return spacing_; }

 private:
  const anatomy::FundusAnatomy* fundus_;
  Eigen::Vector2d centre_ = Eigen::Vector2d::Zero();  // fundus coordinates
  double ring_radius_, spacing_, band_;
  std::vector<bool> excused_;
};

}  // namespace scenario
}  // namespace vrm_sim
