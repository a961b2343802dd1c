// NeighbourSlots (issue 15): the derived CSR of array slots must equal what ListAccess and the ArrayConnectors say,
// after every kind of change the MGE allows (edges inserted and removed, elements destroyed so that the arrays move
// their last entry), and must not rebuild when nothing changed.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "vrm_sim/mge/elements.h"
#include "vrm_sim/mge/graph.h"
#include "vrm_sim/mge/labels.h"
#include "vrm_sim/mge/list_access.h"
#include "vrm_sim/mge/neighbour_slots.h"

namespace vrm_sim {
namespace mge {
namespace {

constexpr Label kLink = labels::kFirstUserLabel;

Node& addNode(Graph& graph, NodeArrays& arrays, Tissue& tissue, double x) {
  Node& node = graph.create<Node>();
  node.arrayConnector().connect(arrays, &node, Eigen::Vector3d(x, 0, 0), Eigen::Vector3d::Zero(), 1.0, 0);
  graph.insertEdge(tissue, node, labels::kNodeList);
  return node;
}

// The reference: the same walk, slot by slot, through ListAccess and Node::slot().
void expectMatchesGraph(const NeighbourSlots<Node>& view, Tissue& tissue) {
  const ListAccess<Node> nodes = tissue.nodes();
  ASSERT_EQ(view.size(), nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    ASSERT_EQ(view.slot(k), nodes[k]->slot()) << "node " << k;
    std::vector<std::uint32_t> expected;
    for (Node* neighbour : ListAccess<Node>(*nodes[k], kLink)) expected.push_back(neighbour->slot());
    for (Node* neighbour : ListAccess<Node>(*nodes[k], -kLink)) expected.push_back(neighbour->slot());
    const auto range = view.neighbours(k);
    ASSERT_EQ(std::vector<std::uint32_t>(range.begin(), range.end()), expected) << "node " << k;
  }
}

TEST(MgeNeighbourSlots, FollowsEdgeChangesAndRelocationsAndSkipsUnchangedRefreshes) {
  std::mt19937 rng(15);
  Graph graph;
  NodeArrays arrays;
  Tissue& tissue = graph.create<Tissue>();
  std::vector<Node*> nodes;
  for (int i = 0; i < 40; ++i) nodes.push_back(&addNode(graph, arrays, tissue, i));
  auto pick = [&rng](std::size_t count) { return std::uniform_int_distribution<std::size_t>(0, count - 1)(rng); };
  for (int i = 0; i < 120; ++i) graph.insertEdge(*nodes[pick(nodes.size())], *nodes[pick(nodes.size())], kLink);

  NeighbourSlots<Node> view(tissue, labels::kNodeList, {kLink, -kLink});
  EXPECT_TRUE(view.refresh(graph, arrays));
  expectMatchesGraph(view, tissue);
  EXPECT_FALSE(view.refresh(graph, arrays));  // nothing changed: no rebuild

  int rebuilds = 0;
  for (int op = 0; op < 600; ++op) {
    const int kind = std::uniform_int_distribution<int>(0, 9)(rng);
    if (kind < 2 && nodes.size() > 5) {
      // Destroying a node that is not the last in the arrays moves the last one into its slot.
      const std::size_t index = pick(nodes.size());
      graph.destroy(*nodes[index]);
      nodes.erase(nodes.begin() + static_cast<std::ptrdiff_t>(index));
    } else if (kind < 3) {
      nodes.push_back(&addNode(graph, arrays, tissue, op));
    } else if (kind < 7) {
      graph.insertEdgeAt(*nodes[pick(nodes.size())], 0, *nodes[pick(nodes.size())], kLink);
    } else {
      Node* from = nodes[pick(nodes.size())];
      if (from->neighbourCount(kLink) > 0) graph.removeEdge(*from, *from->neighbour(kLink, 0), kLink);
    }
    if (view.refresh(graph, arrays)) ++rebuilds;
    expectMatchesGraph(view, tissue);
    if (::testing::Test::HasFatalFailure()) return;
  }
  EXPECT_GT(rebuilds, 300);
}

TEST(MgeNeighbourSlots, RelocationAloneTriggersARebuild) {
  Graph graph;
  NodeArrays arrays;
  Tissue& tissue = graph.create<Tissue>();
  Node& a = addNode(graph, arrays, tissue, 0);
  Node& b = addNode(graph, arrays, tissue, 1);
  Node& c = addNode(graph, arrays, tissue, 2);
  graph.insertEdge(a, c, kLink);
  NeighbourSlots<Node> view(tissue, labels::kNodeList, {kLink, -kLink});
  ASSERT_TRUE(view.refresh(graph, arrays));
  ASSERT_EQ(view.neighbours(0).size(), 1u);
  EXPECT_EQ(*view.neighbours(0).begin(), 2u);
  // b leaves the arrays but stays in the graph: c moves into slot 1, no edge changes.
  const std::uint64_t edges = graph.edgeVersion();
  b.arrayConnector().disconnect();
  EXPECT_EQ(graph.edgeVersion(), edges);
  EXPECT_THROW(view.refresh(graph, arrays), std::invalid_argument);  // b is listed but has no slot any more
  graph.destroy(b);
  ASSERT_TRUE(view.refresh(graph, arrays));
  EXPECT_EQ(*view.neighbours(0).begin(), 1u);
  expectMatchesGraph(view, tissue);
}

// kSlotOrder: row i is the node in slot i, its neighbours ascending; the same topology reached through another
// insertion order (and another list order) gives the same arrays.
TEST(MgeNeighbourSlots, SlotOrderIsCanonicalWhateverTheInsertionOrder) {
  std::mt19937 rng(40);
  std::vector<std::pair<int, int>> links;
  for (int i = 0; i < 150; ++i) links.emplace_back(std::uniform_int_distribution<int>(0, 29)(rng), (i * 7) % 30);
  auto build = [&links](bool reversed, std::vector<std::uint32_t>* offsets, std::vector<std::uint32_t>* slots) {
    Graph graph;
    NodeArrays arrays;
    Tissue& tissue = graph.create<Tissue>();
    std::vector<Node*> nodes(30);
    for (int i = 0; i < 30; ++i) {
      Node& node = graph.create<Node>();
      node.arrayConnector().connect(arrays, &node, Eigen::Vector3d(i, 0, 0), Eigen::Vector3d::Zero(), 1.0, 0);
      nodes[i] = &node;
    }
    // Listed in reverse slot order in one of the two graphs.
    for (int i = 0; i < 30; ++i) graph.insertEdge(tissue, *nodes[reversed ? 29 - i : i], labels::kNodeList);
    for (std::size_t k = 0; k < links.size(); ++k) {
      const auto& [a, b] = links[reversed ? links.size() - 1 - k : k];
      graph.insertEdge(*nodes[a], *nodes[b], kLink);
    }
    NeighbourSlots<Node> view(tissue, labels::kNodeList, {kLink, -kLink}, NeighbourSlots<Node>::Layout::kSlotOrder);
    ASSERT_TRUE(view.refresh(graph, arrays));
    ASSERT_EQ(view.size(), 30u);
    for (std::size_t i = 0; i < view.size(); ++i) {
      ASSERT_EQ(view.slot(i), i);
      std::vector<std::uint32_t> expected;
      for (Node* neighbour : ListAccess<Node>(*nodes[i], kLink)) expected.push_back(neighbour->slot());
      for (Node* neighbour : ListAccess<Node>(*nodes[i], -kLink)) expected.push_back(neighbour->slot());
      std::sort(expected.begin(), expected.end());
      const auto range = view.neighbours(i);
      ASSERT_EQ(std::vector<std::uint32_t>(range.begin(), range.end()), expected) << "node " << i;
    }
    offsets->assign(view.offsets(), view.offsets() + view.size() + 1);
    slots->assign(view.neighbourSlots(), view.neighbourSlots() + view.neighbourCount());
  };
  std::vector<std::uint32_t> offsets_a, slots_a, offsets_b, slots_b;
  build(false, &offsets_a, &slots_a);
  build(true, &offsets_b, &slots_b);
  EXPECT_EQ(offsets_a, offsets_b);
  EXPECT_EQ(slots_a, slots_b);
  EXPECT_EQ(slots_a.size(), 2 * links.size());
}

// kSlotOrder needs the list to be exactly the manager's slots: a node of the arrays missing from the list is an error,
// not a silently short view.
TEST(MgeNeighbourSlots, SlotOrderRejectsAListThatIsNotTheSlots) {
  Graph graph;
  NodeArrays arrays;
  Tissue& tissue = graph.create<Tissue>();
  addNode(graph, arrays, tissue, 0);
  Node& unlisted = graph.create<Node>();
  unlisted.arrayConnector().connect(arrays, &unlisted, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1.0, 0);
  addNode(graph, arrays, tissue, 2);  // slot 2 in a list of two
  NeighbourSlots<Node> view(tissue, labels::kNodeList, {kLink}, NeighbourSlots<Node>::Layout::kSlotOrder);
  EXPECT_THROW(view.refresh(graph, arrays), std::invalid_argument);
  graph.insertEdge(tissue, unlisted, labels::kNodeList);
  EXPECT_TRUE(view.refresh(graph, arrays));  // the failed refresh left no stale view behind
  EXPECT_EQ(view.size(), 3u);
}

// Listed elements and neighbours of different types in different arrays: nodes and the springs at each node.
TEST(MgeNeighbourSlots, NodesToSpringsAcrossTwoArrays) {
  Graph graph;
  NodeArrays nodes;
  SpringArrays springs;
  Tissue& tissue = graph.create<Tissue>();
  Node& a = addNode(graph, nodes, tissue, 0);
  Node& b = addNode(graph, nodes, tissue, 1);
  Node& c = addNode(graph, nodes, tissue, 2);
  auto addSpring = [&](Node& from, Node& to) {
    Spring& spring = graph.create<Spring>();
    spring.arrayConnector().connect(springs, &spring, {from.slot(), to.slot()}, 1.0, 1.0);
    graph.insertEdge(spring, from, labels::kSpringNodes);
    graph.insertEdge(spring, to, labels::kSpringNodes);
    return &spring;
  };
  Spring* bc = addSpring(b, c);
  addSpring(a, b);
  NeighbourSlots<Node, Spring> view(tissue, labels::kNodeList, {referenceLabel(labels::kSpringNodes)},
                                    NeighbourSlots<Node, Spring>::Layout::kSlotOrder);
  ASSERT_TRUE(view.refresh(graph, nodes, springs));
  EXPECT_EQ(std::vector<std::uint32_t>(view.neighbours(0).begin(), view.neighbours(0).end()),
            std::vector<std::uint32_t>{1});
  EXPECT_EQ(std::vector<std::uint32_t>(view.neighbours(1).begin(), view.neighbours(1).end()),
            (std::vector<std::uint32_t>{0, 1}));  // ascending, though b met spring 0 first
  EXPECT_FALSE(view.refresh(graph, nodes, springs));
  // Destroying spring 0 moves spring 1 (a–b) into its slot.
  graph.destroy(*bc);
  ASSERT_TRUE(view.refresh(graph, nodes, springs));
  EXPECT_EQ(view.neighbours(2).size(), 0u);
  EXPECT_EQ(*view.neighbours(0).begin(), 0u);
  EXPECT_EQ(std::vector<std::uint32_t>(view.neighbours(1).begin(), view.neighbours(1).end()),
            std::vector<std::uint32_t>{0});
  SpringArrays other;
  EXPECT_THROW(view.refresh(graph, nodes, other), std::invalid_argument);  // springs of other arrays
}

TEST(MgeNeighbourSlots, ElementsOfOtherArraysAreRejected) {
  Graph graph;
  NodeArrays arrays, other;
  Tissue& tissue = graph.create<Tissue>();
  addNode(graph, arrays, tissue, 0);
  addNode(graph, other, tissue, 1);
  NeighbourSlots<Node> view(tissue, labels::kNodeList, {kLink});
  EXPECT_THROW(view.refresh(graph, arrays), std::invalid_argument);
}

}  // namespace
}  // namespace mge
}  // namespace vrm_sim
