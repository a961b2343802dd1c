#include "vrm_sim/scenario/metrics.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

namespace vrm_sim {
namespace scenario {

double pathLength(const std::vector<Eigen::Vector3d>& points) {
  double length = 0.0;
  for (std::size_t i = 1; i < points.size(); ++i) length += (points[i] - points[i - 1]).norm();
  return length;
}

double bandPower(const std::vector<Eigen::Vector3d>& samples, double sample_rate, double low_hz, double high_hz) {
  const std::size_t n = samples.size();
  if (n < 2 || !(sample_rate > 0.0)) return 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& sample : samples) mean += sample;
  mean /= static_cast<double>(n);
  const double resolution = sample_rate / static_cast<double>(n);
  const std::size_t first = static_cast<std::size_t>(std::max(1.0, std::ceil(low_hz / resolution - 1e-9)));
  const std::size_t last =
      std::min<std::size_t>((n - 1) / 2, static_cast<std::size_t>(std::floor(high_hz / resolution + 1e-9)));
  double power = 0.0;
  for (std::size_t k = first; k <= last; ++k) {
    // One DFT bin by direct summation (only the band's bins are needed; a few dozen at the scenarios' rates).
    const double omega = -2.0 * M_PI * static_cast<double>(k) / static_cast<double>(n);
    std::complex<double> x[3] = {0.0, 0.0, 0.0};
    for (std::size_t i = 0; i < n; ++i) {
      const std::complex<double> w = std::polar(1.0, omega * static_cast<double>(i));
      const Eigen::Vector3d d = samples[i] - mean;
      for (int axis = 0; axis < 3; ++axis) x[axis] += d[axis] * w;
    }
    for (int axis = 0; axis < 3; ++axis) power += 2.0 * std::norm(x[axis]) / (static_cast<double>(n) * n);
  }
  return power;
}

double rmsDistance(const std::vector<Eigen::Vector3d>& samples, const Eigen::Vector3d& centre) {
  if (samples.empty()) return 0.0;
  double sum = 0.0;
  for (const auto& sample : samples) sum += (sample - centre).squaredNorm();
  return std::sqrt(sum / static_cast<double>(samples.size()));
}

PolylineProjection projectOnPolyline(const std::vector<Eigen::Vector3d>& polyline, const Eigen::Vector3d& point) {
  PolylineProjection best;
  if (polyline.empty()) return best;
  best.distance = (point - polyline.front()).norm();
  double arc = 0.0;
  for (std::size_t i = 1; i < polyline.size(); ++i) {
    const Eigen::Vector3d a = polyline[i - 1], b = polyline[i];
    const double length = (b - a).norm();
    double s = length > 0.0 ? std::clamp((point - a).dot(b - a) / (length * length), 0.0, 1.0) : 0.0;
    const double distance = (point - (a + s * (b - a))).norm();
    if (distance < best.distance) {
      best.distance = distance;
      best.arc = arc + s * length;
    }
    arc += length;
  }
  return best;
}

void RunningStats::add(double value) {
  ++count_;
  const double delta = value - mean_;
  mean_ += delta / static_cast<double>(count_);
  m2_ += delta * (value - mean_);
  max_ = count_ == 1 ? value : std::max(max_, value);
}

double RunningStats::coefficientOfVariation() const {
  const double m = mean();
  return m > 0.0 ? std::sqrt(variance()) / m : 0.0;
}

bool ContactCounter::update(bool touching) {
  const bool entered = touching && !in_contact_;
  in_contact_ = touching;
  if (entered) ++count_;
  return entered;
}

}  // namespace scenario
}  // namespace vrm_sim
