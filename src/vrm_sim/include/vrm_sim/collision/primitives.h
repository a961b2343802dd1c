#pragma once
// Exact geometry of the convex primitives (sphere, capsule, box, cylinder, cone, half-space plane) against points,
// lines, triangles and each other: the geometric detector (thesis §4.1: simple objects are tested geometrically)
// and the references of the tests. All inputs in one common frame.
//
// Overlap tests of the round primitives (cylinder, cone) and all primitive pairs use GJK (Gilbert, Johnson, Keerthi
// 1988) on exact support mappings; spheres and capsules enter as their point / segment cores plus a radius, so pairs
// of sphere, capsule and box are decided to round-off, pairs with a cylinder or cone (curved rims, GJK converges
// linearly) to ~1e-9 of their size. Half-space planes are decided in closed form. Closed solids: touching counts as
// overlapping, and `tolerance` adds a ball (overlap within t = distance at most t).

#include <Eigen/Core>
#include <optional>

#include "vrm_sim/collision/collision_detector.h"

namespace vrm_sim {
namespace collision {

// A primitive moved by `pose` (instrument -> surface frame).
Primitive transformed(const Primitive& primitive, const Eigen::Isometry3d& pose);

// Finite parameters, non-negative sizes, unit-length normal (within 1e-6), a proper axis for cylinder and cone.
bool isValid(const Primitive& primitive);

// Signed distance of `point` to the primitive surface (negative inside). Exact (Euclidean) for every type.
double signedDistance(const Primitive& primitive, const Eigen::Vector3d& point);

// True if the closed solid and the closed triangle share a point (within `tolerance` [m]).
bool overlapsTriangle(const Primitive& primitive, const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                      const Eigen::Vector3d& p2, double tolerance = 0.0);

// True if the two closed solids share a point (within `tolerance` [m]). False for invalid primitives.
bool overlaps(const Primitive& first, const Primitive& second, double tolerance = 0.0);

// The support point of a bounded primitive: its farthest point along `direction` (GJK's support mapping). Planes
// are unbounded: their support is undefined (returns a).
Eigen::Vector3d support(const Primitive& primitive, const Eigen::Vector3d& direction);

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
