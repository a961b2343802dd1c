#pragma once
// The measurements behind the score items, as plain functions and accumulators with exact references in
// test/unit/test_scenario_metrics.cpp (a known polyline's length, a sine's band power, a path's deviation).

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace scenario {

// Sum of the segment lengths.
double pathLength(const std::vector<Eigen::Vector3d>& points);

// Power of the motion in [low_hz, high_hz] (m^2): the samples (uniform, `sample_rate` Hz) minus their mean, one-sided
// periodogram 2|X_k|^2 / N^2 summed over the bins in the band and over the axes. A sine of amplitude A per axis at a
// bin frequency inside the band gives A^2 / 2 per axis; a band beyond Nyquist gives 0.
double bandPower(const std::vector<Eigen::Vector3d>& samples, double sample_rate, double low_hz, double high_hz);

// Root mean square distance of the samples from `centre` (m).
double rmsDistance(const std::vector<Eigen::Vector3d>& samples, const Eigen::Vector3d& centre);

struct PolylineProjection {
  double distance = 0.0;  // m, to the closest point of the polyline
  double arc = 0.0;       // m along the polyline to that point
};
// Closest point of a polyline (at least one point) to `point`.
PolylineProjection projectOnPolyline(const std::vector<Eigen::Vector3d>& polyline, const Eigen::Vector3d& point);

// Mean, maximum and coefficient of variation (std / mean) of a stream of values (Welford).
class RunningStats {
 public:
  void add(double value);
  std::size_t count() const { return count_; }
  double mean() const { return count_ ? mean_ : 0.0; }
  double max() const { return count_ ? max_ : 0.0; }
  double variance() const { return count_ > 1 ? m2_ / static_cast<double>(count_ - 1) : 0.0; }
  double coefficientOfVariation() const;
  void transferState(StateArchive& archive) { archive(count_)(mean_)(m2_)(max_); }

 private:
  std::size_t count_ = 0;
  double mean_ = 0.0, m2_ = 0.0, max_ = 0.0;
};

// Counts entries into a contact. By distance: a contact starts below `enter_below` and ends above `leave_above`
// (hysteresis, so tremor at the border is one contact, not many). Returns true on an entry.
class ContactCounter {
 public:
  bool update(bool touching);
  bool update(double distance, double enter_below, double leave_above) {
    return update(in_contact_ ? distance <= leave_above : distance < enter_below);
  }
  std::size_t count() const { return count_; }
  bool inContact() const { return in_contact_; }
  // in_contact_ too: the hysteresis decides whether the next frame is a new entry.
  void transferState(StateArchive& archive) { archive(count_)(in_contact_); }

 private:
  std::size_t count_ = 0;
  bool in_contact_ = false;
};

}  // namespace scenario
}  // namespace vrm_sim
