#include "vrm_sim/tissue/chainmail.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>

#include "vrm_sim/mge/membrane.h"

namespace vrm_sim {
namespace tissue {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr double kMinLink = 1e-12;  // m: shorter rest vectors have no direction (degenerate input)

void requireFinite(double value, const char* name) {
  if (!std::isfinite(value)) throw std::invalid_argument(std::string("chainmail: ") + name + " must be finite");
}

}  // namespace

ChainMail::ChainMail(mge::Membrane& membrane, const ChainMailConfig& config) : membrane_(&membrane), config_(config) {
  requireFinite(config.min_stretch, "min_stretch");
  requireFinite(config.max_stretch, "max_stretch");
  requireFinite(config.max_shear, "max_shear");
  requireFinite(config.relaxation, "relaxation");
  if (config.min_stretch > 1.0 || config.max_stretch < 1.0 || config.max_shear < 0.0) {
    throw std::invalid_argument(
        "chainmail: limits must contain the rest state (min_stretch <= 1 <= max_stretch, "
        "max_shear >= 0)");
  }
  if (config.relaxation < 0.0 || config.relaxation > 1.0) {
    throw std::invalid_argument("chainmail: relaxation must be in [0, 1]");
  }
  for (std::size_t i = 0; i < membrane.nodeCount(); ++i) {
    if (!membrane.positions()[i].allFinite()) {
      throw std::invalid_argument("chainmail: node " + std::to_string(i) + " has a non-finite position");
    }
    rest_by_id_[membrane.nodeAtSlot(i).id()] = membrane.positions()[i];
  }
  rebuild();
}

void ChainMail::rebuild() {
  mge::Membrane& membrane = *membrane_;
  const std::size_t n = membrane.nodeCount();
  const std::size_t springs = membrane.springCount();
  std::vector<Eigen::Vector3d> rest(n);
  for (std::size_t i = 0; i < n; ++i) {
    auto found = rest_by_id_.find(membrane.nodeAtSlot(i).id());
    // A node added later (refinement) rests where it is now.
    rest[i] = found != rest_by_id_.end() ? found->second : membrane.positions()[i];
    if (found == rest_by_id_.end()) rest_by_id_[membrane.nodeAtSlot(i).id()] = rest[i];
  }
  rest_vectors_.assign(springs, Eigen::Vector3d::Zero());
  rest_lengths_.assign(springs, 0.0);
  rest_directions_.assign(springs, Eigen::Vector3d::Zero());
  adjacency_offsets_.assign(n + 1, 0);
  const std::array<std::uint32_t, 2>* ends = membrane.springNodeSlots();
  for (std::size_t s = 0; s < springs; ++s) {
    rest_vectors_[s] = rest[ends[s][1]] - rest[ends[s][0]];
    const double length = rest_vectors_[s].norm();
    if (membrane.springAtSlot(s).bending() || !(length > kMinLink)) continue;
    rest_lengths_[s] = length;
    rest_directions_[s] = rest_vectors_[s] / length;
    ++adjacency_offsets_[ends[s][0] + 1];
    ++adjacency_offsets_[ends[s][1] + 1];
  }
  for (std::size_t i = 0; i < n; ++i) adjacency_offsets_[i + 1] += adjacency_offsets_[i];
  adjacency_.assign(adjacency_offsets_[n], 0);
  std::vector<std::uint32_t> fill(adjacency_offsets_.begin(), adjacency_offsets_.end() - 1);
  for (std::size_t s = 0; s < springs; ++s) {
    if (!active(s)) continue;
    adjacency_[fill[ends[s][0]]++] = static_cast<std::uint32_t>(s);
    adjacency_[fill[ends[s][1]]++] = static_cast<std::uint32_t>(s);
  }
  dist_.assign(n, kInfinity);
  reached_.assign(n, 0);
  settled_mark_.assign(n, 0);
  current_epoch_ = 0;
}

double ChainMail::slack(std::size_t spring, bool from_first, const Eigen::Vector3d& direction) const {
  if (!active(spring)) return kInfinity;
  const auto& ends = membrane_->springNodeSlots()[spring];
  const Eigen::Vector3d* x = membrane_->positions();
  // Link vector from the leading end i to the lagging end j, and the rest direction oriented the same way.
  const std::uint32_t i = from_first ? ends[0] : ends[1];
  const std::uint32_t j = from_first ? ends[1] : ends[0];
  const Eigen::Vector3d link = x[j] - x[i];
  const Eigen::Vector3d u = from_first ? rest_directions_[spring] : Eigen::Vector3d(-rest_directions_[spring]);
  const double l = rest_lengths_[spring];
  // j lags by t: link(t) = link − t·direction. Stretch s(t) = s − t·a must stay in [lo, hi] ...
  const double s = link.dot(u);
  const double a = direction.dot(u);
  double limit = kInfinity;
  if (a > 0.0) {
    limit = (s - config_.min_stretch * l) / a;
  } else if (a < 0.0) {
    limit = (config_.max_stretch * l - s) / -a;
  }
  // ... and the shear |p − t·e| <= h (p, e: link and direction without their u components).
  const Eigen::Vector3d p = link - s * u;
  const Eigen::Vector3d e = direction - a * u;
  const double ee = e.squaredNorm();
  if (ee > 1e-24) {
    const double h = config_.max_shear * l;
    const double pe = p.dot(e);
    const double discriminant = pe * pe - ee * (p.squaredNorm() - h * h);
    limit = discriminant < 0.0 ? 0.0 : std::min(limit, (pe + std::sqrt(discriminant)) / ee);
  }
  return std::max(limit, 0.0);
}

double ChainMail::linkViolation(std::size_t spring) const {
  if (!active(spring)) return 0.0;
  const auto& ends = membrane_->springNodeSlots()[spring];
  const Eigen::Vector3d link = membrane_->positions()[ends[1]] - membrane_->positions()[ends[0]];
  const Eigen::Vector3d& u = rest_directions_[spring];
  const double l = rest_lengths_[spring];
  const double s = link.dot(u);
  const double shear = (link - s * u).norm();
  const double violation =
      std::max({config_.min_stretch * l - s, s - config_.max_stretch * l, shear - config_.max_shear * l, 0.0});
  return violation / l;
}

double ChainMail::maxViolation() const {
  double worst = 0.0;
  for (std::size_t s = 0; s < rest_lengths_.size(); ++s) worst = std::max(worst, linkViolation(s));
  return worst;
}

ChainMailMove ChainMail::move(std::uint32_t node, const Eigen::Vector3d& displacement, const std::uint8_t* held) {
  ChainMailMove result;
  const std::size_t n = membrane_->nodeCount();
  double budget = displacement.norm();
  if (node >= n || !(budget > 0.0) || !std::isfinite(budget) || membrane_->fixedFlags()[node]) return result;
  const Eigen::Vector3d direction = displacement / budget;
  const std::uint8_t* fixed = membrane_->fixedFlags();
  const std::array<std::uint32_t, 2>* ends = membrane_->springNodeSlots();

  if (++current_epoch_ == 0) {  // wrapped: clear the marks once every 2^32 moves
    std::fill(reached_.begin(), reached_.end(), 0);
    std::fill(settled_mark_.begin(), settled_mark_.end(), 0);
    current_epoch_ = 1;
  }
  settled_.clear();
  heap_.clear();
  const auto later = std::greater<std::pair<double, std::uint32_t>>();
  dist_[node] = 0.0;
  reached_[node] = current_epoch_;
  heap_.push_back({0.0, node});
  while (!heap_.empty()) {
    std::pop_heap(heap_.begin(), heap_.end(), later);
    const auto [distance, k] = heap_.back();
    heap_.pop_back();
    if (settled_mark_[k] == current_epoch_ || distance > dist_[k]) continue;  // stale entry
    if (distance >= budget) break;  // k and everything after it stay where they are
    if (k != node && (fixed[k] || (held != nullptr && held[k]))) {
      // k cannot follow: shorten the move so that it does not have to.
      budget = distance;
      result.limited = true;
      break;
    }
    settled_mark_[k] = current_epoch_;
    settled_.push_back(k);
    for (std::uint32_t a = adjacency_offsets_[k]; a < adjacency_offsets_[k + 1]; ++a) {
      const std::uint32_t s = adjacency_[a];
      const bool from_first = ends[s][0] == k;
      const std::uint32_t j = from_first ? ends[s][1] : ends[s][0];
      if (settled_mark_[j] == current_epoch_) continue;
      ++result.link_checks;
      const double candidate = distance + slack(s, from_first, direction);
      if (candidate >= budget) continue;
      if (reached_[j] != current_epoch_ || candidate < dist_[j]) {
        reached_[j] = current_epoch_;
        dist_[j] = candidate;
        heap_.push_back({candidate, j});
        std::push_heap(heap_.begin(), heap_.end(), later);
      }
    }
  }
  // All slacks were measured on the old state; now move everyone at once.
  Eigen::Vector3d* x = membrane_->positions();
  for (std::uint32_t k : settled_) {
    const double t = budget - dist_[k];
    if (t <= 0.0) continue;
    x[k] += t * direction;
    ++result.moved_nodes;
  }
  result.settled_nodes = settled_.size();
  result.achieved = budget * direction;
  return result;
}

std::size_t ChainMail::relax(const std::uint8_t* held) {
  const double alpha = config_.relaxation;
  if (!(alpha > 0.0)) return 0;
  const std::size_t n = membrane_->nodeCount();
  Eigen::Vector3d* x = membrane_->positions();
  const std::uint8_t* fixed = membrane_->fixedFlags();
  const std::array<std::uint32_t, 2>* ends = membrane_->springNodeSlots();
  std::size_t moved = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t begin = adjacency_offsets_[k];
    const std::uint32_t end = adjacency_offsets_[k + 1];
    if (fixed[k] || (held != nullptr && held[k]) || begin == end) continue;
    // Where the rest vectors of its links would put the node.
    Eigen::Vector3d target = Eigen::Vector3d::Zero();
    for (std::uint32_t a = begin; a < end; ++a) {
      const std::uint32_t s = adjacency_[a];
      target += ends[s][0] == k ? Eigen::Vector3d(x[ends[s][1]] - rest_vectors_[s])
                                : Eigen::Vector3d(x[ends[s][0]] + rest_vectors_[s]);
    }
    target /= static_cast<double>(end - begin);
    const Eigen::Vector3d old = x[k];
    x[k] = old + alpha * (target - old);
    bool valid = x[k].allFinite();
    for (std::uint32_t a = begin; a < end && valid; ++a) valid = linkViolation(adjacency_[a]) <= 1e-12;
    if (valid && x[k] != old) {
      ++moved;
    } else {
      x[k] = old;  // relaxation never takes a link out of its limits
    }
  }
  return moved;
}

}  // namespace tissue
}  // namespace vrm_sim
