// ArrayManager / ArrayConnector (thesis §3.3.2, Fig. 3.4–3.6): contiguous attribute arrays, O(1) removal by moving
// the last entry into the hole, shared slots across columns, and the dual storage mode with explicit sync.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>
#include <vector>

#include "vrm_sim/mge/array_manager.h"
#include "vrm_sim/mge/elements.h"
#include "vrm_sim/mge/graph.h"

namespace vrm_sim {
namespace mge {
namespace {

using Positions = ArrayManager<Eigen::Vector3d>;

TEST(MgeArrayManager, ConnectedAttributesAreContiguous) {
  Positions positions;
  std::vector<std::unique_ptr<Positions::Connector>> connectors;
  for (int i = 0; i < 8; ++i) {
    connectors.push_back(std::make_unique<Positions::Connector>());
    connectors.back()->connect(positions, nullptr, Eigen::Vector3d(i, 2.0 * i, 0.0));
  }
  ASSERT_EQ(positions.size(), 8u);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(connectors[i]->slot(), static_cast<std::uint32_t>(i));
    EXPECT_EQ(&connectors[i]->get(), positions.data() + i);  // kArray: the attribute *is* the array entry
  }
  connectors[3]->get().z() = 7.0;
  EXPECT_DOUBLE_EQ(positions.data()[3].z(), 7.0);
}

TEST(MgeArrayManager, RemovalMovesLastEntryIntoTheHole) {
  std::vector<std::size_t> relocated;  // outlives the connectors, whose destruction still notifies the listener
  Positions positions;
  std::vector<std::unique_ptr<Positions::Connector>> connectors;
  for (int i = 0; i < 5; ++i) {
    connectors.push_back(std::make_unique<Positions::Connector>());
    connectors.back()->connect(positions, nullptr, Eigen::Vector3d::Constant(i));
  }
  positions.setRelocationListener([&relocated](std::size_t slot) { relocated.push_back(slot); });

  connectors[1]->disconnect();
  EXPECT_FALSE(connectors[1]->connected());
  ASSERT_EQ(positions.size(), 4u);
  EXPECT_EQ(connectors[4]->slot(), 1u);  // the former last entry fills slot 1
  EXPECT_EQ(&positions.connectorAt(1), connectors[4].get());
  EXPECT_EQ(connectors[4]->get(), Eigen::Vector3d::Constant(4));
  EXPECT_EQ(positions.data()[1], Eigen::Vector3d::Constant(4));
  EXPECT_EQ(relocated, std::vector<std::size_t>{1});

  connectors[4].reset();  // destruction disconnects; removing the last entry moves nothing
  ASSERT_EQ(positions.size(), 3u);
  EXPECT_EQ(relocated, (std::vector<std::size_t>{1, 1}));  // connector 3 (was at slot 3) moved to slot 1
  EXPECT_EQ(connectors[3]->slot(), 1u);
  connectors[2]->disconnect();  // slot 2 is now the last slot
  EXPECT_EQ(relocated.size(), 2u);
  EXPECT_EQ(positions.size(), 2u);
  EXPECT_EQ(positions.data()[0], Eigen::Vector3d::Constant(0));
  EXPECT_EQ(positions.data()[1], Eigen::Vector3d::Constant(3));
}

TEST(MgeArrayManager, RandomizedCompactionKeepsEveryAttribute) {
  std::mt19937 rng(42);
  Positions positions;
  std::vector<std::unique_ptr<Positions::Connector>> connectors;
  std::vector<double> expected;  // expected x value per connector index, NaN when disconnected
  for (int op = 0; op < 20000; ++op) {
    const int kind = std::uniform_int_distribution<int>(0, 9)(rng);
    if (connectors.empty() || kind < 4) {
      connectors.push_back(std::make_unique<Positions::Connector>());
      connectors.back()->connect(positions, nullptr, Eigen::Vector3d(op, 0, 0));
      expected.push_back(op);
    } else {
      const std::size_t index = std::uniform_int_distribution<std::size_t>(0, connectors.size() - 1)(rng);
      if (kind < 7) {
        connectors[index]->disconnect();
        connectors.erase(connectors.begin() + static_cast<std::ptrdiff_t>(index));
        expected.erase(expected.begin() + static_cast<std::ptrdiff_t>(index));
      } else {
        connectors[index]->get().x() = -op;
        expected[index] = -op;
      }
    }
  }
  ASSERT_EQ(positions.size(), connectors.size());
  std::set<std::uint32_t> slots;
  for (std::size_t i = 0; i < connectors.size(); ++i) {
    const std::uint32_t slot = connectors[i]->slot();
    ASSERT_LT(slot, positions.size());
    EXPECT_TRUE(slots.insert(slot).second) << "slot used twice";
    EXPECT_EQ(&positions.connectorAt(slot), connectors[i].get());
    EXPECT_DOUBLE_EQ(positions.data()[slot].x(), expected[i]);
  }
}

TEST(MgeArrayManager, ColumnsShareOneSlotPerElement) {
  ArrayManager<Eigen::Vector3d, double, std::uint8_t> arrays;
  ArrayManager<Eigen::Vector3d, double, std::uint8_t>::Connector a, b, c;
  a.connect(arrays, nullptr, Eigen::Vector3d::UnitX(), 1.0, 1);
  b.connect(arrays, nullptr, Eigen::Vector3d::UnitY(), 2.0, 0);
  c.connect(arrays, nullptr, Eigen::Vector3d::UnitZ(), 3.0, 1);
  a.disconnect();
  ASSERT_EQ(arrays.size(), 2u);
  EXPECT_EQ(c.slot(), 0u);
  EXPECT_EQ(arrays.data<0>()[0], Eigen::Vector3d::UnitZ());
  EXPECT_DOUBLE_EQ(arrays.data<1>()[0], 3.0);
  EXPECT_EQ(arrays.data<2>()[0], 1);
  EXPECT_DOUBLE_EQ(b.get<1>(), 2.0);
  EXPECT_EQ(b.get<2>(), 0);
}

TEST(MgeArrayManager, DualStorageNeedsExplicitSync) {
  Positions positions(StorageMode::kDual);
  Positions::Connector a, b, c;
  a.connect(positions, nullptr, Eigen::Vector3d::Constant(1));
  b.connect(positions, nullptr, Eigen::Vector3d::Constant(2));
  c.connect(positions, nullptr, Eigen::Vector3d::Constant(3));
  EXPECT_EQ(positions.data()[1], Eigen::Vector3d::Constant(2));  // initial values are in both copies
  EXPECT_NE(&b.get(), positions.data() + 1);                     // the instance works on its own copy

  b.get() = Eigen::Vector3d::Constant(20);
  EXPECT_EQ(positions.data()[1], Eigen::Vector3d::Constant(2));  // the array is stale until sync()
  positions.sync();
  EXPECT_EQ(positions.data()[1], Eigen::Vector3d::Constant(20));

  a.disconnect();  // c moves to slot 0 and keeps its own value
  EXPECT_EQ(c.slot(), 0u);
  EXPECT_EQ(c.get(), Eigen::Vector3d::Constant(3));
  c.get() = Eigen::Vector3d::Constant(30);
  positions.sync();
  EXPECT_EQ(positions.data()[0], Eigen::Vector3d::Constant(30));
  EXPECT_EQ(positions.data()[1], Eigen::Vector3d::Constant(20));

  positions.data()[1] = Eigen::Vector3d::Constant(-1);  // a bulk algorithm wrote the array
  positions.syncFromArray();
  EXPECT_EQ(b.get(), Eigen::Vector3d::Constant(-1));
}

TEST(MgeArrayManager, SyncIsANoOpInArrayMode) {
  Positions positions;
  Positions::Connector a;
  a.connect(positions, nullptr, Eigen::Vector3d::Constant(5));
  positions.sync();
  positions.syncFromArray();
  EXPECT_EQ(a.get(), Eigen::Vector3d::Constant(5));
}

TEST(MgeArrayManager, ConnectingTwiceThrowsAndConnectorsMayOutliveTheManager) {
  Positions::Connector survivor;
  {
    Positions positions;
    survivor.connect(positions, nullptr, Eigen::Vector3d::Zero());
    EXPECT_THROW(survivor.connect(positions, nullptr, Eigen::Vector3d::Zero()), std::logic_error);
  }
  EXPECT_FALSE(survivor.connected());
  survivor.disconnect();  // harmless
}

TEST(MgeArrayManager, GraphElementsReleaseTheirSlotWhenDestroyed) {
  Graph graph;
  NodeArrays arrays;
  std::vector<Node*> nodes;
  for (int i = 0; i < 4; ++i) {
    Node& node = graph.create<Node>();
    node.arrayConnector().connect(arrays, &node, Eigen::Vector3d::Constant(i), Eigen::Vector3d::Zero(), 1.0, 0);
    nodes.push_back(&node);
  }
  EXPECT_EQ(arrays.ownerAt(2), nodes[2]);
  graph.destroy(*nodes[0]);
  ASSERT_EQ(arrays.size(), 3u);
  EXPECT_EQ(arrays.ownerAt(0), nodes[3]);
  EXPECT_EQ(nodes[3]->slot(), 0u);
  EXPECT_EQ(nodes[3]->position(), Eigen::Vector3d::Constant(3));
  EXPECT_EQ(arrays.data<kNodePosition>()[0], Eigen::Vector3d::Constant(3));
}

}  // namespace
}  // namespace mge
}  // namespace vrm_sim
