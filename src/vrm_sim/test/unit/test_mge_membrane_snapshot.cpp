// Membrane snapshots (issue 39 §1, the tissue part of a checkpoint): a membrane restored from a snapshot equals the one
// it was taken from in every slot, id, array value and neighbour list — after a history of cuts, tears and
// refinement-like insertions that scrambles slot order against id order — and goes on equal under the same later
// operations. A bad snapshot is refused with a clear error and changes nothing.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_sim/mge/membrane.h"

namespace vrm_sim {
namespace mge {
namespace {

TriangleMesh makeGrid(int n, double spacing = 1.0e-3) {
  TriangleMesh mesh;
  auto index = [n](int i, int j) { return static_cast<std::uint32_t>(j * n + i); };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) mesh.vertices.emplace_back(i * spacing, j * spacing, 0.0);
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      mesh.triangles.push_back({index(i, j), index(i + 1, j), index(i + 1, j + 1)});
      mesh.triangles.push_back({index(i, j), index(i + 1, j + 1), index(i, j + 1)});
    }
  }
  for (int i = 0; i < n; ++i) mesh.fixed_vertices.push_back(index(i, 0));
  return mesh;
}

MembraneOptions withBending() {
  MembraneOptions options;
  options.bending_springs = true;
  return options;
}

std::string bits(double value) {
  std::uint64_t raw = 0;
  std::memcpy(&raw, &value, sizeof raw);
  std::ostringstream out;
  out << std::hex << raw;
  return out.str();
}
std::string bits(const Eigen::Vector3d& v) { return bits(v.x()) + "," + bits(v.y()) + "," + bits(v.z()); }

template <typename T>
std::string ids(ListAccess<T> list) {
  std::string text;
  for (T* element : list) text += std::to_string(element->id()) + " ";
  return text;
}

// Everything the simulation can observe of a membrane, one line per fact, values bit for bit: every slot's element,
// id and array values, every neighbour list (as ids, in order), the tissue's lists and the graph's next id.
std::vector<std::string> describe(Membrane& m) {
  std::vector<std::string> lines;
  lines.push_back("next_id " + std::to_string(m.graph().nextId()) + " transform " + std::to_string(m.transform().id()) +
                  " tissue " + std::to_string(m.tissue().id()));
  lines.push_back("tissue nodes " + ids(m.nodes()));
  lines.push_back("tissue springs " + ids(m.springs()));
  lines.push_back("tissue triangles " + ids(m.triangles()));
  for (std::size_t i = 0; i < m.nodeCount(); ++i) {
    Node& node = m.nodeAtSlot(i);
    lines.push_back("node " + std::to_string(i) + " id " + std::to_string(node.id()) + " x " + bits(node.position()) +
                    " v " + bits(node.velocity()) + " m " + bits(node.mass()) + " fixed " +
                    std::to_string(node.fixed()) + " springs " + ids(node.springs()) + " triangles " +
                    ids(node.triangles()));
  }
  for (std::size_t k = 0; k < m.springCount(); ++k) {
    Spring& spring = m.springAtSlot(k);
    const auto& ends = m.springNodeSlots()[k];
    lines.push_back("spring " + std::to_string(k) + " id " + std::to_string(spring.id()) + " ends " +
                    std::to_string(ends[0]) + "," + std::to_string(ends[1]) + " nodes " + ids(spring.nodes()) +
                    " rest " + bits(m.restLengths()[k]) + " k " + bits(m.stiffnesses()[k]) + " bending " +
                    std::to_string(spring.bending()) + " edge_of " +
                    ids(ListAccess<Triangle>(spring, referenceLabel(labels::kTriangleEdgeSprings))) + " bends " +
                    ids(ListAccess<Triangle>(spring, referenceLabel(labels::kTriangleBendingSprings))));
  }
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    Triangle& triangle = m.triangleAtSlot(t);
    const auto& corners = m.triangleNodeSlots()[t];
    lines.push_back("triangle " + std::to_string(t) + " id " + std::to_string(triangle.id()) + " corners " +
                    std::to_string(corners[0]) + "," + std::to_string(corners[1]) + "," + std::to_string(corners[2]) +
                    " nodes " + ids(triangle.nodes()) + " edges " + ids(triangle.edgeSprings()) + " bending " +
                    ids(triangle.bendingSprings()));
  }
  return lines;
}

// Equal descriptions, or the first line that differs (the whole dump would be thousands of lines).
::testing::AssertionResult sameMembrane(Membrane& expected, Membrane& actual) {
  const std::vector<std::string> a = describe(expected), b = describe(actual);
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    if (a[i] != b[i])
      return ::testing::AssertionFailure() << "line " << i << "\n  expected " << a[i] << "\n  actual   " << b[i];
  }
  if (a.size() != b.size()) return ::testing::AssertionFailure() << a.size() << " lines against " << b.size();
  return ::testing::AssertionSuccess();
}

Spring* springBetween(Node& a, Node& b) {
  for (Spring* spring : a.springs()) {
    if (spring->bending()) continue;
    ListAccess<Node> ends = spring->nodes();
    if ((ends[0] == &a && ends[1] == &b) || (ends[0] == &b && ends[1] == &a)) return spring;
  }
  return nullptr;
}

// One round of what the simulation does to a membrane, every choice by slot from `rng`: motion (positions,
// velocities, plastic rest lengths), a tear (springs), a cut (triangles and a node), and a refinement-like split of a
// triangle into three around a new centre node (new ids appended while old slots were reshuffled by removals).
void evolve(Membrane& m, std::mt19937& rng) {
  std::uniform_real_distribution<double> jitter(-1e-5, 1e-5);
  for (std::size_t i = 0; i < m.nodeCount(); ++i) {
    m.positions()[i] += Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
    m.velocities()[i] = Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng)) * 1e3;
  }
  for (std::size_t k = 0; k < m.springCount(); k += 7) m.restLengths()[k] *= 1.0 + std::abs(jitter(rng)) * 100.0;
  auto pick = [&rng](std::size_t count) { return std::uniform_int_distribution<std::size_t>(0, count - 1)(rng); };

  std::vector<Spring*> torn;
  for (int i = 0; i < 4 && m.springCount() > 0; ++i) torn.push_back(&m.springAtSlot(pick(m.springCount())));
  m.removeElements({}, torn, {}, /*remove_isolated_nodes=*/true);
  std::vector<Triangle*> cut;
  for (int i = 0; i < 3 && m.triangleCount() > 0; ++i) cut.push_back(&m.triangleAtSlot(pick(m.triangleCount())));
  std::vector<Node*> cut_nodes;
  if (m.nodeCount() > 0) cut_nodes.push_back(&m.nodeAtSlot(pick(m.nodeCount())));
  m.removeElements(cut, {}, cut_nodes, /*remove_isolated_nodes=*/true);

  if (m.triangleCount() == 0) return;
  Triangle& split = m.triangleAtSlot(pick(m.triangleCount()));
  std::vector<Node*> corners(split.nodes().begin(), split.nodes().end());
  const Eigen::Vector3d centre = (corners[0]->position() + corners[1]->position() + corners[2]->position()) / 3.0;
  Node& middle = m.addNode(centre, 1e-9);
  std::vector<Spring*> spokes;
  for (Node* corner : corners) spokes.push_back(&m.addSpring(*corner, middle, 2.0));
  for (int c = 0; c < 3; ++c) {
    Node& a = *corners[c];
    Node& b = *corners[(c + 1) % 3];
    Triangle& part = m.addTriangle(a, b, middle);
    if (Spring* rim = springBetween(a, b)) m.linkEdgeSpring(part, *rim);
    m.linkEdgeSpring(part, *spokes[(c + 1) % 3]);
    m.linkEdgeSpring(part, *spokes[c]);
  }
  m.removeElements({&split}, {}, {}, /*remove_isolated_nodes=*/false);
}

TEST(MgeMembraneSnapshot, RestoredMembraneEqualsTheOriginalAndStaysEqual) {
  const TriangleMesh mesh = makeGrid(12);
  auto original = buildMembrane(mesh, withBending());
  std::mt19937 history(7);
  for (int round = 0; round < 12; ++round) evolve(*original, history);
  ASSERT_TRUE(original->checkConsistency().ok()) << original->checkConsistency().summary();

  MembraneSnapshot snapshot;
  original->takeSnapshot(snapshot);
  // Restored into a membrane built from the scene again, as a World rebuilt after a crash would have it.
  auto restored = buildMembrane(mesh, withBending());
  restored->restore(snapshot);
  ASSERT_TRUE(restored->checkConsistency().ok()) << restored->checkConsistency().summary();
  ASSERT_TRUE(sameMembrane(*original, *restored));
  // Slots really are out of id order here, or the test would not show that both orders are kept.
  bool scrambled = false;
  for (std::size_t i = 1; i < original->nodeCount(); ++i) scrambled |= snapshot.node_ids[i] < snapshot.node_ids[i - 1];
  EXPECT_TRUE(scrambled);

  // The same later operations keep both equal: cuts pick by slot, removals go in id order, new ids follow next_id.
  std::mt19937 later_a(99), later_b(99);
  for (int round = 0; round < 8; ++round) {
    evolve(*original, later_a);
    evolve(*restored, later_b);
    ASSERT_TRUE(sameMembrane(*original, *restored)) << "after later round " << round;
  }
  EXPECT_TRUE(restored->checkConsistency().ok());
}

TEST(MgeMembraneSnapshot, SnapshotOfAnUntouchedMembraneAndRestoreIntoItself) {
  const TriangleMesh mesh = makeGrid(6);
  auto membrane = buildMembrane(mesh, withBending());
  auto copy = buildMembrane(mesh, withBending());
  MembraneSnapshot snapshot;
  membrane->takeSnapshot(snapshot);
  EXPECT_EQ(snapshot.nodeCount(), 36u);
  membrane->restore(snapshot);  // over itself: same content, new elements
  EXPECT_TRUE(sameMembrane(*copy, *membrane));
  EXPECT_TRUE(membrane->checkConsistency().ok());
  // The next element created gets the id an untouched membrane would give it.
  EXPECT_EQ(membrane->addNode(Eigen::Vector3d::Zero(), 1e-9).id(), copy->addNode(Eigen::Vector3d::Zero(), 1e-9).id());
}

TEST(MgeMembraneSnapshot, DualStorageAndTheEmptyMembrane) {
  MembraneOptions dual = withBending();
  dual.node_storage = StorageMode::kDual;
  const TriangleMesh mesh = makeGrid(5);
  auto original = buildMembrane(mesh, dual);
  std::mt19937 history(3);
  for (int round = 0; round < 3; ++round) evolve(*original, history);
  original->nodeArrays().sync();
  MembraneSnapshot snapshot;
  original->takeSnapshot(snapshot);
  auto restored = buildMembrane(mesh, dual);
  restored->restore(snapshot);
  EXPECT_TRUE(sameMembrane(*original, *restored));  // Node::position() reads the instance copies in kDual

  auto empty = std::make_unique<Membrane>();
  MembraneSnapshot nothing;
  empty->takeSnapshot(nothing);
  auto full = buildMembrane(makeGrid(3));
  // A membrane of the same construction (transform, tissue: ids 1, 2) takes the empty state.
  full->restore(nothing);
  EXPECT_EQ(full->nodeCount(), 0u);
  EXPECT_EQ(full->springCount(), 0u);
  EXPECT_TRUE(full->checkConsistency().ok());
}

TEST(MgeMembraneSnapshot, ASnapshotIntoAUsedObjectGivesTheSameResult) {
  // A periodic checkpoint reuses its snapshot object: what an earlier snapshot left in it must not leak into the next.
  auto membrane = buildMembrane(makeGrid(30), withBending());
  MembraneSnapshot first, second;
  membrane->takeSnapshot(first);
  membrane->takeSnapshot(second);
  membrane->takeSnapshot(second);
  EXPECT_EQ(first.node_ids, second.node_ids);
  EXPECT_EQ(first.triangle_links, second.triangle_links);
  EXPECT_EQ(first.triangle_link_offsets, second.triangle_link_offsets);
}

// Each corruption is refused with a message naming it, and the membrane keeps its state.
TEST(MgeMembraneSnapshot, BadSnapshotsAreRefusedAndChangeNothing) {
  const TriangleMesh mesh = makeGrid(6);
  auto source = buildMembrane(mesh, withBending());
  std::mt19937 history(11);
  for (int round = 0; round < 3; ++round) evolve(*source, history);
  MembraneSnapshot good;
  source->takeSnapshot(good);

  struct Case {
    const char* name;
    std::function<void(MembraneSnapshot&)> corrupt;
    const char* message;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Case> cases = {
      {"short column", [](MembraneSnapshot& s) { s.masses.pop_back(); }, "node columns"},
      {"spring end out of range", [](MembraneSnapshot& s) { s.spring_ends[3][1] = 100000; }, "spring slot 3"},
      {"spring to itself", [](MembraneSnapshot& s) { s.spring_ends[0][1] = s.spring_ends[0][0]; }, "spring slot 0"},
      {"repeated corner", [](MembraneSnapshot& s) { s.triangle_corners[2][2] = s.triangle_corners[2][0]; },
       "triangle slot 2"},
      {"link out of range", [](MembraneSnapshot& s) { s.triangle_links[1] = 1u << 30; }, "links a spring"},
      {"offsets", [](MembraneSnapshot& s) { s.triangle_link_offsets.back() += 1; }, "link offsets"},
      {"nan position", [nan](MembraneSnapshot& s) { s.positions[4].y() = nan; }, "node slot 4 is not finite"},
      {"negative mass", [](MembraneSnapshot& s) { s.masses[1] = -1.0; }, "node slot 1 has mass"},
      {"repeated id", [](MembraneSnapshot& s) { s.spring_ids[2] = s.node_ids[0]; }, "repeats id"},
      {"id of the tissue", [](MembraneSnapshot& s) { s.node_ids[0] = s.tissue_id; }, "repeats id"},
      {"id beyond next id", [](MembraneSnapshot& s) { s.triangle_ids[0] = s.next_id + 5; }, "next id is"},
      {"another membrane", [](MembraneSnapshot& s) { s.tissue_id += 1; }, "another membrane"},
  };
  for (const Case& c : cases) {
    auto target = buildMembrane(mesh, withBending());
    auto pristine = buildMembrane(mesh, withBending());
    MembraneSnapshot bad = good;
    c.corrupt(bad);
    try {
      target->restore(bad);
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find(c.message), std::string::npos) << c.name << ": " << error.what();
    }
    EXPECT_TRUE(sameMembrane(*pristine, *target)) << c.name << " changed the membrane";
  }
}

}  // namespace
}  // namespace mge
}  // namespace vrm_sim
