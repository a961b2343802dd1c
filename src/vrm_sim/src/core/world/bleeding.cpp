#include "vrm_sim/world/bleeding.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vrm_sim {
namespace world {

BleedingField::BleedingField(std::string object, std::vector<Eigen::Vector3d> vertices, BleedingParameters parameters)
    : object_(std::move(object)), vertices_(std::move(vertices)), parameters_(parameters) {
  field_.assign(vertices_.size(), 0.0f);
}

void BleedingField::clear() {
  std::fill(field_.begin(), field_.end(), 0.0f);
  spots_.clear();
  active_.clear();
  events_.clear();
  dirty_ = false;
  max_injury_ = 0.0;
}

double BleedingField::distanceToSurface(const Eigen::Vector3d& point) const {
  double best = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& vertex : vertices_) best = std::min(best, (vertex - point).squaredNorm());
  return std::sqrt(best);
}

double BleedingField::radiusAt(const Spot& spot, double time) const {
  return std::min(std::max(parameters_.max_radius, spot.initial_radius),
                  spot.initial_radius + parameters_.spread_rate * std::max(0.0, time - spot.onset));
}

void BleedingField::contact(const std::string& instrument, const Eigen::Vector3d& point, double depth, bool aspiration,
                            double time, double extent) {
  if (!point.allFinite() || !std::isfinite(depth) || !std::isfinite(time) || !std::isfinite(extent)) return;
  const double initial_radius = std::max(parameters_.initial_radius, 0.5 * extent);
  depth = std::max(0.0, depth);
  const double intensity =
      std::clamp(parameters_.min_intensity + (1.0 - parameters_.min_intensity) * depth / parameters_.depth_full,
                 parameters_.min_intensity, 1.0);
  auto active =
      std::find_if(active_.begin(), active_.end(), [&](const Active& entry) { return entry.instrument == instrument; });
  if (active == active_.end()) {
    ContactEvent event;
    event.instrument = instrument;
    event.object = object_;
    event.start = event.end = time;
    event.point = point;
    event.max_depth = depth;
    event.aspiration = aspiration;
    events_.push_back(event);
    spots_.push_back({point, time, intensity, initial_radius, true});
    active_.push_back({instrument, events_.size() - 1, spots_.size() - 1, true});
    dirty_ = true;
    return;
  }
  active->renewed = true;
  ContactEvent& event = events_[active->event];
  event.end = time;
  event.max_depth = std::max(event.max_depth, depth);
  event.aspiration = event.aspiration || aspiration;
  Spot& spot = spots_[active->spot];
  if ((point - spot.centre).norm() > parameters_.new_spot_distance) {
    // Dragged along the retina: a smear of spots.
    spots_.push_back({point, time, intensity, initial_radius, true});
    active->spot = spots_.size() - 1;
    dirty_ = true;
  } else if (intensity > spot.intensity) {
    spot.intensity = intensity;
    dirty_ = true;
  }
}

bool BleedingField::update(double time, std::vector<ContactEvent>* ended) {
  for (auto it = active_.begin(); it != active_.end();) {
    if (it->renewed) {
      it->renewed = false;
      ++it;
      continue;
    }
    ContactEvent& event = events_[it->event];
    event.ongoing = false;
    if (ended != nullptr) ended->push_back(event);
    it = active_.erase(it);
  }
  bool spreading = false;
  for (Spot& spot : spots_) {
    spot.spreading = radiusAt(spot, time) < parameters_.max_radius;
    spreading = spreading || spot.spreading;
  }
  // A spot that reached its final radius leaves the field as it is: recompute only while something changes.
  if (!dirty_ && !spreading) return false;
  const bool was_dirty = dirty_;
  dirty_ = false;
  std::vector<float> next(vertices_.size(), 0.0f);
  for (const Spot& spot : spots_) {
    const double sigma = radiusAt(spot, time);
    const double cutoff2 = 9.0 * sigma * sigma;  // 3 sigma: exactly zero outside, so an injury stays local
    const double inverse = 1.0 / (2.0 * sigma * sigma);
    for (std::size_t i = 0; i < vertices_.size(); ++i) {
      const double d2 = (vertices_[i] - spot.centre).squaredNorm();
      if (d2 > cutoff2) continue;
      const double value = spot.intensity * std::exp(-d2 * inverse);
      next[i] = static_cast<float>(std::min(1.0, static_cast<double>(next[i]) + value));
    }
  }
  const bool changed = was_dirty || next != field_;
  field_.swap(next);
  max_injury_ = field_.empty() ? 0.0 : *std::max_element(field_.begin(), field_.end());
  return changed;
}

}  // namespace world
}  // namespace vrm_sim
