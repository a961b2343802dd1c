#include "vrm_sim/scenario/laser.h"

#include <algorithm>
#include <cmath>

#include "vrm_scene/hash.h"

namespace vrm_sim {
namespace scenario {

std::optional<LaserAim> laserAim(const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, double eye_radius) {
  if (!tip.allFinite() || !axis.allFinite() || !(eye_radius > 0.0)) return std::nullopt;
  const double length = axis.norm();
  if (!(length > 0.0)) return std::nullopt;
  const Eigen::Vector3d direction = axis / length;
  // |tip + s direction| = R with the tip inside: the one positive root.
  const double b = tip.dot(direction);
  const double c = tip.squaredNorm() - eye_radius * eye_radius;
  if (!(c < 0.0)) return std::nullopt;
  const double s = -b + std::sqrt(b * b - c);
  return LaserAim{tip + s * direction, s};
}

LaserSetting laserSetting(const scene::LaserProbeParams& params) {
  LaserSetting setting;
  setting.power = params.power_mw * 1e-3;
  setting.duration = params.duration_ms * 1e-3;
  setting.interval = params.interval_ms * 1e-3;
  setting.fibre_diameter = params.fibre_diameter;
  setting.numerical_aperture = params.numerical_aperture;
  return setting;
}

double spotDiameter(const LaserSetting& setting, double distance) {
  const double half_angle = std::asin(std::clamp(setting.numerical_aperture / kVitreousIndex, 0.0, 1.0));
  return setting.fibre_diameter + 2.0 * std::max(distance, 0.0) * std::tan(half_angle);
}

double burnGrade(const LaserSetting& setting, double distance) {
  const double d = spotDiameter(setting, distance);
  const double fluence = setting.power * setting.duration / (M_PI * 0.25 * d * d);
  return fluence / kModerateFluence;
}

LaserBurn makeBurn(const LaserSetting& setting, const Eigen::Vector3d& point, double distance, double time) {
  LaserBurn burn;
  burn.position = point;
  burn.spot = spotDiameter(setting, distance);
  burn.grade = burnGrade(setting, distance);
  burn.diameter = burn.grade >= kVisibleGrade ? burn.spot * std::min(1.6, 0.6 + 0.4 * burn.grade) : 0.0;
  burn.whiteness = burn.diameter > 0.0 ? 1.0 - std::exp(-burn.grade) : 0.0;
  burn.power = setting.power;
  burn.duration = setting.duration;
  burn.distance = distance;
  burn.time = time;
  return burn;
}

bool LaserTrigger::update(double pedal_travel, double time, const LaserSetting& setting) {
  const bool pressed = pedal_travel >= kPressTravel;
  bool fire = false;
  if (pressed && !pressed_) {
    fire = true;
  } else if (pressed && setting.interval > 0.0 && time >= next_shot_) {
    fire = true;  // repeat mode: the next exposure once the previous one and the interval have passed
  }
  if (fire) next_shot_ = time + setting.duration + setting.interval;
  pressed_ = pressed;
  return fire;
}

void LaserTrigger::hash(std::uint64_t& state) const {
  hashValue(state, pressed_);
  hashValue(state, next_shot_);
}

BurnCheck checkBurn(const LaserBurn& burn, const std::vector<LaserBurn>& earlier, const anatomy::FundusAnatomy& fundus,
                    double min_vessel_radius, double overlap_margin) {
  BurnCheck check;
  if (!(burn.diameter > 0.0)) return check;  // no lesion, no injury
  const double radius = 0.5 * burn.diameter;
  for (const LaserBurn& other : earlier) {
    if (!(other.diameter > 0.0)) continue;
    const double depth = radius + 0.5 * other.diameter - (burn.position - other.position).norm();
    if (depth > overlap_margin * std::min(burn.diameter, other.diameter)) check.overlaps = true;
  }
  // Along the retina, in the anatomy's fundus coordinates (metres along the surface).
  const Eigen::Vector3f point = burn.position.cast<float>();
  const Eigen::Vector2f at = fundus.toFundus(point);
  for (const anatomy::VesselSegment& vessel : fundus.vessels()) {
    if (std::max(vessel.radius_a, vessel.radius_b) < min_vessel_radius) continue;
    const Eigen::Vector2f ab = vessel.b - vessel.a;
    const float t = std::clamp((at - vessel.a).dot(ab) / std::max(ab.squaredNorm(), 1e-20f), 0.0f, 1.0f);
    const float vessel_radius = vessel.radius_a + (vessel.radius_b - vessel.radius_a) * t;
    if (vessel_radius < min_vessel_radius) continue;
    if ((at - (vessel.a + t * ab)).norm() <= radius + vessel_radius) {
      check.on_vessel = true;
      break;
    }
  }
  check.in_macula = (at - fundus.fovea()).norm() <= fundus.params().macula_radius + radius;
  return check;
}

BurnRow::BurnRow(const anatomy::FundusAnatomy& fundus, const Eigen::Vector3d& lesion_centre, double ring_radius,
                 double spacing, double band, double min_vessel_radius)
    : fundus_(&fundus), ring_radius_(ring_radius), spacing_(spacing), band_(band) {
  centre_ = fundus.toFundus(lesion_centre.cast<float>()).cast<double>();
  const int sectors = std::max(6, static_cast<int>(std::lround(2.0 * M_PI * ring_radius / spacing)));
  excused_.assign(static_cast<std::size_t>(sectors), false);
  for (std::size_t k = 0; k < excused_.size(); ++k) {
    LaserBurn probe;
    probe.position = point(k);
    probe.diameter = spacing;  // a burn as wide as the row's spacing (burns laid a burn width apart)
    excused_[k] = checkBurn(probe, {}, fundus, min_vessel_radius).on_vessel;
  }
}

Eigen::Vector3d BurnRow::point(std::size_t sector) const {
  const double angle = 2.0 * M_PI * (static_cast<double>(sector) + 0.5) / static_cast<double>(excused_.size());
  const Eigen::Vector2d at = centre_ + ring_radius_ * Eigen::Vector2d(std::cos(angle), std::sin(angle));
  return fundus_->toEye(at.cast<float>()).cast<double>();
}

std::size_t BurnRow::countable() const {
  return static_cast<std::size_t>(std::count(excused_.begin(), excused_.end(), false));
}

std::optional<std::size_t> BurnRow::sectorOf(const Eigen::Vector3d& point) const {
  const Eigen::Vector2d offset = fundus_->toFundus(point.cast<float>()).cast<double>() - centre_;
  if (!(std::abs(offset.norm() - ring_radius_) <= band_)) return std::nullopt;
  double angle = std::atan2(offset.y(), offset.x());
  if (angle < 0.0) angle += 2.0 * M_PI;
  return std::min(excused_.size() - 1, static_cast<std::size_t>(angle / (2.0 * M_PI) * excused_.size()));
}

}  // namespace scenario
}  // namespace vrm_sim
