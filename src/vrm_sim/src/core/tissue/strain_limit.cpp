#include "vrm_sim/tissue/strain_limit.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "spring_kernels.h"

namespace vrm_sim {
namespace tissue {

void NodeSpringAdjacency::build(const SystemView& system) {
  const std::size_t n = system.node_count;
  own_offsets_.assign(n + 1, 0);
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    ++own_offsets_[system.springs[s][0] + 1];
    ++own_offsets_[system.springs[s][1] + 1];
  }
  for (std::size_t i = 0; i < n; ++i) own_offsets_[i + 1] += own_offsets_[i];
  own_springs_.assign(own_offsets_[n], 0);
  std::vector<std::uint32_t> fill(own_offsets_.begin(), own_offsets_.end() - 1);
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    own_springs_[fill[system.springs[s][0]]++] = static_cast<std::uint32_t>(s);
    own_springs_[fill[system.springs[s][1]]++] = static_cast<std::uint32_t>(s);
  }
  adopt(system, own_offsets_.data(), own_springs_.data());
}

void NodeSpringAdjacency::adopt(const SystemView& system, const std::uint32_t* offsets, const std::uint32_t* springs) {
  node_count_ = system.node_count;
  offsets_ = offsets;
  springs_ = springs;
  others_.resize(offsets[node_count_]);
  for (std::uint32_t i = 0; i < node_count_; ++i) {
    for (std::uint32_t k = offsets[i]; k < offsets[i + 1]; ++k) {
      const std::array<std::uint32_t, 2>& ends = system.springs[springs[k]];
      others_[k] = ends[0] == i ? ends[1] : ends[0];
    }
  }
}

void SpringSorter::rebuild(const SystemView& system, const NodeSpringAdjacency& shared) {
  shared_ = &shared;
  reserve(system);
}

void SpringSorter::rebuild(const SystemView& system) {
  own_.build(system);
  shared_ = nullptr;
  reserve(system);
}

void SpringSorter::reserve(const SystemView& system) {
  distance_.assign(system.node_count, -1);
  queue_.reserve(system.node_count);
  order_.reserve(system.spring_count);
  spring_level_.assign(system.spring_count, 0);
  inner_is_second_.reserve(system.spring_count);
}

void SpringSorter::sort(const SystemView& system, const std::vector<std::uint32_t>& seeds) {
  // Alg. 5.2: breadth-first search from the interaction nodes. (Raw pointers in the loops: through the vectors'
  // members the compiler reloads every base pointer after each store.)
  const std::size_t n = distance_.size();
  const std::size_t m = system.spring_count;
  int* const distance = distance_.data();
  std::fill(distance, distance + n, -1);
  queue_.resize(n);
  std::uint32_t* const queue = queue_.data();
  std::size_t tail = 0;
  for (std::uint32_t seed : seeds) {
    if (seed < n && distance[seed] < 0) {
      distance[seed] = 0;
      queue[tail++] = seed;
    }
  }
  const std::uint32_t* const offsets = adjacency().offsets();
  const std::uint32_t* const neighbours = adjacency().others();
  int max_distance = 0;
  for (std::size_t head = 0; head < tail; ++head) {
    const std::uint32_t node = queue[head];
    const int next = distance[node] + 1;
    for (std::uint32_t k = offsets[node]; k < offsets[node + 1]; ++k) {
      const std::uint32_t other = neighbours[k];
      if (distance[other] < 0) {
        distance[other] = next;
        max_distance = std::max(max_distance, next);
        queue[tail++] = other;
      }
    }
  }
  queue_.resize(tail);
  // Counting sort of the springs by the distance of their nearer end; level max_distance + 1 = unreachable.
  const int unreachable = max_distance + 1;
  level_offsets_.assign(static_cast<std::size_t>(unreachable) + 2, 0);
  spring_inner_second_.resize(m);
  std::size_t* const counts = level_offsets_.data();
  int* const spring_level = spring_level_.data();
  std::uint8_t* const spring_inner_second = spring_inner_second_.data();
  const std::array<std::uint32_t, 2>* const springs = system.springs;
  for (std::size_t s = 0; s < m; ++s) {
    const int d0 = distance[springs[s][0]];
    const int d1 = distance[springs[s][1]];
    const int level = (d0 < 0 || d1 < 0) ? (d0 < 0 && d1 < 0 ? unreachable : std::max(d0, d1)) : std::min(d0, d1);
    spring_level[s] = level;
    spring_inner_second[s] = (d1 >= 0 && (d0 < 0 || d1 < d0)) ? 1 : 0;
    ++counts[level + 1];
  }
  for (std::size_t d = 1; d < level_offsets_.size(); ++d) level_offsets_[d] += level_offsets_[d - 1];
  order_.resize(m);
  ordered_ends_.resize(m);
  inner_is_second_.resize(m);
  level_fill_.assign(level_offsets_.begin(), level_offsets_.end() - 1);
  std::size_t* const fill = level_fill_.data();
  std::uint32_t* const order = order_.data();
  std::array<std::uint32_t, 2>* const ordered_ends = ordered_ends_.data();
  std::uint8_t* const inner_is_second = inner_is_second_.data();
  for (std::size_t s = 0; s < m; ++s) {
    const std::size_t k = fill[spring_level[s]]++;
    order[k] = static_cast<std::uint32_t>(s);
    ordered_ends[k] = springs[s];
    inner_is_second[k] = spring_inner_second[s];
  }
}

namespace {

// Shortens spring s (nodes `ends`) to tau·l. `inner` = 0/1 names the end that stays put when known (BFS order),
// -1 = unknown.
// A node moved by `delta` loses the part of its velocity that points against the move (an inelastic stop, as a
// ChainMail link: it never adds energy); nothing without velocities.
inline void stopAgainst(Eigen::Vector3d* velocities, std::uint32_t i, const Eigen::Vector3d& delta) {
  if (velocities == nullptr) return;
  const double norm2 = delta.squaredNorm();
  if (!(norm2 > 0.0)) return;
  Eigen::Vector3d& v = velocities[i];
  const double along = v.dot(delta);
  if (along < 0.0) v -= (along / norm2) * delta;
}

// Which ends a correction moves: only the free ones; of two free ends only the outer one when `inner` (0 or 1) names
// the end nearer the interaction (Alg. 5.2 order), both halfway otherwise.
struct MovingEnds {
  bool first, second;
};
inline MovingEnds movingEnds(bool free0, bool free1, int inner) {
  if (free0 && free1 && inner >= 0) return {inner == 1, inner == 0};
  return {free0, free1};
}

inline bool limitSpring(const SystemView& system, std::size_t s, const std::array<std::uint32_t, 2>& ends, double tau,
                        int inner, ProvotStatistics& stats, Eigen::Vector3d* velocities) {
  const double rest = system.rest_lengths[s];
  if (rest < kMinSpringLength) return false;
  Eigen::Vector3d& x0 = system.positions[ends[0]];
  Eigen::Vector3d& x1 = system.positions[ends[1]];
  const Eigen::Vector3d d = x1 - x0;
  const double limit = tau * rest;
  // Most springs are well inside the limit: decide those on |d|² without the square root (the margin keeps every
  // spring the exact test would correct).
  const double length2 = d.squaredNorm();
  if (length2 <= (limit * limit) * (1.0 - 1e-9)) return false;
  const double length = std::sqrt(length2);
  if (length <= limit * (1.0 + 1e-12)) return false;  // rounding after an earlier correction
  const bool free0 = system.isFree(ends[0]);
  const bool free1 = system.isFree(ends[1]);
  if (!free0 && !free1) {
    ++stats.skipped_fixed;
    return false;
  }
  const Eigen::Vector3d excess = ((length - limit) / length) * d;
  const MovingEnds move = movingEnds(free0, free1, inner);
  if (move.first && move.second) {
    x0 += 0.5 * excess;
    x1 -= 0.5 * excess;
    stopAgainst(velocities, ends[0], 0.5 * excess);
    stopAgainst(velocities, ends[1], -0.5 * excess);
  } else if (move.first) {
    x0 += excess;
    stopAgainst(velocities, ends[0], excess);
  } else {
    x1 -= excess;
    stopAgainst(velocities, ends[1], -excess);
  }
  ++stats.corrected;
  return true;
}

}  // namespace

ProvotStatistics provotPass(const SystemView& system, double tau, const SpringSorter* sorter, bool outer_only,
                            Eigen::Vector3d* velocities) {
  ProvotStatistics stats;
  if (sorter != nullptr && sorter->order().size() == system.spring_count) {
    const auto& order = sorter->order();
    const auto& ends = sorter->orderedEnds();
    const auto& inner_second = sorter->innerIsSecond();
    // The last set (not connected to an interaction) has no inner end.
    const std::size_t reachable_end = sorter->levelOffsets()[sorter->levelOffsets().size() - 2];
    for (std::size_t k = 0; k < order.size(); ++k) {
      limitSpring(system, order[k], ends[k], tau, (outer_only && k < reachable_end) ? inner_second[k] : -1, stats,
                  velocities);
    }
  } else {
    for (std::size_t s = 0; s < system.spring_count; ++s)
      limitSpring(system, s, system.springs[s], tau, -1, stats, velocities);
  }
  return stats;
}

double strainBound(double tau) {
  if (!(tau > 1.0) || !std::isfinite(tau)) return std::numeric_limits<double>::infinity();
  return std::min(2.0, 1.0 + 1.5 * (tau - 1.0));
}

double strainBoundTarget(double tau) {
  const double bound = strainBound(tau);
  if (!std::isfinite(bound)) return bound;
  return bound - std::max(0.2 * (bound - tau), 0.02 * (bound - 1.0));
}

bool anyBeyond(const SystemView& system, double bound) {
  if (!std::isfinite(bound)) return false;
  const double bound2 = bound * bound;
  for (std::size_t s = 0; s < system.spring_count; ++s) {
    const double rest = system.rest_lengths[s];
    const auto& ends = system.springs[s];
    const double length2 = (system.positions[ends[1]] - system.positions[ends[0]]).squaredNorm();
    // A non-finite length counts too (the watchdog rejects such a state anyway).
    if (!(length2 <= bound2 * (rest * rest)) && rest >= kMinSpringLength) return true;
  }
  return false;
}

namespace {

// Moves node `i` by `delta`; its velocity loses the component against the move (see BoundPassOptions::velocities).
inline void moveNode(const SystemView& system, const BoundPassOptions& options, std::uint32_t i,
                     const Eigen::Vector3d& delta) {
  system.positions[i] += delta;
  if (options.moved != nullptr) options.moved[i] = 1;
  stopAgainst(options.velocities, i, delta);
}

// Returns which ends it moved: bit 0 the first, bit 1 the second.
inline int boundSpring(const SystemView& system, const BoundPassOptions& options, std::size_t s,
                       const std::array<std::uint32_t, 2>& ends, int inner, BoundPassStatistics& stats) {
  const double rest = system.rest_lengths[s];
  if (!(rest >= kMinSpringLength)) return 0;
  const Eigen::Vector3d d = system.positions[ends[1]] - system.positions[ends[0]];
  const double limit = options.bound * rest;
  const double length2 = d.squaredNorm();
  if (length2 <= limit * limit || !std::isfinite(length2)) return 0;
  const double length = std::sqrt(length2);
  const bool may_tear =
      options.tearable != nullptr
          ? options.tearable[s] != 0
          : (options.bending == nullptr || options.bending[s] == 0) &&
                (options.pressed == nullptr || (options.pressed[ends[0]] == 0 && options.pressed[ends[1]] == 0));
  if (options.tear_strain > 0.0 && length > options.tear_strain * rest && may_tear) {
    ++stats.left_to_tear;
    return 0;
  }
  const bool free0 = options.fixed != nullptr ? options.fixed[ends[0]] == 0 : system.isFree(ends[0]);
  const bool free1 = options.fixed != nullptr ? options.fixed[ends[1]] == 0 : system.isFree(ends[1]);
  if (!free0 && !free1) {
    ++stats.skipped_fixed;
    return 0;
  }
  const double shortened = std::max(rest, length - options.relaxation * (length - options.target * rest));
  const Eigen::Vector3d excess = ((length - shortened) / length) * d;
  const MovingEnds move = movingEnds(free0, free1, inner);
  ++stats.corrected;
  if (move.first && move.second) {
    moveNode(system, options, ends[0], 0.5 * excess);
    moveNode(system, options, ends[1], -0.5 * excess);
    return 3;
  }
  if (move.first) {
    moveNode(system, options, ends[0], excess);
    return 1;
  }
  moveNode(system, options, ends[1], -excess);
  return 2;
}

}  // namespace

BoundPassStatistics boundPass(const SystemView& system, const BoundPassOptions& options) {
  BoundPassStatistics stats;
  if (!std::isfinite(options.bound)) return stats;
  const SpringSorter* sorter = options.sorter;
  if (sorter != nullptr && sorter->order().size() == system.spring_count) {
    const auto& order = sorter->order();
    const auto& ends = sorter->orderedEnds();
    const auto& inner_second = sorter->innerIsSecond();
    const auto& distance = sorter->nodeDistances();
    const std::size_t reachable_end = sorter->levelOffsets()[sorter->levelOffsets().size() - 2];
    for (std::size_t k = 0; k < order.size(); ++k) {
      // Both ends equally far from the seeds (two contacts of one instrument, a ring around it): neither is inner.
      const bool level = distance[ends[k][0]] == distance[ends[k][1]];
      boundSpring(system, options, order[k], ends[k], k < reachable_end && !level ? inner_second[k] : -1, stats);
    }
  } else if (options.reverse) {
    for (std::size_t s = system.spring_count; s-- > 0;) boundSpring(system, options, s, system.springs[s], -1, stats);
  } else {
    for (std::size_t s = 0; s < system.spring_count; ++s) boundSpring(system, options, s, system.springs[s], -1, stats);
  }
  return stats;
}

void ActiveBoundSolver::reset(std::size_t spring_count, const NodeSpringAdjacency& adjacency) {
  const std::size_t node_count = adjacency.nodeCount();
  adjacency_ = &adjacency;
  node_active_.assign(node_count, 0);
  spring_listed_.assign(spring_count, 0);
  nodes_.clear();
  nodes_.reserve(node_count);
  springs_.clear();
  springs_.reserve(spring_count);
}

void ActiveBoundSolver::activate(std::uint32_t node) {
  if (node >= node_active_.size() || node_active_[node]) return;
  node_active_[node] = 1;
  nodes_.push_back(node);
  const std::uint32_t* const offsets = adjacency_->offsets();
  const std::uint32_t* const springs = adjacency_->springs();
  for (std::uint32_t k = offsets[node]; k < offsets[node + 1]; ++k) {
    const std::uint32_t spring = springs[k];
    if (spring_listed_[spring]) continue;
    spring_listed_[spring] = 1;
    springs_.push_back(spring);
  }
}

bool ActiveBoundSolver::seed(const SystemView& system, double bound) {
  for (std::uint32_t node : nodes_) node_active_[node] = 0;
  for (std::uint32_t spring : springs_) spring_listed_[spring] = 0;
  nodes_.clear();
  springs_.clear();
  if (adjacency_ == nullptr || node_active_.size() != system.node_count ||
      spring_listed_.size() != system.spring_count || !std::isfinite(bound)) {
    return false;
  }
  // The sweep of squared lengths (vectorised, the same test), then the springs it found in spring order.
  beyond_.clear();
  kernels::springsBeyond(system, bound, beyond_);
  for (const std::uint32_t s : beyond_) {
    activate(system.springs[s][0]);
    activate(system.springs[s][1]);
  }
  return !springs_.empty();
}

BoundPassStatistics ActiveBoundSolver::sweep(const SystemView& system, const BoundPassOptions& options, bool reverse) {
  BoundPassStatistics stats;
  const auto visit = [&](std::uint32_t s) {
    const auto& ends = system.springs[s];
    const int moved = boundSpring(system, options, s, ends, -1, stats);
    if (moved & 1) activate(ends[0]);
    if (moved & 2) activate(ends[1]);
  };
  if (reverse) {
    for (std::size_t k = springs_.size(); k-- > 0;) visit(springs_[k]);
  } else {
    // The list grows while it is walked: springs a correction brought in are visited in the same sweep.
    for (std::size_t k = 0; k < springs_.size(); ++k) visit(springs_[k]);
  }
  return stats;
}

}  // namespace tissue
}  // namespace vrm_sim
