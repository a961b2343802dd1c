// MGE graph and ListAccess: thesis §3.2 Def. 3.2 invariants (labels ≠ 0, reference edges, total order of Γ(v, l)),
// element deletion without dangling edges, and a seeded randomized comparison against a naive reference model.

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include "vrm_sim/mge/graph.h"
#include "vrm_sim/mge/list_access.h"

namespace vrm_sim {
namespace mge {
namespace {

class Item : public Element {
 public:
  explicit Item(int value = 0) : value(value) {}
  int value;
};

class OtherItem : public Element {
 public:
  double weight = 1.0;
};

constexpr Label kLink = 7;

std::vector<Element*> ids(std::initializer_list<Element*> elements) { return std::vector<Element*>(elements); }

TEST(MgeGraph, RejectsLabelZero) {
  Graph graph;
  Item& a = graph.create<Item>();
  Item& b = graph.create<Item>();
  EXPECT_THROW(graph.insertEdge(a, b, 0), std::invalid_argument);
  EXPECT_THROW(graph.insertEdgeAt(a, 0, b, 0), std::invalid_argument);
  EXPECT_THROW(graph.removeEdge(a, b, 0), std::invalid_argument);
  EXPECT_EQ(graph.edgeCount(), 0u);
  EXPECT_TRUE(graph.checkInvariants().ok());
}

TEST(MgeGraph, InsertEdgeAlsoInsertsReferenceEdge) {
  Graph graph;
  Item& a = graph.create<Item>();
  Item& b = graph.create<Item>();
  graph.insertEdge(a, b, kLink);
  EXPECT_EQ(a.neighbours(kLink), ids({&b}));
  EXPECT_EQ(b.neighbours(-kLink), ids({&a}));
  EXPECT_EQ(a.neighbourCount(-kLink), 0u);
  EXPECT_EQ(b.neighbourCount(kLink), 0u);
  EXPECT_EQ(graph.edgeCount(), 1u);
  EXPECT_EQ(a.labels(), std::vector<Label>{kLink});
  EXPECT_EQ(b.labels(), std::vector<Label>{-kLink});
  EXPECT_TRUE(graph.checkInvariants().ok());
}

TEST(MgeGraph, NeighbourListsKeepInsertionOrderAndInsertAtPosition) {
  Graph graph;
  Item& triangle = graph.create<Item>();
  Item& v0 = graph.create<Item>();
  Item& v1 = graph.create<Item>();
  Item& v2 = graph.create<Item>();
  Item& v3 = graph.create<Item>();
  graph.insertEdge(triangle, v0, kLink);
  graph.insertEdge(triangle, v2, kLink);
  graph.insertEdgeAt(triangle, 1, v1, kLink);  // between v0 and v2
  graph.insertEdgeAt(triangle, 0, v3, kLink);  // front
  EXPECT_EQ(triangle.neighbours(kLink), ids({&v3, &v0, &v1, &v2}));
  EXPECT_THROW(graph.insertEdgeAt(triangle, 5, v3, kLink), std::out_of_range);
  ASSERT_TRUE(graph.removeEdge(triangle, v0, kLink));
  EXPECT_EQ(triangle.neighbours(kLink), ids({&v3, &v1, &v2}));
  EXPECT_TRUE(graph.checkInvariants().ok()) << graph.checkInvariants().summary();
}

TEST(MgeGraph, RemoveEdgeRemovesBothDirections) {
  Graph graph;
  Item& a = graph.create<Item>();
  Item& b = graph.create<Item>();
  graph.insertEdge(a, b, kLink);
  graph.insertEdge(a, b, kLink);                // parallel edge: it is a multigraph
  EXPECT_FALSE(graph.removeEdge(b, a, kLink));  // wrong direction for this label
  ASSERT_TRUE(graph.removeEdge(b, a, -kLink));  // the reference edge names the same relation
  EXPECT_EQ(a.neighbourCount(kLink), 1u);
  EXPECT_EQ(b.neighbourCount(-kLink), 1u);
  ASSERT_TRUE(graph.removeEdge(a, b, kLink));
  EXPECT_EQ(a.degree(), 0u);
  EXPECT_EQ(b.degree(), 0u);
  EXPECT_FALSE(graph.removeEdge(a, b, kLink));
  EXPECT_TRUE(graph.checkInvariants().ok());
}

TEST(MgeGraph, DestroyLeavesNoDanglingEdges) {
  Graph graph;
  Item& hub = graph.create<Item>();
  Item& a = graph.create<Item>();
  Item& b = graph.create<Item>();
  graph.insertEdge(hub, a, 1);
  graph.insertEdge(hub, b, 1);
  graph.insertEdge(a, hub, 2);
  graph.insertEdge(hub, hub, 3);  // self loop
  graph.insertEdge(a, b, 4);
  graph.insertEdge(a, b, 4);
  graph.destroy(hub);
  EXPECT_EQ(graph.size(), 2u);
  EXPECT_EQ(a.neighbourCount(-1), 0u);
  EXPECT_EQ(a.neighbourCount(2), 0u);
  EXPECT_EQ(b.neighbourCount(-1), 0u);
  EXPECT_EQ(a.neighbours(4), ids({&b, &b}));
  EXPECT_EQ(graph.edgeCount(), 2u);
  EXPECT_TRUE(graph.checkInvariants().ok()) << graph.checkInvariants().summary();
  graph.destroy(b);
  EXPECT_EQ(a.degree(), 0u);
  EXPECT_TRUE(graph.checkInvariants().ok());
}

TEST(MgeGraph, RejectsElementsOfAnotherGraph) {
  Graph graph;
  Graph other;
  Item& a = graph.create<Item>();
  Item& foreign = other.create<Item>();
  EXPECT_FALSE(graph.contains(foreign));
  EXPECT_THROW(graph.insertEdge(a, foreign, kLink), std::invalid_argument);
  EXPECT_THROW(graph.destroy(foreign), std::invalid_argument);
  EXPECT_TRUE(graph.checkInvariants().ok());
  EXPECT_TRUE(other.checkInvariants().ok());
}

TEST(MgeGraph, PoolReusesSlotsAndKeepsAddressesStable) {
  Graph graph;
  std::vector<Item*> items;
  for (int i = 0; i < 5000; ++i) items.push_back(&graph.create<Item>(i));
  // Addresses never move while more elements are created.
  for (int i = 0; i < 5000; ++i) EXPECT_EQ(items[i]->value, i);
  Item* freed = items[1234];
  graph.destroy(*freed);
  Item& reused = graph.create<Item>(-1);
  EXPECT_EQ(&reused, freed);  // LIFO free list: the hole is filled first
  EXPECT_EQ(graph.size(), 5000u);
  EXPECT_NE(reused.id(), 1235u);  // ids are never reused
}

TEST(MgeListAccess, TypedIndexedAccessAndIteration) {
  Graph graph;
  Item& owner = graph.create<Item>();
  std::vector<Item*> expected;
  for (int i = 0; i < 10; ++i) {
    Item& item = graph.create<Item>(i);
    graph.insertEdge(owner, item, kLink);
    expected.push_back(&item);
  }
  OtherItem& other = graph.create<OtherItem>();
  graph.insertEdge(owner, other, kLink + 1);

  ListAccess<Item> items(owner, kLink);
  ASSERT_EQ(items.size(), 10u);
  for (std::size_t i = 0; i < items.size(); ++i) EXPECT_EQ(items[i]->value, static_cast<int>(i));  // no cast
  int sum = 0;
  for (Item* item : items) sum += item->value;
  EXPECT_EQ(sum, 45);
  EXPECT_EQ(std::vector<Item*>(items.begin(), items.end()), expected);
  EXPECT_EQ(items.indexOf(expected[3]), 3u);
  EXPECT_EQ(items.indexOf(&owner), items.size());
  EXPECT_EQ(items.label(), kLink);

  ListAccess<OtherItem> others(owner, kLink + 1);
  ASSERT_EQ(others.size(), 1u);
  EXPECT_DOUBLE_EQ(others.front()->weight, 1.0);
  ListAccess<Item> back(*expected[0], -kLink);
  EXPECT_EQ(back.front(), &owner);
}

TEST(MgeListAccess, StaysBoundAcrossLaterEdgeChanges) {
  Graph graph;
  Item& owner = graph.create<Item>();
  ListAccess<Item> first(owner, 1);  // bound before the list has any entry
  EXPECT_TRUE(first.empty());
  EXPECT_TRUE(graph.checkInvariants().ok());
  std::vector<Item*> expected_first;
  std::vector<Item*> expected_second;
  ListAccess<Item> second(owner, 2);
  // Interleaved growth forces label ranges to move inside the element's adjacency vector.
  for (int i = 0; i < 300; ++i) {
    Item& x = graph.create<Item>(i);
    Item& y = graph.create<Item>(-i);
    graph.insertEdge(owner, x, 1);
    graph.insertEdgeAt(owner, 0, y, 2);
    expected_first.push_back(&x);
    expected_second.insert(expected_second.begin(), &y);
  }
  EXPECT_EQ(std::vector<Item*>(first.begin(), first.end()), expected_first);
  EXPECT_EQ(std::vector<Item*>(second.begin(), second.end()), expected_second);
  EXPECT_TRUE(graph.checkInvariants().ok()) << graph.checkInvariants().summary();
  graph.shrinkToFit();
  EXPECT_EQ(std::vector<Item*>(first.begin(), first.end()), expected_first);
  EXPECT_EQ(std::vector<Item*>(second.begin(), second.end()), expected_second);
  EXPECT_TRUE(graph.checkInvariants().ok()) << graph.checkInvariants().summary();
}

// Naive model: per element id, per label, the ordered neighbour ids.
using ReferenceModel = std::map<std::uint64_t, std::map<Label, std::vector<std::uint64_t>>>;

void eraseFirst(std::vector<std::uint64_t>& list, std::uint64_t value) {
  auto found = std::find(list.begin(), list.end(), value);
  if (found != list.end()) list.erase(found);
}

void expectSameAsModel(const Graph& graph, const ReferenceModel& model) {
  ASSERT_EQ(graph.size(), model.size());
  for (const Element* element : graph.elements()) {
    auto entry = model.find(element->id());
    ASSERT_NE(entry, model.end());
    std::size_t degree = 0;
    for (const auto& [label, expected] : entry->second) {
      std::vector<std::uint64_t> actual;
      for (const Element* neighbour : element->neighbours(label)) actual.push_back(neighbour->id());
      ASSERT_EQ(actual, expected) << "element " << element->id() << " label " << label;
      degree += expected.size();
    }
    ASSERT_EQ(element->degree(), degree) << "element " << element->id() << " has labels the model does not know";
  }
}

TEST(MgeGraph, RandomizedOperationsMatchReferenceModel) {
  std::mt19937 rng(20030517);
  Graph graph;
  ReferenceModel model;
  std::vector<Item*> live;
  std::map<std::uint64_t, Item*> by_id;
  // Long-lived views, checked against the model along the way.
  std::vector<std::pair<std::unique_ptr<ListAccess<Item>>, std::uint64_t>> views;
  auto pick = [&rng](std::size_t count) { return std::uniform_int_distribution<std::size_t>(0, count - 1)(rng); };
  auto random_label = [&rng]() {
    const Label magnitude = std::uniform_int_distribution<Label>(1, 4)(rng);
    return std::bernoulli_distribution(0.5)(rng) ? magnitude : -magnitude;
  };

  const int kOperations = 20000;
  for (int op = 0; op < kOperations; ++op) {
    const int kind = std::uniform_int_distribution<int>(0, 99)(rng);
    if (live.size() < 2 || kind < 10) {
      Item& item = graph.create<Item>();
      live.push_back(&item);
      by_id[item.id()] = &item;
      model[item.id()];
    } else if (kind < 15) {
      const std::size_t index = pick(live.size());
      Item* doomed = live[index];
      const std::uint64_t id = doomed->id();
      views.erase(std::remove_if(views.begin(), views.end(), [id](const auto& view) { return view.second == id; }),
                  views.end());
      graph.destroy(*doomed);
      live.erase(live.begin() + static_cast<std::ptrdiff_t>(index));
      by_id.erase(id);
      model.erase(id);
      for (auto& [other_id, lists] : model) {
        for (auto& [label, list] : lists) list.erase(std::remove(list.begin(), list.end(), id), list.end());
      }
    } else if (kind < 65) {
      Item* from = live[pick(live.size())];
      Item* to = live[pick(live.size())];  // self loops included
      const Label label = random_label();
      std::vector<std::uint64_t>& list = model[from->id()][label];
      const std::size_t position = std::uniform_int_distribution<std::size_t>(0, list.size())(rng);
      graph.insertEdgeAt(*from, position, *to, label);
      list.insert(list.begin() + static_cast<std::ptrdiff_t>(position), to->id());
      model[to->id()][-label].push_back(from->id());
    } else if (kind < 95) {
      Item* from = live[pick(live.size())];
      const Label label = random_label();
      std::vector<std::uint64_t>& list = model[from->id()][label];
      // Mostly existing edges, sometimes absent ones.
      Item* to = (!list.empty() && kind < 90) ? by_id.at(list[pick(list.size())]) : live[pick(live.size())];
      const bool exists = std::find(list.begin(), list.end(), to->id()) != list.end();
      EXPECT_EQ(graph.removeEdge(*from, *to, label), exists);
      if (exists) {
        eraseFirst(list, to->id());
        eraseFirst(model[to->id()][-label], from->id());
      }
    } else {
      Item* owner = live[pick(live.size())];
      views.emplace_back(std::make_unique<ListAccess<Item>>(*owner, random_label()), owner->id());
    }

    if (op % 500 == 0 || op == kOperations - 1) {
      expectSameAsModel(graph, model);
      const InvariantReport report = graph.checkInvariants();
      ASSERT_TRUE(report.ok()) << "after op " << op << ": " << report.summary();
      for (const auto& [view, owner_id] : views) {
        const std::vector<std::uint64_t>& expected = model[owner_id][view->label()];
        ASSERT_EQ(view->size(), expected.size());
        for (std::size_t i = 0; i < expected.size(); ++i) ASSERT_EQ((*view)[i]->id(), expected[i]);
      }
    }
    if (::testing::Test::HasFatalFailure()) return;
  }
  EXPECT_GT(graph.edgeCount(), 100u);  // the run exercised a non-trivial graph
}

}  // namespace
}  // namespace mge
}  // namespace vrm_sim
