#include "vrm_sim/tissue/refinement.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>

#include "vrm_sim/mge/membrane.h"

namespace vrm_sim {
namespace tissue {

namespace {

mge::Spring* springBetween(mge::Node& a, mge::Node& b) {
  for (mge::Spring* spring : a.springs()) {
    mge::ListAccess<mge::Node> ends = spring->nodes();
    if ((ends[0] == &a && ends[1] == &b) || (ends[0] == &b && ends[1] == &a)) return spring;
  }
  return nullptr;
}

std::pair<std::uint64_t, std::uint64_t> ordered(std::uint64_t a, std::uint64_t b) {
  return a < b ? std::make_pair(a, b) : std::make_pair(b, a);
}

}  // namespace

std::size_t LocalRefinement::nodesPerTriangle(int level) {
  const std::size_t s = std::size_t{1} << level;
  return (s + 1) * (s + 2) / 2;
}
std::size_t LocalRefinement::springsPerTriangle(int level) {
  const std::size_t s = std::size_t{1} << level;
  return 3 * s * (s + 1) / 2;  // 3·2ⁿ⁻¹(2ⁿ+1)
}
std::size_t LocalRefinement::trianglesPerTriangle(int level) { return std::size_t{1} << (2 * level); }

LocalRefinement::LocalRefinement(mge::Membrane& membrane, const RefinementConfig& config)
    : membrane_(&membrane), config_(config) {
  if (config.levels < 0 || config.levels > 4) throw std::invalid_argument("refinement: levels must be in [0, 4]");
  if (!(config.radius > 0.0) || !std::isfinite(config.radius)) {
    throw std::invalid_argument("refinement: radius must be positive and finite");
  }
  segments_ = 1 << config.levels;
  for (std::size_t s = 0; s < membrane.springCount(); ++s) {
    if (membrane.springAtSlot(s).bending()) {
      throw std::invalid_argument("refinement: membranes with bending springs are not supported");
    }
  }
  const Eigen::Vector3d* x = membrane.positions();
  const std::size_t n = membrane.nodeCount();
  std::vector<double> node_area(n, 0.0);
  std::vector<int> node_triangles(n, 0);
  std::vector<double> areas(membrane.triangleCount());
  for (std::size_t t = 0; t < membrane.triangleCount(); ++t) {
    const auto& c = membrane.triangleNodeSlots()[t];
    areas[t] = 0.5 * (x[c[1]] - x[c[0]]).cross(x[c[2]] - x[c[0]]).norm();
    for (std::uint32_t corner : c) {
      node_area[corner] += areas[t];
      ++node_triangles[corner];
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    original_mass_[membrane.nodeAtSlot(i).id()] = membrane.masses()[i];
    original_fixed_[membrane.nodeAtSlot(i).id()] = membrane.fixedFlags()[i] != 0;
  }
  coarse_.resize(membrane.triangleCount());
  for (std::size_t t = 0; t < membrane.triangleCount(); ++t) {
    const auto& c = membrane.triangleNodeSlots()[t];
    CoarseTriangle& coarse = coarse_[t];
    for (int k = 0; k < 3; ++k) {
      mge::Node& a = membrane.nodeAtSlot(c[k]);
      mge::Node& b = membrane.nodeAtSlot(c[(k + 1) % 3]);
      coarse.corners[k] = a.id();
      mge::Spring* spring = springBetween(a, b);
      if (spring == nullptr) throw std::invalid_argument("refinement: a triangle edge has no spring");
      coarse.rest[k] = spring->restLength();
      coarse.stiffness[k] = spring->stiffness();
      Edge& edge = edges_[ordered(a.id(), b.id())];
      ++edge.coarse_users;
      edge.rest = coarse.rest[k];
      edge.stiffness = coarse.stiffness[k];
      // The corner's mass, shared among its triangles by area (evenly if they have none).
      const std::uint32_t slot = c[k];
      const double fraction = node_area[slot] > 0.0 ? areas[t] / node_area[slot] : 1.0 / node_triangles[slot];
      coarse.mass_share[k] = membrane.masses()[slot] * fraction;
      coarse.mass += coarse.mass_share[k];
    }
  }
  rebuildIdMap();
}

std::size_t LocalRefinement::refinedTriangleCount() const {
  std::size_t count = 0;
  for (const CoarseTriangle& coarse : coarse_) count += coarse.refined ? 1 : 0;
  return count;
}

std::size_t LocalRefinement::latticeIndex(int i, int j) const {
  // Row j holds S + 1 − j points.
  return static_cast<std::size_t>(j * (segments_ + 1) - j * (j - 1) / 2 + i);
}

void LocalRefinement::rebuildIdMap() {
  node_of_.clear();
  for (std::size_t i = 0; i < membrane_->nodeCount(); ++i) {
    mge::Node& node = membrane_->nodeAtSlot(i);
    node_of_[node.id()] = &node;
  }
  // The coarse corners as elements (their addresses never move), so that the per-step search in refineAt() needs
  // no hash lookups. Only a cut removes corners; it calls this again.
  corner_nodes_.resize(coarse_.size());
  for (std::size_t t = 0; t < coarse_.size(); ++t) {
    for (int k = 0; k < 3; ++k) corner_nodes_[t][k] = nodeById(coarse_[t].corners[k]);
  }
}

mge::Node* LocalRefinement::nodeById(std::uint64_t id) const {
  auto found = node_of_.find(id);
  return found == node_of_.end() ? nullptr : found->second;
}

bool LocalRefinement::cornersAlive(std::size_t index) const {
  const auto& corners = corner_nodes_[index];
  return corners[0] != nullptr && corners[1] != nullptr && corners[2] != nullptr;
}

Eigen::Vector3d LocalRefinement::centroid(std::size_t index) const {
  const auto& corners = corner_nodes_[index];
  return (corners[0]->position() + corners[1]->position() + corners[2]->position()) / 3.0;
}

void LocalRefinement::refineTriangle(std::size_t index) {
  mge::Membrane& membrane = *membrane_;
  CoarseTriangle& coarse = coarse_[index];
  const int S = segments_;
  std::array<mge::Node*, 3> corner{};
  for (int k = 0; k < 3; ++k) corner[k] = nodeById(coarse.corners[k]);
  const Eigen::Vector3d p0 = corner[0]->position(), p1 = corner[1]->position(), p2 = corner[2]->position();
  // The rest shape from the three rest lengths (planar), for the fine rest lengths (eq. 5.15).
  const double l01 = coarse.rest[0], l12 = coarse.rest[1], l20 = coarse.rest[2];
  const Eigen::Vector3d r0 = Eigen::Vector3d::Zero();
  const Eigen::Vector3d r1(l01, 0.0, 0.0);
  const double rx = l01 > 0.0 ? (l01 * l01 + l20 * l20 - l12 * l12) / (2.0 * l01) : 0.0;
  const Eigen::Vector3d r2(rx, std::sqrt(std::max(l20 * l20 - rx * rx, 0.0)), 0.0);

  // Remove the coarse triangle (its edge springs go only where no other coarse triangle uses them). No node is
  // removed, so node_of_ stays valid; new nodes are added to it as they are created.
  if (mge::Triangle* triangle = findCoarseTriangle(coarse)) membrane.removeElements({triangle}, {}, {}, false);

  // Lattice nodes: corners, shared edge nodes (created by whichever triangle of the edge is refined first), interior.
  const std::size_t count = nodesPerTriangle(config_.levels);
  std::vector<mge::Node*> lattice(count, nullptr);
  std::vector<Eigen::Vector3d> rest(count);
  coarse.lattice.assign(count, 0);
  for (int j = 0; j <= S; ++j) {
    for (int i = 0; i + j <= S; ++i) {
      const std::size_t at = latticeIndex(i, j);
      const double u = static_cast<double>(i) / S, v = static_cast<double>(j) / S;
      rest[at] = r0 + u * (r1 - r0) + v * (r2 - r0);
      const Eigen::Vector3d position = p0 + u * (p1 - p0) + v * (p2 - p0);
      mge::Node* node = nullptr;
      if (i == 0 && j == 0) {
        node = corner[0];
      } else if (i == S && j == 0) {
        node = corner[1];
      } else if (i == 0 && j == S) {
        node = corner[2];
      } else {
        // Which coarse edge (if any) and the position along it from its first corner.
        int edge = -1, along = 0;
        if (j == 0) {
          edge = 0, along = i;
        } else if (i + j == S) {
          edge = 1, along = j;
        } else if (i == 0) {
          edge = 2, along = S - j;
        }
        if (edge < 0) {
          node = &membrane.addNode(position, 0.0);
          node_of_[node->id()] = node;
        } else {
          const std::uint64_t a = coarse.corners[edge], b = coarse.corners[(edge + 1) % 3];
          Edge& record = edges_[ordered(a, b)];
          if (record.nodes.empty()) {
            const Eigen::Vector3d pa = nodeById(std::min(a, b))->position();
            const Eigen::Vector3d pb = nodeById(std::max(a, b))->position();
            for (int k = 1; k < S; ++k) {
              mge::Node& created = membrane.addNode(pa + (static_cast<double>(k) / S) * (pb - pa), 0.0);
              node_of_[created.id()] = &created;
              record.nodes.push_back(created.id());
            }
          }
          const int from_smaller = a < b ? along : S - along;
          node = nodeById(record.nodes[from_smaller - 1]);
        }
      }
      lattice[at] = node;
      coarse.lattice[at] = node->id();
    }
  }

  // Fine springs: reuse those on an edge shared with an already refined neighbour; stiffness by direction.
  const double scale = config_.chain_stiffness_scaling ? static_cast<double>(S) : 1.0;
  auto spring = [&](std::size_t a, std::size_t b, int direction) -> mge::Spring& {
    if (mge::Spring* existing = springBetween(*lattice[a], *lattice[b])) return *existing;
    return membrane.addSpring(*lattice[a], *lattice[b], coarse.stiffness[direction] * scale, false,
                              (rest[b] - rest[a]).norm());
  };
  auto triangle = [&](std::size_t a, std::size_t b, std::size_t c, int dir_ab, int dir_bc, int dir_ca) {
    mge::Triangle& fine = membrane.addTriangle(*lattice[a], *lattice[b], *lattice[c]);
    membrane.linkEdgeSpring(fine, spring(a, b, dir_ab));
    membrane.linkEdgeSpring(fine, spring(b, c, dir_bc));
    membrane.linkEdgeSpring(fine, spring(c, a, dir_ca));
  };
  // Directions: (+1, 0) ∥ edge 0, (−1, +1) ∥ edge 1, (0, +1) ∥ edge 2.
  for (int j = 0; j < S; ++j) {
    for (int i = 0; i + j < S; ++i) {
      triangle(latticeIndex(i, j), latticeIndex(i + 1, j), latticeIndex(i, j + 1), 0, 1, 2);
      if (i + j + 1 < S) {
        triangle(latticeIndex(i + 1, j), latticeIndex(i + 1, j + 1), latticeIndex(i, j + 1), 2, 0, 1);
      }
    }
  }
  for (int k = 0; k < 3; ++k) {
    Edge& record = edges_[ordered(coarse.corners[k], coarse.corners[(k + 1) % 3])];
    --record.coarse_users;
    ++record.refined_users;
  }
  coarse.refined = true;
  springs_in_use_ += springsPerTriangle(config_.levels);
}

void LocalRefinement::coarsenTriangle(std::size_t index) {
  mge::Membrane& membrane = *membrane_;
  CoarseTriangle& coarse = coarse_[index];
  const int S = segments_;
  std::set<std::uint64_t> lattice_ids(coarse.lattice.begin(), coarse.lattice.end());
  bool intact = cornersAlive(index);
  for (std::uint64_t id : coarse.lattice) intact = intact && node_of_.count(id) > 0;
  // Edges that stay refined (the neighbour still uses their lattice) keep their nodes and springs.
  std::array<bool, 3> kept{};
  for (int k = 0; k < 3; ++k) {
    Edge& record = edges_[ordered(coarse.corners[k], coarse.corners[(k + 1) % 3])];
    --record.refined_users;
    kept[k] = record.refined_users > 0;
  }
  auto onKeptEdge = [&](std::uint64_t a, std::uint64_t b) {
    for (int k = 0; k < 3; ++k) {
      if (!kept[k]) continue;
      const Edge& record = edges_[ordered(coarse.corners[k], coarse.corners[(k + 1) % 3])];
      auto onLine = [&](std::uint64_t id) {
        return id == coarse.corners[k] || id == coarse.corners[(k + 1) % 3] ||
               std::find(record.nodes.begin(), record.nodes.end(), id) != record.nodes.end();
      };
      if (onLine(a) && onLine(b)) return true;
    }
    return false;
  };
  std::vector<mge::Node*> nodes;
  std::vector<mge::Spring*> springs;
  std::vector<mge::Triangle*> triangles;
  for (int j = 0; j <= S; ++j) {
    for (int i = 0; i + j <= S; ++i) {
      const bool is_corner = (i == 0 && j == 0) || (i == S && j == 0) || (i == 0 && j == S);
      mge::Node* node = nodeById(coarse.lattice[latticeIndex(i, j)]);
      if (node == nullptr) continue;  // cut away
      for (mge::Triangle* fine : node->triangles()) {
        bool inside = true;
        for (mge::Node* c : fine->nodes()) inside = inside && lattice_ids.count(c->id()) > 0;
        if (inside) triangles.push_back(fine);
      }
      for (mge::Spring* fine : node->springs()) {
        mge::ListAccess<mge::Node> ends = fine->nodes();
        if (lattice_ids.count(ends[0]->id()) && lattice_ids.count(ends[1]->id()) &&
            !onKeptEdge(ends[0]->id(), ends[1]->id()) && !springBetweenCorners(coarse, *fine)) {
          springs.push_back(fine);
        }
      }
      if (is_corner) continue;
      int edge = -1;
      if (j == 0) {
        edge = 0;
      } else if (i + j == S) {
        edge = 1;
      } else if (i == 0) {
        edge = 2;
      }
      if (edge < 0 || !kept[edge]) nodes.push_back(node);
    }
  }
  for (int k = 0; k < 3; ++k) {
    if (!kept[k]) edges_[ordered(coarse.corners[k], coarse.corners[(k + 1) % 3])].nodes.clear();
  }
  // A coarse triangle that will not come back (cut) must not leave its corners isolated.
  std::vector<std::uint64_t> removed_ids;
  for (mge::Node* node : nodes) removed_ids.push_back(node->id());
  membrane.removeElements(triangles, springs, nodes, /*remove_isolated_nodes=*/!intact);
  if (intact) {
    for (std::uint64_t id : removed_ids) node_of_.erase(id);  // exactly these went
  } else {
    rebuildIdMap();  // isolated corners may have gone too
  }
  coarse.refined = false;
  coarse.lattice.clear();
  springs_in_use_ -= springsPerTriangle(config_.levels);
  if (!intact || !cornersAlive(index)) {
    // Thesis §5.2.4: a cut inside a region to be coarsened deletes the coarse triangle.
    coarse.alive = false;
    return;
  }
  std::array<mge::Node*, 3> corner{};
  for (int k = 0; k < 3; ++k) corner[k] = nodeById(coarse.corners[k]);
  mge::Triangle& triangle = membrane.addTriangle(*corner[0], *corner[1], *corner[2]);
  for (int k = 0; k < 3; ++k) {
    mge::Spring* spring = springBetween(*corner[k], *corner[(k + 1) % 3]);
    if (spring == nullptr) {
      spring = &membrane.addSpring(*corner[k], *corner[(k + 1) % 3], coarse.stiffness[k], false, coarse.rest[k]);
    }
    membrane.linkEdgeSpring(triangle, *spring);
    ++edges_[ordered(coarse.corners[k], coarse.corners[(k + 1) % 3])].coarse_users;
  }
}

mge::Triangle* LocalRefinement::findCoarseTriangle(const CoarseTriangle& coarse) const {
  mge::Node* first = nodeById(coarse.corners[0]);
  if (first == nullptr) return nullptr;
  for (mge::Triangle* candidate : first->triangles()) {
    mge::ListAccess<mge::Node> c = candidate->nodes();
    if (c[0]->id() == coarse.corners[0] && c[1]->id() == coarse.corners[1] && c[2]->id() == coarse.corners[2]) {
      return candidate;
    }
  }
  return nullptr;
}

bool LocalRefinement::springBetweenCorners(const CoarseTriangle& coarse, mge::Spring& spring) const {
  mge::ListAccess<mge::Node> ends = spring.nodes();
  int corners = 0;
  for (std::uint64_t id : coarse.corners) corners += (ends[0]->id() == id || ends[1]->id() == id) ? 1 : 0;
  return corners == 2;
}

void LocalRefinement::coarsenRegion(int region) {
  auto found = regions_.find(region);
  if (found == regions_.end()) return;
  for (std::size_t index : found->second.triangles) {
    if (coarse_[index].refined) coarsenTriangle(index);
    coarse_[index].region = -1;
  }
  regions_.erase(found);
}

bool LocalRefinement::refineAt(const Eigen::Vector3d& point, std::uint64_t time) {
  if (config_.levels <= 0 || !point.allFinite()) return false;
  std::vector<std::pair<double, std::size_t>> wanted;
  for (std::size_t t = 0; t < coarse_.size(); ++t) {
    CoarseTriangle& coarse = coarse_[t];
    if (!coarse.alive || !cornersAlive(t)) continue;
    const double distance = (centroid(t) - point).norm();
    if (distance > config_.radius) continue;
    if (!coarse.refined && findCoarseTriangle(coarse) == nullptr) {
      coarse.alive = false;  // cut: never resurrect it
      continue;
    }
    if (coarse.refined) {
      regions_[coarse.region].time = time;  // still in use
    } else {
      wanted.push_back({distance, t});
    }
  }
  if (wanted.empty()) return false;
  std::sort(wanted.begin(), wanted.end());
  const std::size_t per = springsPerTriangle(config_.levels);
  bool changed = false;
  // LRU: coarsen the regions used longest ago until the new one fits (never one touched by this call).
  while (springs_in_use_ + wanted.size() * per > config_.element_budget) {
    int oldest = -1;
    for (const auto& [id, region] : regions_) {
      if (region.time < time && (oldest < 0 || region.time < regions_[oldest].time)) oldest = id;
    }
    if (oldest < 0) break;
    coarsenRegion(oldest);
    changed = true;
  }
  const std::size_t room =
      springs_in_use_ >= config_.element_budget ? 0 : (config_.element_budget - springs_in_use_) / per;
  if (wanted.size() > room) wanted.resize(room);  // the nearest first
  if (!wanted.empty()) {
    const int region = next_region_++;
    Region& record = regions_[region];
    record.time = time;
    for (const auto& [distance, t] : wanted) {
      refineTriangle(t);
      coarse_[t].region = region;
      record.triangles.push_back(t);
    }
    changed = true;
  }
  if (changed) recomputeMassesAndVirtuals();
  return changed;
}

bool LocalRefinement::coarsenAll() {
  if (regions_.empty()) return false;
  while (!regions_.empty()) coarsenRegion(regions_.begin()->first);
  recomputeMassesAndVirtuals();
  return true;
}

void LocalRefinement::onTopologyChanged() {
  rebuildIdMap();
  recomputeMassesAndVirtuals();
}

void LocalRefinement::recomputeMassesAndVirtuals() {
  mge::NodeArrays& arrays = membrane_->nodeArrays();
  auto massOf = [&](std::uint64_t id) -> double* {
    mge::Node* node = nodeById(id);
    return node == nullptr ? nullptr : &arrays.at<mge::kNodeMass>(node->slot());
  };
  for (const auto& [id, mass] : original_mass_) {
    if (double* m = massOf(id)) *m = mass;
  }
  // Lattice nodes start from zero; virtual ones hand their share to the ends of their coarse spring.
  virtual_slots_.clear();
  std::unordered_map<std::uint64_t, std::array<std::uint64_t, 2>> virtual_ends;
  std::unordered_map<std::uint64_t, double> virtual_w;
  const int S = segments_;
  for (const auto& [key, record] : edges_) {
    if (record.nodes.empty()) continue;
    const bool pinned = original_fixed_[key.first] && original_fixed_[key.second];
    // A cut may have taken an end of the coarse spring: then the lattice nodes are ordinary nodes.
    mge::Node* first = nodeById(key.first);
    mge::Node* second = nodeById(key.second);
    const bool is_virtual = record.coarse_users > 0 && first != nullptr && second != nullptr;
    for (std::size_t k = 0; k < record.nodes.size(); ++k) {
      mge::Node* node = nodeById(record.nodes[k]);
      if (node == nullptr) continue;
      arrays.at<mge::kNodeMass>(node->slot()) = 0.0;
      arrays.at<mge::kNodeFixed>(node->slot()) = (pinned || is_virtual) ? 1 : 0;
      if (is_virtual) {
        const double w = static_cast<double>(k + 1) / S;
        virtual_ends[record.nodes[k]] = {key.first, key.second};
        virtual_w[record.nodes[k]] = w;
        virtual_slots_.push_back({node->slot(), first->slot(), second->slot(), w});
      }
    }
  }
  for (const CoarseTriangle& coarse : coarse_) {
    if (!coarse.refined) continue;
    for (int k = 0; k < 3; ++k) {
      if (double* m = massOf(coarse.corners[k])) *m -= coarse.mass_share[k];
    }
    for (std::uint64_t id : coarse.lattice) {
      if (original_mass_.count(id) == 0) {
        if (double* m = massOf(id)) *m = 0.0;
      }
    }
  }
  // Density kept (eq. 5.19): each fine triangle carries mass/4ⁿ, a third on each corner.
  for (const CoarseTriangle& coarse : coarse_) {
    if (!coarse.refined) continue;
    const double third = coarse.mass / (3.0 * static_cast<double>(trianglesPerTriangle(config_.levels)));
    for (int j = 0; j <= S; ++j) {
      for (int i = 0; i + j <= S; ++i) {
        // Fine triangles at lattice point (i, j): 6 inside, 3 on an edge, 1 at a corner... counted exactly:
        int touching = 0;
        for (const auto& [di, dj] : {std::pair<int, int>{0, 0}, {-1, 0}, {0, -1}}) {
          const int a = i + di, b = j + dj;  // up triangle (a, b) has corners (a, b), (a+1, b), (a, b+1)
          if (a >= 0 && b >= 0 && a + b < S) ++touching;
        }
        for (const auto& [di, dj] : {std::pair<int, int>{-1, 0}, {-1, -1}, {0, -1}}) {
          const int a = i + di, b = j + dj;  // down triangle (a, b): (a+1, b), (a+1, b+1), (a, b+1)
          if (a >= 0 && b >= 0 && a + b + 1 < S) ++touching;
        }
        const double share = touching * third;
        const std::uint64_t id = coarse.lattice[latticeIndex(i, j)];
        auto ends = virtual_ends.find(id);
        if (ends != virtual_ends.end()) {
          const double w = virtual_w[id];
          if (double* m = massOf(ends->second[0])) *m += (1.0 - w) * share;
          if (double* m = massOf(ends->second[1])) *m += w * share;
        } else if (double* m = massOf(id)) {
          *m += share;
        }
      }
    }
  }
}

void LocalRefinement::updateVirtualNodes() {
  Eigen::Vector3d* x = membrane_->positions();
  Eigen::Vector3d* v = membrane_->velocities();
  for (const VirtualNode& node : virtual_slots_) {
    x[node.node] = (1.0 - node.w) * x[node.a] + node.w * x[node.b];
    v[node.node] = (1.0 - node.w) * v[node.a] + node.w * v[node.b];
  }
}

}  // namespace tissue
}  // namespace vrm_sim
