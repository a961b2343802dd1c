// Membrane as an MGE subgraph (thesis Fig. 3.1): exact element counts for a triangulated grid, arrays that match the
// mesh, scene-graph attachment, and removal (cutting / tearing) that keeps graph and arrays consistent.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>
#include <vector>

#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_sim/mge/membrane.h"

namespace vrm_sim {
namespace mge {
namespace {

// n×n vertices on a square of side (n−1)·spacing; each quad (i, j) split along (i, j)–(i+1, j+1) into two
// counter-clockwise triangles; the first row of vertices is fixed.
TriangleMesh makeGrid(int n, double spacing = 1.0e-3) {
  TriangleMesh mesh;
  mesh.name = "grid";
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

std::size_t gridEdges(std::size_t n) { return 2 * n * (n - 1) + (n - 1) * (n - 1); }
std::size_t gridBoundaryEdges(std::size_t n) { return 4 * (n - 1); }

std::size_t countBendingSprings(Membrane& membrane) {
  std::size_t count = 0;
  for (Spring* spring : membrane.springs()) count += spring->bending() ? 1 : 0;
  return count;
}

// Positions never change in these tests, so every stretch spring's array entry must still span its rest length.
void expectSpringSlotsMatchGeometry(Membrane& membrane) {
  const Eigen::Vector3d* positions = membrane.positions();
  for (std::size_t s = 0; s < membrane.springCount(); ++s) {
    const auto& ends = membrane.springNodeSlots()[s];
    ASSERT_LT(ends[0], membrane.nodeCount());
    ASSERT_LT(ends[1], membrane.nodeCount());
    EXPECT_NEAR((positions[ends[0]] - positions[ends[1]]).norm(), membrane.restLengths()[s], 1e-15);
  }
}

TEST(MgeMembrane, GridCountsAreExact) {
  for (int n : {2, 3, 5, 10, 33}) {
    SCOPED_TRACE(n);
    const std::size_t size = static_cast<std::size_t>(n);
    auto membrane = buildMembrane(makeGrid(n));
    EXPECT_EQ(membrane->nodeCount(), size * size);
    EXPECT_EQ(membrane->triangleCount(), 2 * (size - 1) * (size - 1));
    EXPECT_EQ(membrane->springCount(), gridEdges(size));
    EXPECT_EQ(membrane->nodes().size(), membrane->nodeCount());
    EXPECT_EQ(membrane->springs().size(), membrane->springCount());
    EXPECT_EQ(membrane->triangles().size(), membrane->triangleCount());
    EXPECT_EQ(countBendingSprings(*membrane), 0u);
    const InvariantReport report = membrane->checkConsistency();
    EXPECT_TRUE(report.ok()) << report.summary();
  }
}

TEST(MgeMembrane, BendingSpringsSpanEveryInteriorEdge) {
  for (int n : {2, 3, 6}) {
    SCOPED_TRACE(n);
    const std::size_t size = static_cast<std::size_t>(n);
    MembraneOptions options;
    options.bending_springs = true;
    options.bending_stiffness = 0.25;
    auto membrane = buildMembrane(makeGrid(n), options);
    const std::size_t interior_edges = gridEdges(size) - gridBoundaryEdges(size);
    EXPECT_EQ(countBendingSprings(*membrane), interior_edges);
    EXPECT_EQ(membrane->springCount(), gridEdges(size) + interior_edges);
    for (Spring* spring : membrane->springs()) {
      if (!spring->bending()) continue;
      EXPECT_EQ(spring->neighbourCount(referenceLabel(labels::kTriangleBendingSprings)), 2u);
      EXPECT_DOUBLE_EQ(spring->stiffness(), 0.25);
    }
    EXPECT_TRUE(membrane->checkConsistency().ok()) << membrane->checkConsistency().summary();
  }
}

TEST(MgeMembrane, ArraysMatchTheMesh) {
  const TriangleMesh mesh = makeGrid(4, 0.5e-3);
  MembraneOptions options;
  options.total_mass = 2.0e-6;
  options.stretch_stiffness = 3.0;
  auto membrane = buildMembrane(mesh, options);

  ASSERT_EQ(membrane->nodeCount(), mesh.vertices.size());
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    EXPECT_EQ(membrane->positions()[v], mesh.vertices[v]);  // built in vertex order: slot == vertex index
    EXPECT_EQ(membrane->velocities()[v], Eigen::Vector3d::Zero());
    const bool fixed =
        std::find(mesh.fixed_vertices.begin(), mesh.fixed_vertices.end(), v) != mesh.fixed_vertices.end();
    EXPECT_EQ(membrane->fixedFlags()[v], fixed ? 1 : 0);
    EXPECT_EQ(membrane->nodeAtSlot(v).fixed(), fixed);
  }
  const double total_mass = std::accumulate(membrane->masses(), membrane->masses() + membrane->nodeCount(), 0.0);
  EXPECT_NEAR(total_mass, 2.0e-6, 1e-18);
  // A corner with one triangle gets less mass than an interior node with six.
  EXPECT_LT(membrane->masses()[0], membrane->masses()[5]);

  ASSERT_EQ(membrane->triangleCount(), mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    EXPECT_EQ(membrane->triangleNodeSlots()[t], mesh.triangles[t]);  // vertex order (→ normal) preserved
    Triangle& triangle = membrane->triangleAtSlot(t);
    for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(triangle.nodes()[k]->slot(), mesh.triangles[t][k]);
    EXPECT_EQ(triangle.edgeSprings().size(), 3u);
  }
  for (std::size_t s = 0; s < membrane->springCount(); ++s) EXPECT_DOUBLE_EQ(membrane->stiffnesses()[s], 3.0);
  expectSpringSlotsMatchGeometry(*membrane);
}

TEST(MgeMembrane, SpringsAndTrianglesShareNodes) {
  auto membrane = buildMembrane(makeGrid(5));
  Node& interior = membrane->nodeAtSlot(2 * 5 + 2);
  EXPECT_EQ(interior.springs().size(), 6u);
  EXPECT_EQ(interior.triangles().size(), 6u);
  for (Spring* spring : interior.springs()) EXPECT_NE(spring->nodes().indexOf(&interior), 2u);
  for (Triangle* triangle : interior.triangles()) EXPECT_LT(triangle->nodes().indexOf(&interior), 3u);
  // Every interior edge spring belongs to two triangles, a boundary one to one.
  std::size_t boundary = 0;
  for (Spring* spring : membrane->springs()) {
    const std::size_t triangles = spring->neighbourCount(referenceLabel(labels::kTriangleEdgeSprings));
    EXPECT_TRUE(triangles == 1 || triangles == 2);
    boundary += triangles == 1 ? 1 : 0;
  }
  EXPECT_EQ(boundary, gridBoundaryEdges(5));
}

TEST(MgeMembrane, SceneGraphAttachment) {
  Graph scene;
  Transform& root = scene.create<Transform>();
  {
    auto membrane = buildMembrane(scene, makeGrid(4));
    scene.insertEdge(root, membrane->transform(), labels::kSceneChild);
    ASSERT_EQ(root.children().size(), 1u);
    EXPECT_EQ(root.children()[0], &membrane->transform());
    EXPECT_EQ(membrane->transform().children()[0], &membrane->tissue());
    EXPECT_EQ(membrane->transform().parents()[0], &root);
    EXPECT_EQ(scene.size(), 1u + 2u + 16u + gridEdges(4) + 18u);
    EXPECT_TRUE(membrane->checkConsistency().ok()) << membrane->checkConsistency().summary();
  }
  // Destroying the membrane removes its elements and edges from the shared graph.
  EXPECT_EQ(scene.size(), 1u);
  EXPECT_TRUE(root.children().empty());
  EXPECT_TRUE(scene.checkInvariants().ok()) << scene.checkInvariants().summary();
}

TEST(MgeMembrane, RemovingABoundaryTriangleRemovesItsOrphanSprings) {
  const int n = 4;
  auto membrane = buildMembrane(makeGrid(n));
  const std::size_t springs = membrane->springCount();
  // Triangle 0 = (v0, v1, v5): edges v0v1 (boundary), v1v5 (shared with the next quad), v5v0 (the diagonal).
  membrane->removeTriangle(membrane->triangleAtSlot(0));
  EXPECT_EQ(membrane->triangleCount(), 2u * (n - 1) * (n - 1) - 1);
  EXPECT_EQ(membrane->springCount(), springs - 1);  // only the boundary edge lost its last triangle
  EXPECT_EQ(membrane->nodeCount(), 16u);
  EXPECT_TRUE(membrane->checkConsistency().ok()) << membrane->checkConsistency().summary();
  expectSpringSlotsMatchGeometry(*membrane);

  CutOptions keep;
  keep.remove_orphan_springs = false;
  const std::size_t before = membrane->springCount();
  membrane->removeTriangle(membrane->triangleAtSlot(0), keep);
  EXPECT_EQ(membrane->springCount(), before);
  EXPECT_TRUE(membrane->checkConsistency().ok()) << membrane->checkConsistency().summary();
}

TEST(MgeMembrane, RemovingATriangleRemovesItsBendingSprings) {
  MembraneOptions options;
  options.bending_springs = true;
  auto membrane = buildMembrane(makeGrid(4), options);
  Triangle& triangle = membrane->triangleAtSlot(8);  // quad (1, 1), lower half: all three edges interior
  const std::size_t bending_of_triangle = triangle.bendingSprings().size();
  EXPECT_EQ(bending_of_triangle, 3u);
  const std::size_t bending = countBendingSprings(*membrane);
  membrane->removeTriangle(triangle);
  EXPECT_EQ(countBendingSprings(*membrane), bending - bending_of_triangle);
  EXPECT_TRUE(membrane->checkConsistency().ok()) << membrane->checkConsistency().summary();
}

TEST(MgeMembrane, RemovingANodeRemovesItsTrianglesAndSpringsAndFixesMovedSlots) {
  const int n = 5;
  auto membrane = buildMembrane(makeGrid(n));
  const Eigen::Vector3d last_position = membrane->positions()[n * n - 1];
  Node& last = membrane->nodeAtSlot(n * n - 1);
  Node& interior = membrane->nodeAtSlot(2 * n + 2);
  const std::size_t springs = membrane->springCount();
  const std::size_t triangles = membrane->triangleCount();
  membrane->removeNode(interior);
  EXPECT_EQ(membrane->nodeCount(), static_cast<std::size_t>(n * n - 1));
  EXPECT_EQ(membrane->triangleCount(), triangles - 6);
  EXPECT_EQ(membrane->springCount(), springs - 6);  // the surrounding ring keeps its outer triangles
  // The last node moved into the hole; its springs and triangles now index the new slot.
  EXPECT_EQ(last.slot(), static_cast<std::uint32_t>(2 * n + 2));
  EXPECT_EQ(membrane->positions()[last.slot()], last_position);
  const InvariantReport report = membrane->checkConsistency();
  EXPECT_TRUE(report.ok()) << report.summary();
  expectSpringSlotsMatchGeometry(*membrane);
}

TEST(MgeMembrane, OrphanNodesCanBeRemovedWithTheirLastTriangle) {
  auto membrane = buildMembrane(makeGrid(2));  // two triangles
  CutOptions options;
  options.remove_orphan_nodes = true;
  membrane->removeTriangle(membrane->triangleAtSlot(0), options);
  // (v0, v1, v3) removed: springs v0v1 and v1v3 orphaned, v1 left alone.
  EXPECT_EQ(membrane->triangleCount(), 1u);
  EXPECT_EQ(membrane->springCount(), 3u);
  EXPECT_EQ(membrane->nodeCount(), 3u);
  membrane->removeTriangle(membrane->triangleAtSlot(0), options);
  EXPECT_EQ(membrane->nodeCount(), 0u);
  EXPECT_EQ(membrane->springCount(), 0u);
  EXPECT_TRUE(membrane->checkConsistency().ok()) << membrane->checkConsistency().summary();
}

TEST(MgeMembrane, RandomCuttingKeepsGraphAndArraysConsistent) {
  std::mt19937 rng(1998);
  MembraneOptions options;
  options.bending_springs = true;
  auto membrane = buildMembrane(makeGrid(9), options);
  int step = 0;
  while (membrane->nodeCount() > 0) {
    const int kind = std::uniform_int_distribution<int>(0, 2)(rng);
    if (kind == 0 && membrane->triangleCount() > 0) {
      const std::size_t slot = std::uniform_int_distribution<std::size_t>(0, membrane->triangleCount() - 1)(rng);
      CutOptions cut;
      cut.remove_orphan_nodes = std::bernoulli_distribution(0.5)(rng);
      membrane->removeTriangle(membrane->triangleAtSlot(slot), cut);
    } else if (kind == 1 && membrane->springCount() > 0) {
      const std::size_t slot = std::uniform_int_distribution<std::size_t>(0, membrane->springCount() - 1)(rng);
      membrane->removeSpring(membrane->springAtSlot(slot));
    } else {
      const std::size_t slot = std::uniform_int_distribution<std::size_t>(0, membrane->nodeCount() - 1)(rng);
      membrane->removeNode(membrane->nodeAtSlot(slot));
    }
    const InvariantReport report = membrane->checkConsistency();
    ASSERT_TRUE(report.ok()) << "step " << step << ": " << report.summary();
    // Positions never change and every rest length is the initial distance, so stale slots would show here.
    expectSpringSlotsMatchGeometry(*membrane);
    ++step;
  }
  EXPECT_EQ(membrane->springCount(), 0u);
  EXPECT_EQ(membrane->triangleCount(), 0u);
  EXPECT_EQ(membrane->graph().size(), 2u);  // transform and tissue
}

TEST(MgeMembrane, DualStorageNodesPublishOnSync) {
  MembraneOptions options;
  options.node_storage = StorageMode::kDual;
  auto membrane = buildMembrane(makeGrid(3), options);
  Node& node = membrane->nodeAtSlot(4);
  const Eigen::Vector3d original = membrane->positions()[4];
  node.position() += Eigen::Vector3d(0, 0, 1e-3);
  EXPECT_EQ(membrane->positions()[4], original);
  membrane->nodeArrays().sync();
  EXPECT_EQ(membrane->positions()[4], original + Eigen::Vector3d(0, 0, 1e-3));
  membrane->removeNode(membrane->nodeAtSlot(0));
  EXPECT_TRUE(membrane->checkConsistency().ok()) << membrane->checkConsistency().summary();
}

TEST(MgeMembrane, RejectsInvalidMeshesAndForeignElements) {
  TriangleMesh out_of_range = makeGrid(2);
  out_of_range.triangles.push_back({0, 1, 9});
  EXPECT_THROW(buildMembrane(out_of_range), std::invalid_argument);
  TriangleMesh repeated = makeGrid(2);
  repeated.triangles.push_back({0, 1, 1});
  EXPECT_THROW(buildMembrane(repeated), std::invalid_argument);
  TriangleMesh bad_fixed = makeGrid(2);
  bad_fixed.fixed_vertices.push_back(4);
  EXPECT_THROW(buildMembrane(bad_fixed), std::invalid_argument);

  auto first = buildMembrane(makeGrid(2));
  auto second = buildMembrane(makeGrid(2));
  EXPECT_THROW(first->removeNode(second->nodeAtSlot(0)), std::invalid_argument);
  EXPECT_THROW(first->addSpring(first->nodeAtSlot(0), first->nodeAtSlot(0), 1.0), std::invalid_argument);
}

TEST(MgeMembrane, EmptyMeshGivesEmptyMembrane) {
  auto membrane = buildMembrane(TriangleMesh{});
  EXPECT_EQ(membrane->nodeCount(), 0u);
  EXPECT_TRUE(membrane->checkConsistency().ok());
}

}  // namespace
}  // namespace mge
}  // namespace vrm_sim
