#pragma once
// The element types of thesis Fig. 3.1: mass-point nodes, springs and triangles of a membrane, the tissue MGE g2 that
// links to all of them, and a scene-graph transform. Attributes that solvers and the renderer sweep over live in
// ArrayManagers (§3.3.2); each element reaches its entry through its ArrayConnector.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>

#include "vrm_sim/mge/array_manager.h"
#include "vrm_sim/mge/element.h"
#include "vrm_sim/mge/labels.h"
#include "vrm_sim/mge/list_access.h"

namespace vrm_sim {
namespace mge {

// Node columns: position, velocity, mass, fixed flag (1 = pinned; uint8 rather than vector<bool> so it is an array).
using NodeArrays = ArrayManager<Eigen::Vector3d, Eigen::Vector3d, double, std::uint8_t>;
enum NodeColumn : std::size_t { kNodePosition = 0, kNodeVelocity = 1, kNodeMass = 2, kNodeFixed = 3 };

// Spring columns: node slots of the two ends (indices into the NodeArrays), rest length, stiffness.
using SpringArrays = ArrayManager<std::array<std::uint32_t, 2>, double, double>;
enum SpringColumn : std::size_t { kSpringNodeSlots = 0, kSpringRestLength = 1, kSpringStiffness = 2 };

// Triangle column: node slots of the three corners, in the triangle's vertex order.
using TriangleArrays = ArrayManager<std::array<std::uint32_t, 3>>;

class Spring;
class Triangle;

class Node final : public Element {
 public:
  Node() = default;

  Eigen::Vector3d& position() { return state_.get<kNodePosition>(); }
  const Eigen::Vector3d& position() const { return state_.get<kNodePosition>(); }
  Eigen::Vector3d& velocity() { return state_.get<kNodeVelocity>(); }
  const Eigen::Vector3d& velocity() const { return state_.get<kNodeVelocity>(); }
  double& mass() { return state_.get<kNodeMass>(); }
  double mass() const { return state_.get<kNodeMass>(); }
  bool fixed() const { return state_.get<kNodeFixed>() != 0; }
  void setFixed(bool fixed) { state_.get<kNodeFixed>() = fixed ? 1 : 0; }
  // Index of this node in the NodeArrays columns (changes when another node is removed).
  std::uint32_t slot() const { return state_.slot(); }

  // Springs and triangles attached to this node (reference lists of kSpringNodes / kTriangleNodes).
  ListAccess<Spring> springs() { return ListAccess<Spring>(*this, referenceLabel(labels::kSpringNodes)); }
  ListAccess<Triangle> triangles() { return ListAccess<Triangle>(*this, referenceLabel(labels::kTriangleNodes)); }

  NodeArrays::Connector& arrayConnector() { return state_; }
  const NodeArrays::Connector& arrayConnector() const { return state_; }

 private:
  NodeArrays::Connector state_;
};

class Spring final : public Element {
 public:
  // Bending springs span two triangles across their shared edge (resistance to folding), not a mesh edge.
  explicit Spring(bool bending = false) : bending_(bending) {}

  bool bending() const { return bending_; }
  double& restLength() { return arrays_.get<kSpringRestLength>(); }
  double restLength() const { return arrays_.get<kSpringRestLength>(); }
  double& stiffness() { return arrays_.get<kSpringStiffness>(); }
  double stiffness() const { return arrays_.get<kSpringStiffness>(); }
  std::uint32_t slot() const { return arrays_.slot(); }
  ListAccess<Node> nodes() { return ListAccess<Node>(*this, labels::kSpringNodes); }

  SpringArrays::Connector& arrayConnector() { return arrays_; }
  const SpringArrays::Connector& arrayConnector() const { return arrays_; }

 private:
  SpringArrays::Connector arrays_;
  bool bending_;
};

class Triangle final : public Element {
 public:
  Triangle() = default;

  std::uint32_t slot() const { return arrays_.slot(); }
  ListAccess<Node> nodes() { return ListAccess<Node>(*this, labels::kTriangleNodes); }
  ListAccess<Spring> edgeSprings() { return ListAccess<Spring>(*this, labels::kTriangleEdgeSprings); }
  ListAccess<Spring> bendingSprings() { return ListAccess<Spring>(*this, labels::kTriangleBendingSprings); }

  TriangleArrays::Connector& arrayConnector() { return arrays_; }
  const TriangleArrays::Connector& arrayConnector() const { return arrays_; }

 private:
  TriangleArrays::Connector arrays_;
};

// The tissue MGE (g2 in Fig. 3.1): the entry point from the scene graph into a deformable object's inner structure.
class Tissue final : public Element {
 public:
  Tissue() = default;
  ListAccess<Node> nodes() { return ListAccess<Node>(*this, labels::kNodeList); }
  ListAccess<Spring> springs() { return ListAccess<Spring>(*this, labels::kSpringList); }
  ListAccess<Triangle> triangles() { return ListAccess<Triangle>(*this, labels::kTriangleList); }
};

// Scene-graph node (g1 in Fig. 3.1): local pose relative to its parent; children via labels::kSceneChild.
class Transform final : public Element {
 public:
  Transform() : local_pose(Eigen::Isometry3d::Identity()) {}
  explicit Transform(const Eigen::Isometry3d& pose) : local_pose(pose) {}

  ListAccess<Element> children() { return ListAccess<Element>(*this, labels::kSceneChild); }
  ListAccess<Transform> parents() { return ListAccess<Transform>(*this, referenceLabel(labels::kSceneChild)); }

  Eigen::Isometry3d local_pose;
};

}  // namespace mge
}  // namespace vrm_sim
