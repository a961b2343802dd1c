#pragma once
// Exact geometry of the convex primitives (sphere, capsule, box) against points, lines and triangles: the
// geometric detector (thesis §4.1: simple objects are tested geometrically) and the references of the tests.
// All inputs in one common frame.

#include <Eigen/Core>
#include <optional>

#include "vrm_sim/collision/collision_detector.h"

namespace vrm_sim {
namespace collision {

// A primitive moved by `pose` (instrument -> surface frame).
Primitive transformed(const Primitive& primitive, const Eigen::Isometry3d& pose);

// Signed distance of `point` to the primitive surface (negative inside).
double signedDistance(const Primitive& primitive, const Eigen::Vector3d& point);

// True if the closed solid and the closed triangle share a point (within `tolerance` [m]).
bool overlapsTriangle(const Primitive& primitive, const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                      const Eigen::Vector3d& p2, double tolerance = 0.0);

// Interval [lo, hi] of the line origin + t * direction (direction unit) inside the solid, if any.
std::optional<Eigen::Vector2d> lineInterval(const Primitive& primitive, const Eigen::Vector3d& origin,
                                            const Eigen::Vector3d& direction);

// Closest point on the triangle to `point`.
Eigen::Vector3d closestPointOnTriangle(const Eigen::Vector3d& point, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       const Eigen::Vector3d& c);
// Squared distance between the segments p0-p1 and q0-q1.
double segmentSegmentDistanceSquared(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q0,
                                     const Eigen::Vector3d& q1);
// Squared distance between a segment and a triangle (0 if they intersect).
double segmentTriangleDistanceSquared(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1, const Eigen::Vector3d& a,
                                      const Eigen::Vector3d& b, const Eigen::Vector3d& c);

// A closed triangle mesh of the primitive (instrument coordinates), e.g. to feed image-space / FCL detectors with
// the same instrument the geometric detector sees exactly.
TriangleMesh primitiveMesh(const Primitive& primitive, int segments = 32);

}  // namespace collision
}  // namespace vrm_sim
