#include "vrm_sim/mge/membrane.h"

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

namespace vrm_sim {
namespace mge {

namespace {

template <typename T>
std::vector<T*> snapshot(ListAccess<T> list) {
  return std::vector<T*>(list.begin(), list.end());
}

template <typename T>
void sortUnique(std::vector<T*>& elements) {
  std::sort(elements.begin(), elements.end());
  elements.erase(std::unique(elements.begin(), elements.end()), elements.end());
}

// Sorted by element id, not address: the removal order decides the array slot order (last entry moves into the
// hole), and ids are deterministic where heap addresses are not.
bool byId(const Element* a, const Element* b) { return a->id() < b->id(); }

template <typename T>
void sortUniqueById(std::vector<T*>& elements) {
  std::sort(elements.begin(), elements.end(), byId);
  elements.erase(std::unique(elements.begin(), elements.end()), elements.end());
}

// Neighbour list of a const element without binding a ListAccess (which may add an empty label range).
std::vector<Element*> listOf(const Element& element, Label label) { return element.neighbours(label); }

}  // namespace

Membrane::Membrane(const MembraneOptions& options)
    : options_(options),
      owned_graph_(std::make_unique<Graph>()),
      graph_(owned_graph_.get()),
      node_arrays_(options.node_storage) {
  initialize();
}

Membrane::Membrane(Graph& graph, const MembraneOptions& options)
    : options_(options), graph_(&graph), node_arrays_(options.node_storage) {
  initialize();
}

Membrane::~Membrane() { destroyAll(); }

void Membrane::initialize() {
  transform_ = &graph_->create<Transform>();
  tissue_ = &graph_->create<Tissue>();
  graph_->insertEdge(*transform_, *tissue_, labels::kSceneChild);
  node_arrays_.setRelocationListener([this](std::size_t slot) { onNodeRelocated(slot); });
}

void Membrane::destroyAll() {
  node_arrays_.setRelocationListener(nullptr);
  // An owned graph dies with the membrane; the managers (declared after it) disconnect their elements first.
  if (owned_graph_) return;
  std::vector<Triangle*> triangles = snapshot(tissue_->triangles());
  std::vector<Spring*> springs = snapshot(tissue_->springs());
  std::vector<Node*> nodes = snapshot(tissue_->nodes());
  // Hub first: then every later destroy only touches short lists.
  graph_->destroy(*tissue_);
  graph_->destroy(*transform_);
  for (Triangle* triangle : triangles) graph_->destroy(*triangle);
  for (Spring* spring : springs) graph_->destroy(*spring);
  for (Node* node : nodes) graph_->destroy(*node);
}

void Membrane::reserve(std::size_t nodes, std::size_t springs, std::size_t triangles) {
  node_arrays_.reserve(nodes);
  spring_arrays_.reserve(springs);
  triangle_arrays_.reserve(triangles);
}

void Membrane::requireOwn(const Element& element, Label tissue_label) const {
  const Label back = referenceLabel(tissue_label);
  if (!graph_->contains(element) || element.neighbourCount(back) != 1 || element.neighbour(back, 0) != tissue_) {
    throw std::invalid_argument("element does not belong to this membrane");
  }
}

Node& Membrane::addNode(const Eigen::Vector3d& position, double mass, bool fixed) {
  Node& node = graph_->create<Node>();
  try {
    node.arrayConnector().connect(node_arrays_, &node, position, Eigen::Vector3d::Zero(), mass,
                                  static_cast<std::uint8_t>(fixed ? 1 : 0));
    graph_->insertEdge(*tissue_, node, labels::kNodeList);
  } catch (...) {
    graph_->destroy(node);
    throw;
  }
  return node;
}

Spring& Membrane::addSpring(Node& first, Node& second, double stiffness, bool bending,
                            std::optional<double> rest_length) {
  requireOwn(first, labels::kNodeList);
  requireOwn(second, labels::kNodeList);
  if (&first == &second) throw std::invalid_argument("a spring needs two different nodes");
  Spring& spring = graph_->create<Spring>(bending);
  try {
    const double rest = rest_length.value_or((first.position() - second.position()).norm());
    spring.arrayConnector().connect(spring_arrays_, &spring, {first.slot(), second.slot()}, rest, stiffness);
    graph_->insertEdge(spring, first, labels::kSpringNodes);
    graph_->insertEdge(spring, second, labels::kSpringNodes);
    graph_->insertEdge(*tissue_, spring, labels::kSpringList);
  } catch (...) {
    graph_->destroy(spring);
    throw;
  }
  return spring;
}

Triangle& Membrane::addTriangle(Node& first, Node& second, Node& third) {
  requireOwn(first, labels::kNodeList);
  requireOwn(second, labels::kNodeList);
  requireOwn(third, labels::kNodeList);
  if (&first == &second || &second == &third || &first == &third) {
    throw std::invalid_argument("a triangle needs three different nodes");
  }
  Triangle& triangle = graph_->create<Triangle>();
  try {
    triangle.arrayConnector().connect(triangle_arrays_, &triangle, {first.slot(), second.slot(), third.slot()});
    for (Node* corner : {&first, &second, &third}) graph_->insertEdge(triangle, *corner, labels::kTriangleNodes);
    graph_->insertEdge(*tissue_, triangle, labels::kTriangleList);
  } catch (...) {
    graph_->destroy(triangle);
    throw;
  }
  return triangle;
}

void Membrane::linkEdgeSpring(Triangle& triangle, Spring& spring) {
  requireOwn(triangle, labels::kTriangleList);
  requireOwn(spring, labels::kSpringList);
  graph_->insertEdge(triangle, spring, labels::kTriangleEdgeSprings);
}

void Membrane::linkBendingSpring(Triangle& triangle, Spring& spring) {
  requireOwn(triangle, labels::kTriangleList);
  requireOwn(spring, labels::kSpringList);
  graph_->insertEdge(triangle, spring, labels::kTriangleBendingSprings);
}

void Membrane::onNodeRelocated(std::size_t slot) {
  // The last node moved into `slot`; its springs and triangles are its reference-edge neighbours (§3.2), so fixing
  // their node-slot entries needs no search over the arrays.
  Node& node = nodeAtSlot(slot);
  const auto new_slot = static_cast<std::uint32_t>(slot);
  for (Spring* spring : node.springs()) {
    std::array<std::uint32_t, 2>& ends = spring_arrays_.at<kSpringNodeSlots>(spring->slot());
    ListAccess<Node> spring_nodes = spring->nodes();
    for (std::size_t k = 0; k < spring_nodes.size(); ++k) {
      if (spring_nodes[k] == &node) ends[k] = new_slot;
    }
  }
  for (Triangle* triangle : node.triangles()) {
    std::array<std::uint32_t, 3>& corners = triangle_arrays_.at(triangle->slot());
    ListAccess<Node> triangle_nodes = triangle->nodes();
    for (std::size_t k = 0; k < triangle_nodes.size(); ++k) {
      if (triangle_nodes[k] == &node) corners[k] = new_slot;
    }
  }
}

void Membrane::removeSpring(Spring& spring) {
  requireOwn(spring, labels::kSpringList);
  graph_->destroy(spring);
}

void Membrane::removeTriangle(Triangle& triangle, const CutOptions& options) {
  requireOwn(triangle, labels::kTriangleList);
  std::vector<Spring*> bending = snapshot(triangle.bendingSprings());
  std::vector<Spring*> edges = snapshot(triangle.edgeSprings());
  std::vector<Node*> corners = snapshot(triangle.nodes());
  sortUnique(bending);
  sortUnique(edges);
  sortUnique(corners);
  graph_->destroy(triangle);
  // A bending spring models the angle between two triangles; without one of them it has no meaning.
  for (Spring* spring : bending) graph_->destroy(*spring);
  if (options.remove_orphan_springs) {
    for (Spring* spring : edges) {
      if (spring->neighbourCount(referenceLabel(labels::kTriangleEdgeSprings)) == 0) graph_->destroy(*spring);
    }
  }
  if (options.remove_orphan_nodes) {
    for (Node* node : corners) {
      if (node->springs().empty() && node->triangles().empty()) graph_->destroy(*node);
    }
  }
}

void Membrane::removeNode(Node& node) {
  requireOwn(node, labels::kNodeList);
  std::vector<Triangle*> triangles = snapshot(node.triangles());
  sortUnique(triangles);
  for (Triangle* triangle : triangles) removeTriangle(*triangle);
  // Re-read: removeTriangle may already have removed some of the node's springs.
  std::vector<Spring*> springs = snapshot(node.springs());
  sortUnique(springs);
  for (Spring* spring : springs) graph_->destroy(*spring);
  graph_->destroy(node);
}

RemovalSummary Membrane::removeElements(const std::vector<Triangle*>& triangles_in,
                                        const std::vector<Spring*>& springs_in, const std::vector<Node*>& nodes_in,
                                        bool remove_isolated_nodes) {
  for (Triangle* triangle : triangles_in) requireOwn(*triangle, labels::kTriangleList);
  for (Spring* spring : springs_in) requireOwn(*spring, labels::kSpringList);
  for (Node* node : nodes_in) requireOwn(*node, labels::kNodeList);

  std::vector<Node*> nodes = nodes_in;
  sortUniqueById(nodes);
  std::vector<Triangle*> triangles = triangles_in;
  for (Node* node : nodes) {
    for (Triangle* triangle : node->triangles()) triangles.push_back(triangle);
  }
  sortUniqueById(triangles);
  std::vector<Spring*> springs = springs_in;
  std::vector<Node*> candidates;  // may become isolated
  for (Node* node : nodes) {
    for (Spring* spring : node->springs()) springs.push_back(spring);
  }
  for (Triangle* triangle : triangles) {
    for (Spring* spring : triangle->bendingSprings()) springs.push_back(spring);
    for (Node* corner : triangle->nodes()) candidates.push_back(corner);
  }
  // Edge springs orphaned by this batch: every triangle that uses them is removed too.
  const Label edge_users = referenceLabel(labels::kTriangleEdgeSprings);
  for (Triangle* triangle : triangles) {
    for (Spring* spring : triangle->edgeSprings()) {
      bool orphaned = true;
      for (std::size_t k = 0; k < spring->neighbourCount(edge_users) && orphaned; ++k) {
        orphaned = std::binary_search(triangles.begin(), triangles.end(),
                                      static_cast<Triangle*>(spring->neighbour(edge_users, k)), byId);
      }
      if (orphaned) springs.push_back(spring);
    }
  }
  sortUniqueById(springs);
  for (Spring* spring : springs) {
    for (Node* end : spring->nodes()) candidates.push_back(end);
  }
  sortUniqueById(candidates);

  RemovalSummary summary;
  summary.triangles = triangles.size();
  summary.springs = springs.size();
  for (Triangle* triangle : triangles) graph_->destroy(*triangle);
  for (Spring* spring : springs) graph_->destroy(*spring);
  const Label spring_users = referenceLabel(labels::kSpringNodes);
  const Label triangle_users = referenceLabel(labels::kTriangleNodes);
  if (remove_isolated_nodes) {
    for (Node* node : candidates) {
      if (node->neighbourCount(spring_users) == 0 && node->neighbourCount(triangle_users) == 0) nodes.push_back(node);
    }
    sortUniqueById(nodes);
  }
  summary.nodes = nodes.size();
  for (Node* node : nodes) {
    summary.mass += node->mass();
    graph_->destroy(*node);
  }
  return summary;
}

InvariantReport Membrane::checkConsistency() const {
  InvariantReport report = graph_->checkInvariants();
  if (!report.ok()) return report;  // the checks below navigate the graph and need it intact
  auto fail = [&report](const std::string& what) { report.errors.push_back(what); };

  const std::vector<Element*> nodes = listOf(*tissue_, labels::kNodeList);
  const std::vector<Element*> springs = listOf(*tissue_, labels::kSpringList);
  const std::vector<Element*> triangles = listOf(*tissue_, labels::kTriangleList);
  if (nodes.size() != node_arrays_.size()) fail("node list and node arrays differ in size");
  if (springs.size() != spring_arrays_.size()) fail("spring list and spring arrays differ in size");
  if (triangles.size() != triangle_arrays_.size()) fail("triangle list and triangle arrays differ in size");

  // Each listed element exactly once, owning the array slot its connector claims. With equal sizes this makes
  // list ↔ array slots a bijection.
  auto check_slots = [&fail](const std::vector<Element*>& listed, const char* kind, auto& arrays, auto connector_of) {
    std::unordered_set<const Element*> seen;
    for (const Element* element : listed) {
      if (!seen.insert(element).second) fail(std::string(kind) + " listed twice in the tissue");
      const auto* connector = connector_of(element);
      if (connector == nullptr) {
        fail(std::string(kind) + " of the wrong type in the tissue list");
        continue;
      }
      if (!connector->connected() || connector->manager() != &arrays) {
        fail(std::string(kind) + " not connected to the membrane arrays");
      } else if (connector->slot() >= arrays.size() || arrays.ownerAt(connector->slot()) != element) {
        fail(std::string(kind) + " slot owned by another element");
      }
    }
  };
  check_slots(nodes, "node", node_arrays_, [](const Element* e) -> const NodeArrays::Connector* {
    const auto* node = dynamic_cast<const Node*>(e);
    return node ? &node->arrayConnector() : nullptr;
  });
  check_slots(springs, "spring", spring_arrays_, [](const Element* e) -> const SpringArrays::Connector* {
    const auto* spring = dynamic_cast<const Spring*>(e);
    return spring ? &spring->arrayConnector() : nullptr;
  });
  check_slots(triangles, "triangle", triangle_arrays_, [](const Element* e) -> const TriangleArrays::Connector* {
    const auto* triangle = dynamic_cast<const Triangle*>(e);
    return triangle ? &triangle->arrayConnector() : nullptr;
  });
  if (!report.ok()) return report;

  const std::unordered_set<const Element*> node_set(nodes.begin(), nodes.end());
  auto check_corners = [&](const Element& element, Label label, std::size_t expected, const std::uint32_t* slots,
                           const char* kind) {
    const std::vector<Element*> corners = listOf(element, label);
    if (corners.size() != expected) {
      fail(std::string(kind) + " with " + std::to_string(corners.size()) + " nodes");
      return;
    }
    for (std::size_t k = 0; k < expected; ++k) {
      if (node_set.count(corners[k]) == 0) {
        fail(std::string(kind) + " uses a node of another membrane");
      } else if (static_cast<const Node*>(corners[k])->slot() != slots[k]) {
        fail(std::string(kind) + " node-slot array entry is stale");
      }
    }
  };
  for (const Element* element : springs) {
    const auto* spring = static_cast<const Spring*>(element);
    check_corners(*spring, labels::kSpringNodes, 2, spring_arrays_.at<kSpringNodeSlots>(spring->slot()).data(),
                  "spring");
  }
  for (const Element* element : triangles) {
    const auto* triangle = static_cast<const Triangle*>(element);
    check_corners(*triangle, labels::kTriangleNodes, 3, triangle_arrays_.at(triangle->slot()).data(), "triangle");
    for (Label label : {labels::kTriangleEdgeSprings, labels::kTriangleBendingSprings}) {
      for (const Element* spring : listOf(*triangle, label)) {
        if (dynamic_cast<const Spring*>(spring) == nullptr) fail("triangle links a non-spring as spring");
      }
    }
  }
  if (listOf(*transform_, labels::kSceneChild) != std::vector<Element*>{tissue_}) {
    fail("membrane transform does not have the tissue as its only child");
  }
  return report;
}

// ---------------------------------------------------------------------------------------------------------------------
// buildMembrane

namespace {

std::uint64_t edgeKey(std::uint32_t a, std::uint32_t b) {
  return a < b ? (std::uint64_t{a} << 32) | b : (std::uint64_t{b} << 32) | a;
}

std::uint32_t oppositeCorner(const std::array<std::uint32_t, 3>& triangle, std::uint32_t a, std::uint32_t b) {
  for (std::uint32_t corner : triangle) {
    if (corner != a && corner != b) return corner;
  }
  return triangle[0];  // unreachable for validated triangles
}

void validateMesh(const TriangleMesh& mesh) {
  const std::size_t count = mesh.vertices.size();
  if (count > 0xffffffffu) throw std::invalid_argument("mesh too large for 32-bit node slots");
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& triangle = mesh.triangles[t];
    for (std::uint32_t corner : triangle) {
      if (corner >= count) throw std::invalid_argument("triangle " + std::to_string(t) + " has a vertex out of range");
    }
    if (triangle[0] == triangle[1] || triangle[1] == triangle[2] || triangle[0] == triangle[2]) {
      throw std::invalid_argument("triangle " + std::to_string(t) + " repeats a vertex");
    }
  }
  for (std::uint32_t fixed : mesh.fixed_vertices) {
    if (fixed >= count) throw std::invalid_argument("fixed vertex index out of range");
  }
}

std::vector<double> lumpedMasses(const TriangleMesh& mesh, double total_mass) {
  std::vector<double> masses(mesh.vertices.size(), 0.0);
  double total_area = 0.0;
  for (const auto& triangle : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices[triangle[0]];
    const double area = 0.5 * (mesh.vertices[triangle[1]] - a).cross(mesh.vertices[triangle[2]] - a).norm();
    for (std::uint32_t corner : triangle) masses[corner] += area / 3.0;
    total_area += area;
  }
  if (total_area > 0.0) {
    for (double& mass : masses) mass *= total_mass / total_area;
  } else if (!masses.empty()) {
    std::fill(masses.begin(), masses.end(), total_mass / static_cast<double>(masses.size()));
  }
  return masses;
}

struct EdgeInfo {
  Spring* spring = nullptr;
  Spring* bending = nullptr;
  std::uint32_t triangles[2] = {0, 0};
  std::uint32_t triangle_count = 0;
};

void fillMembrane(Membrane& membrane, const TriangleMesh& mesh, const MembraneOptions& options) {
  validateMesh(mesh);
  const std::vector<double> masses = lumpedMasses(mesh, options.total_mass);
  std::vector<bool> fixed(mesh.vertices.size(), false);
  for (std::uint32_t index : mesh.fixed_vertices) fixed[index] = true;

  membrane.reserve(mesh.vertices.size(), 3 * mesh.triangles.size() / 2 + mesh.vertices.size(), mesh.triangles.size());
  std::vector<Node*> nodes;
  nodes.reserve(mesh.vertices.size());
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    nodes.push_back(&membrane.addNode(mesh.vertices[v], masses[v], fixed[v]));
  }

  // One spring per unique edge, created in order of first appearance (deterministic slot order).
  std::unordered_map<std::uint64_t, EdgeInfo> edges;
  edges.reserve(3 * mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& triangle = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = triangle[k];
      const std::uint32_t b = triangle[(k + 1) % 3];
      EdgeInfo& edge = edges[edgeKey(a, b)];
      if (edge.spring == nullptr) edge.spring = &membrane.addSpring(*nodes[a], *nodes[b], options.stretch_stiffness);
      if (edge.triangle_count < 2) edge.triangles[edge.triangle_count] = static_cast<std::uint32_t>(t);
      ++edge.triangle_count;
    }
  }

  if (options.bending_springs) {
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      const auto& triangle = mesh.triangles[t];
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = triangle[k];
        const std::uint32_t b = triangle[(k + 1) % 3];
        EdgeInfo& edge = edges[edgeKey(a, b)];
        // Only manifold interior edges, each once (from its first triangle).
        if (edge.triangle_count != 2 || edge.triangles[0] != t) continue;
        const std::uint32_t c = oppositeCorner(triangle, a, b);
        const std::uint32_t d = oppositeCorner(mesh.triangles[edge.triangles[1]], a, b);
        if (c == d || edges.count(edgeKey(c, d)) != 0) continue;  // already held by a stretch spring
        edge.bending = &membrane.addSpring(*nodes[c], *nodes[d], options.bending_stiffness, /*bending=*/true);
      }
    }
  }

  for (const auto& corners : mesh.triangles) {
    Triangle& triangle = membrane.addTriangle(*nodes[corners[0]], *nodes[corners[1]], *nodes[corners[2]]);
    for (int k = 0; k < 3; ++k) {
      const EdgeInfo& edge = edges[edgeKey(corners[k], corners[(k + 1) % 3])];
      membrane.linkEdgeSpring(triangle, *edge.spring);
    }
    for (int k = 0; k < 3; ++k) {
      const EdgeInfo& edge = edges[edgeKey(corners[k], corners[(k + 1) % 3])];
      if (edge.bending != nullptr) membrane.linkBendingSpring(triangle, *edge.bending);
    }
  }
}

}  // namespace

std::unique_ptr<Membrane> buildMembrane(const TriangleMesh& mesh, const MembraneOptions& options) {
  auto membrane = std::make_unique<Membrane>(options);
  fillMembrane(*membrane, mesh, options);
  return membrane;
}

std::unique_ptr<Membrane> buildMembrane(Graph& graph, const TriangleMesh& mesh, const MembraneOptions& options) {
  auto membrane = std::make_unique<Membrane>(graph, options);
  fillMembrane(*membrane, mesh, options);
  return membrane;
}

}  // namespace mge
}  // namespace vrm_sim
