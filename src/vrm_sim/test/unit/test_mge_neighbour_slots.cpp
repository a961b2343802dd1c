// NeighbourSlots (issue 15): the derived CSR of array slots must equal what ListAccess and the ArrayConnectors say,
// after every kind of change the MGE allows (edges inserted and removed, elements destroyed so that the arrays move
// their last entry), and must not rebuild when nothing changed.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <random>
#include <stdexcept>
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
