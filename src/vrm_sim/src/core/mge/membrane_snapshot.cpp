// Membrane::takeSnapshot / Membrane::restore (issue 39 §1): the tissue part of a checkpoint. See MembraneSnapshot in
// membrane.h for what is saved and why it reproduces every slot, id and neighbour list.

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <vector>

#include "vrm_sim/mge/membrane.h"

namespace vrm_sim {
namespace mge {

namespace {

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("membrane snapshot: " + what); }

template <typename T>
void resizeTo(std::vector<T>& column, std::size_t size) {
  column.resize(size);  // keeps the capacity of an earlier snapshot
}

// Slots in ascending order of their element ids: the order every list that grows by creation has.
std::vector<std::uint32_t> slotsById(const std::vector<std::uint64_t>& ids) {
  std::vector<std::uint32_t> slots(ids.size());
  std::iota(slots.begin(), slots.end(), 0u);
  std::sort(slots.begin(), slots.end(), [&ids](std::uint32_t a, std::uint32_t b) { return ids[a] < ids[b]; });
  return slots;
}

bool finite(const Eigen::Vector3d& value) { return value.allFinite(); }

void validate(const MembraneSnapshot& s, std::uint64_t transform_id, std::uint64_t tissue_id,
              const std::unordered_set<std::uint64_t>& foreign_ids, std::uint64_t foreign_max_id) {
  const std::size_t nodes = s.nodeCount(), springs = s.springCount(), triangles = s.triangleCount();
  if (s.positions.size() != nodes || s.velocities.size() != nodes || s.masses.size() != nodes ||
      s.fixed.size() != nodes) {
    fail("the node columns differ in length");
  }
  if (s.spring_ends.size() != springs || s.rest_lengths.size() != springs || s.stiffnesses.size() != springs ||
      s.bending.size() != springs) {
    fail("the spring columns differ in length");
  }
  if (s.triangle_corners.size() != triangles || s.triangle_edge_springs.size() != triangles ||
      s.triangle_link_offsets.size() != triangles + 1) {
    fail("the triangle columns differ in length");
  }
  if (nodes > 0xffffffffu || springs > 0xffffffffu || triangles > 0xffffffffu) fail("more elements than 32-bit slots");
  if (s.transform_id != transform_id || s.tissue_id != tissue_id) {
    fail("taken from another membrane (transform/tissue ids " + std::to_string(s.transform_id) + "/" +
         std::to_string(s.tissue_id) + ", this one has " + std::to_string(transform_id) + "/" +
         std::to_string(tissue_id) + ")");
  }
  for (std::size_t i = 0; i < nodes; ++i) {
    if (!finite(s.positions[i]) || !finite(s.velocities[i])) fail("node slot " + std::to_string(i) + " is not finite");
    if (!(std::isfinite(s.masses[i]) && s.masses[i] >= 0.0)) {
      fail("node slot " + std::to_string(i) + " has mass " + std::to_string(s.masses[i]));
    }
    if (s.fixed[i] > 1) fail("node slot " + std::to_string(i) + " has a fixed flag other than 0 or 1");
  }
  for (std::size_t k = 0; k < springs; ++k) {
    const auto& ends = s.spring_ends[k];
    if (ends[0] >= nodes || ends[1] >= nodes || ends[0] == ends[1]) {
      fail("spring slot " + std::to_string(k) + " has ends " + std::to_string(ends[0]) + ", " +
           std::to_string(ends[1]) + " (" + std::to_string(nodes) + " nodes)");
    }
    if (!std::isfinite(s.rest_lengths[k]) || !std::isfinite(s.stiffnesses[k]) || s.bending[k] > 1) {
      fail("spring slot " + std::to_string(k) + " has a non-finite rest length or stiffness, or a bad bending flag");
    }
  }
  if (s.triangle_link_offsets.front() != 0 || s.triangle_link_offsets.back() != s.triangle_links.size()) {
    fail("the triangle link offsets do not span the links");
  }
  for (std::size_t t = 0; t < triangles; ++t) {
    const auto& c = s.triangle_corners[t];
    if (c[0] >= nodes || c[1] >= nodes || c[2] >= nodes || c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) {
      fail("triangle slot " + std::to_string(t) + " has corners out of range or repeated");
    }
    const std::uint32_t begin = s.triangle_link_offsets[t], end = s.triangle_link_offsets[t + 1];
    if (end < begin || end - begin < s.triangle_edge_springs[t]) {
      fail("triangle slot " + std::to_string(t) + " has inconsistent link offsets");
    }
    for (std::uint32_t l = begin; l < end; ++l) {
      if (s.triangle_links[l] >= springs) fail("triangle slot " + std::to_string(t) + " links a spring out of range");
    }
  }
  // Ids: non-zero, distinct, below next_id, and not taken by an element outside the membrane's nodes, springs and
  // triangles (its transform and tissue, or other objects of a shared graph).
  std::unordered_set<std::uint64_t> seen;
  seen.reserve(nodes + springs + triangles);
  auto check_ids = [&](const std::vector<std::uint64_t>& ids, const char* kind) {
    for (std::size_t i = 0; i < ids.size(); ++i) {
      const std::uint64_t id = ids[i];
      if (id == 0 || id >= s.next_id) {
        fail(std::string(kind) + " slot " + std::to_string(i) + " has id " + std::to_string(id) + ", next id is " +
             std::to_string(s.next_id));
      }
      if (foreign_ids.count(id) != 0 || !seen.insert(id).second) {
        fail(std::string(kind) + " slot " + std::to_string(i) + " repeats id " + std::to_string(id));
      }
    }
  };
  check_ids(s.node_ids, "node");
  check_ids(s.spring_ids, "spring");
  check_ids(s.triangle_ids, "triangle");
  if (foreign_max_id >= s.next_id) {
    fail("next id " + std::to_string(s.next_id) + " is not above the graph's element id " +
         std::to_string(foreign_max_id));
  }
}

}  // namespace

void Membrane::takeSnapshot(MembraneSnapshot& s) const {
  s.transform_id = transform_->id();
  s.tissue_id = tissue_->id();
  s.next_id = graph_->nextId();

  const std::size_t nodes = node_arrays_.size();
  resizeTo(s.node_ids, nodes);
  for (std::size_t i = 0; i < nodes; ++i) s.node_ids[i] = node_arrays_.ownerAt(i)->id();
  const Eigen::Vector3d* positions = node_arrays_.data<kNodePosition>();
  const Eigen::Vector3d* velocities = node_arrays_.data<kNodeVelocity>();
  s.positions.assign(positions, positions + nodes);
  s.velocities.assign(velocities, velocities + nodes);
  s.masses.assign(node_arrays_.data<kNodeMass>(), node_arrays_.data<kNodeMass>() + nodes);
  s.fixed.assign(node_arrays_.data<kNodeFixed>(), node_arrays_.data<kNodeFixed>() + nodes);

  const std::size_t springs = spring_arrays_.size();
  resizeTo(s.spring_ids, springs);
  resizeTo(s.bending, springs);
  for (std::size_t k = 0; k < springs; ++k) {
    const auto& spring = static_cast<const Spring&>(*spring_arrays_.ownerAt(k));
    s.spring_ids[k] = spring.id();
    s.bending[k] = spring.bending() ? 1 : 0;
  }
  s.spring_ends.assign(spring_arrays_.data<kSpringNodeSlots>(), spring_arrays_.data<kSpringNodeSlots>() + springs);
  s.rest_lengths.assign(spring_arrays_.data<kSpringRestLength>(), spring_arrays_.data<kSpringRestLength>() + springs);
  s.stiffnesses.assign(spring_arrays_.data<kSpringStiffness>(), spring_arrays_.data<kSpringStiffness>() + springs);

  const std::size_t triangles = triangle_arrays_.size();
  resizeTo(s.triangle_ids, triangles);
  resizeTo(s.triangle_edge_springs, triangles);
  resizeTo(s.triangle_link_offsets, triangles + 1);
  s.triangle_corners.assign(triangle_arrays_.data(), triangle_arrays_.data() + triangles);
  s.triangle_links.clear();
  s.triangle_link_offsets[0] = 0;
  for (std::size_t t = 0; t < triangles; ++t) {
    const Element& triangle = *triangle_arrays_.ownerAt(t);
    s.triangle_ids[t] = triangle.id();
    const std::size_t edges = triangle.neighbourCount(labels::kTriangleEdgeSprings);
    const std::size_t bending = triangle.neighbourCount(labels::kTriangleBendingSprings);
    s.triangle_edge_springs[t] = static_cast<std::uint8_t>(edges);
    for (std::size_t e = 0; e < edges; ++e) {
      s.triangle_links.push_back(
          static_cast<const Spring*>(triangle.neighbour(labels::kTriangleEdgeSprings, e))->slot());
    }
    for (std::size_t b = 0; b < bending; ++b) {
      s.triangle_links.push_back(
          static_cast<const Spring*>(triangle.neighbour(labels::kTriangleBendingSprings, b))->slot());
    }
    s.triangle_link_offsets[t + 1] = static_cast<std::uint32_t>(s.triangle_links.size());
  }
}

void Membrane::restore(const MembraneSnapshot& s) {
  // Everything is checked before the first element goes, so a bad snapshot leaves the membrane as it was.
  std::unordered_set<const Element*> own;
  own.reserve(nodeCount() + springCount() + triangleCount());
  for (std::size_t i = 0; i < node_arrays_.size(); ++i) own.insert(node_arrays_.ownerAt(i));
  for (std::size_t i = 0; i < spring_arrays_.size(); ++i) own.insert(spring_arrays_.ownerAt(i));
  for (std::size_t i = 0; i < triangle_arrays_.size(); ++i) own.insert(triangle_arrays_.ownerAt(i));
  std::unordered_set<std::uint64_t> foreign_ids;
  std::uint64_t foreign_max_id = 0;
  for (const Element* element : graph_->elements()) {
    if (own.count(element) != 0) continue;
    foreign_ids.insert(element->id());
    foreign_max_id = std::max(foreign_max_id, element->id());
  }
  validate(s, transform_->id(), tissue_->id(), foreign_ids, foreign_max_id);

  // Out with the old elements: the tissue hub first (its lists are long; every later destroy then only touches short
  // ones), then triangles, springs and nodes. The tissue element comes back with its id below.
  const std::uint64_t tissue_id = tissue_->id();
  std::vector<Element*> old_elements;
  old_elements.reserve(own.size());
  for (std::size_t i = triangle_arrays_.size(); i-- > 0;) old_elements.push_back(triangle_arrays_.ownerAt(i));
  for (std::size_t i = spring_arrays_.size(); i-- > 0;) old_elements.push_back(spring_arrays_.ownerAt(i));
  for (std::size_t i = node_arrays_.size(); i-- > 0;) old_elements.push_back(node_arrays_.ownerAt(i));
  node_arrays_.setRelocationListener(nullptr);  // no spring or triangle is left to fix while the nodes go
  graph_->destroy(*tissue_);
  tissue_ = nullptr;
  for (Element* element : old_elements) graph_->destroy(*element);

  // In with the snapshot's: created and connected in slot order (a connection appends, so the slots come out as
  // saved), then the edges inserted in id order, which is the order creation gave every list that grows.
  tissue_ = &graph_->createWithId<Tissue>(tissue_id);
  graph_->insertEdge(*transform_, *tissue_, labels::kSceneChild);
  const std::size_t nodes = s.nodeCount(), springs = s.springCount(), triangles = s.triangleCount();
  node_arrays_.reserve(nodes);
  spring_arrays_.reserve(springs);
  triangle_arrays_.reserve(triangles);
  std::vector<Node*> node_at(nodes);
  std::vector<Spring*> spring_at(springs);
  std::vector<Triangle*> triangle_at(triangles);
  for (std::size_t i = 0; i < nodes; ++i) {
    Node& node = graph_->createWithId<Node>(s.node_ids[i]);
    node.arrayConnector().connect(node_arrays_, &node, s.positions[i], s.velocities[i], s.masses[i], s.fixed[i]);
    node_at[i] = &node;
  }
  for (std::size_t k = 0; k < springs; ++k) {
    Spring& spring = graph_->createWithId<Spring>(s.spring_ids[k], s.bending[k] != 0);
    spring.arrayConnector().connect(spring_arrays_, &spring, s.spring_ends[k], s.rest_lengths[k], s.stiffnesses[k]);
    spring_at[k] = &spring;
  }
  for (std::size_t t = 0; t < triangles; ++t) {
    Triangle& triangle = graph_->createWithId<Triangle>(s.triangle_ids[t]);
    triangle.arrayConnector().connect(triangle_arrays_, &triangle, s.triangle_corners[t]);
    triangle_at[t] = &triangle;
  }
  for (std::uint32_t i : slotsById(s.node_ids)) graph_->insertEdge(*tissue_, *node_at[i], labels::kNodeList);
  for (std::uint32_t k : slotsById(s.spring_ids)) {
    Spring& spring = *spring_at[k];
    graph_->insertEdge(spring, *node_at[s.spring_ends[k][0]], labels::kSpringNodes);
    graph_->insertEdge(spring, *node_at[s.spring_ends[k][1]], labels::kSpringNodes);
    graph_->insertEdge(*tissue_, spring, labels::kSpringList);
  }
  for (std::uint32_t t : slotsById(s.triangle_ids)) {
    Triangle& triangle = *triangle_at[t];
    for (std::uint32_t corner : s.triangle_corners[t])
      graph_->insertEdge(triangle, *node_at[corner], labels::kTriangleNodes);
    graph_->insertEdge(*tissue_, triangle, labels::kTriangleList);
    const std::uint32_t begin = s.triangle_link_offsets[t], end = s.triangle_link_offsets[t + 1];
    for (std::uint32_t l = begin; l < end; ++l) {
      const Label label =
          l - begin < s.triangle_edge_springs[t] ? labels::kTriangleEdgeSprings : labels::kTriangleBendingSprings;
      graph_->insertEdge(triangle, *spring_at[s.triangle_links[l]], label);
    }
  }
  graph_->setNextId(s.next_id);
  node_arrays_.setRelocationListener([this](std::size_t slot) { onNodeRelocated(slot); });
}

}  // namespace mge
}  // namespace vrm_sim
