#include "vrm_sim/collision/primitives.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/primitive_meshes.h"

namespace vrm_sim {
namespace collision {

using Eigen::Vector3d;

Primitive Primitive::sphere(const Vector3d& centre, double radius) {
  Primitive p;
  p.type = Type::kSphere;
  p.a = centre;
  p.radius = radius;
  return p;
}

Primitive Primitive::capsule(const Vector3d& a, const Vector3d& b, double radius) {
  Primitive p;
  p.type = Type::kCapsule;
  p.a = a;
  p.b = b;
  p.radius = radius;
  return p;
}

Primitive Primitive::box(const Vector3d& centre, const Vector3d& half_extents, const Eigen::Matrix3d& rotation) {
  Primitive p;
  p.type = Type::kBox;
  p.a = centre;
  p.half_extents = half_extents;
  p.rotation = rotation;
  return p;
}

Primitive Primitive::cylinder(const Vector3d& a, const Vector3d& b, double radius) {
  Primitive p = capsule(a, b, radius);
  p.type = Type::kCylinder;
  return p;
}

Primitive Primitive::cone(const Vector3d& apex, const Vector3d& base_centre, double base_radius) {
  Primitive p = capsule(apex, base_centre, base_radius);
  p.type = Type::kCone;
  return p;
}

Primitive Primitive::plane(const Vector3d& point, const Vector3d& normal) {
  Primitive p;
  p.type = Type::kPlane;
  p.a = point;
  p.normal = normal.normalized();
  return p;
}

Primitive transformed(const Primitive& primitive, const Eigen::Isometry3d& pose) {
  Primitive p = primitive;
  p.a = pose * primitive.a;
  p.b = pose * primitive.b;
  p.rotation = pose.linear() * primitive.rotation;
  p.normal = pose.linear() * primitive.normal;
  return p;
}

bool isValid(const Primitive& p) {
  if (!p.a.allFinite() || !p.b.allFinite() || !std::isfinite(p.radius) || p.radius < 0.0) return false;
  switch (p.type) {
    case Primitive::Type::kSphere:
    case Primitive::Type::kCapsule:
      return true;
    case Primitive::Type::kBox:
      return p.half_extents.allFinite() && p.half_extents.minCoeff() >= 0.0 && p.rotation.allFinite();
    case Primitive::Type::kCylinder:
    case Primitive::Type::kCone:
      return (p.b - p.a).norm() > 0.0;
    case Primitive::Type::kPlane:
      return p.normal.allFinite() && std::abs(p.normal.norm() - 1.0) < 1e-6;
  }
  return false;
}

namespace {

Vector3d closestPointOnSegment(const Vector3d& p, const Vector3d& a, const Vector3d& b) {
  const Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  if (len2 <= 0.0) return a;
  const double t = std::clamp((p - a).dot(ab) / len2, 0.0, 1.0);
  return a + t * ab;
}

// Interval of a line in a sphere; direction unit.
std::optional<Eigen::Vector2d> sphereInterval(const Vector3d& centre, double radius, const Vector3d& origin,
                                              const Vector3d& direction) {
  const Vector3d m = origin - centre;
  const double b = m.dot(direction);
  const double c = m.squaredNorm() - radius * radius;
  const double disc = b * b - c;
  if (disc < 0.0) return std::nullopt;
  const double s = std::sqrt(disc);
  return Eigen::Vector2d(-b - s, -b + s);
}

}  // namespace

double signedDistance(const Primitive& primitive, const Vector3d& point) {
  switch (primitive.type) {
    case Primitive::Type::kSphere:
      return (point - primitive.a).norm() - primitive.radius;
    case Primitive::Type::kCapsule:
      return (point - closestPointOnSegment(point, primitive.a, primitive.b)).norm() - primitive.radius;
    case Primitive::Type::kBox: {
      const Vector3d local = primitive.rotation.transpose() * (point - primitive.a);
      const Vector3d q = local.cwiseAbs() - primitive.half_extents;
      return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
    }
    case Primitive::Type::kCylinder:
    case Primitive::Type::kCone: {
      if (!isValid(primitive)) return std::numeric_limits<double>::infinity();
      // Solids of revolution: the exact 2D distance in (radial, axial) coordinates.
      const Vector3d axis = primitive.b - primitive.a;
      const double length = axis.norm();
      const Vector3d u = axis / length;
      const double h = (point - primitive.a).dot(u);
      const double rho = (point - primitive.a - h * u).norm();
      if (primitive.type == Primitive::Type::kCylinder) {
        const Eigen::Vector2d q(rho - primitive.radius, std::abs(h - 0.5 * length) - 0.5 * length);
        return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
      }
      // Cone: the triangle (0,0)-(R,H)-(0,H) in (rho, h); its boundary in 3D is the slanted side and the base.
      const Eigen::Vector2d p(rho, h), apex(0.0, 0.0), rim(primitive.radius, length), centre(0.0, length);
      auto segment = [&p](const Eigen::Vector2d& s0, const Eigen::Vector2d& s1) {
        const Eigen::Vector2d d = s1 - s0;
        const double t = std::clamp((p - s0).dot(d) / d.squaredNorm(), 0.0, 1.0);
        return (p - s0 - t * d).norm();
      };
      const double distance = std::min(segment(apex, rim), segment(centre, rim));
      const bool inside = h >= 0.0 && h <= length && rho * length <= primitive.radius * h;
      return inside ? -distance : distance;
    }
    case Primitive::Type::kPlane:
      return primitive.normal.dot(point - primitive.a);
  }
  return 0.0;
}

Vector3d closestPointOnTriangle(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  // Ericson, Real-Time Collision Detection, 5.1.5 (Voronoi regions).
  const Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  const Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + d1 / (d1 - d3) * ab;
  const Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) return a;  // degenerate triangle
  const double denom = 1.0 / sum;
  return a + ab * (vb * denom) + ac * (vc * denom);
}

double segmentSegmentDistanceSquared(const Vector3d& p1, const Vector3d& q1, const Vector3d& p2, const Vector3d& q2) {
  // Ericson 5.1.9.
  const Vector3d d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  const double eps = 1e-30;
  if (a <= eps && e <= eps) return r.squaredNorm();
  if (a <= eps) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= eps) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2);
      const double denom = a * e - b * b;
      s = denom > eps ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return ((p1 + d1 * s) - (p2 + d2 * t)).squaredNorm();
}

double segmentTriangleDistanceSquared(const Vector3d& s0, const Vector3d& s1, const Vector3d& a, const Vector3d& b,
                                      const Vector3d& c) {
  // Intersection of the segment with the triangle plane inside the triangle -> 0.
  const Vector3d n = (b - a).cross(c - a);
  const double d0 = n.dot(s0 - a), d1 = n.dot(s1 - a);
  if ((d0 <= 0.0 && d1 >= 0.0) || (d0 >= 0.0 && d1 <= 0.0)) {
    if (d0 != d1) {
      const Vector3d x = s0 + (d0 / (d0 - d1)) * (s1 - s0);
      if ((closestPointOnTriangle(x, a, b, c) - x).squaredNorm() <= 1e-24) return 0.0;
    }
  }
  double best = (closestPointOnTriangle(s0, a, b, c) - s0).squaredNorm();
  best = std::min(best, (closestPointOnTriangle(s1, a, b, c) - s1).squaredNorm());
  best = std::min(best, segmentSegmentDistanceSquared(s0, s1, a, b));
  best = std::min(best, segmentSegmentDistanceSquared(s0, s1, b, c));
  best = std::min(best, segmentSegmentDistanceSquared(s0, s1, c, a));
  return best;
}

namespace {

// Akenine-Möller triangle/box overlap (separating axis theorem with 13 axes), in the box frame.
bool triangleBoxOverlap(const Vector3d& v0, const Vector3d& v1, const Vector3d& v2, const Vector3d& h) {
  const Vector3d e[3] = {v1 - v0, v2 - v1, v0 - v2};
  const Vector3d v[3] = {v0, v1, v2};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      const Vector3d axis = Vector3d::Unit(i).cross(e[j]);
      if (axis.squaredNorm() < 1e-30) continue;
      const double p0 = axis.dot(v[0]), p1 = axis.dot(v[1]), p2 = axis.dot(v[2]);
      const double r = h.x() * std::abs(axis.x()) + h.y() * std::abs(axis.y()) + h.z() * std::abs(axis.z());
      if (std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r) return false;
    }
  }
  for (int i = 0; i < 3; ++i) {
    if (std::min({v0[i], v1[i], v2[i]}) > h[i] || std::max({v0[i], v1[i], v2[i]}) < -h[i]) return false;
  }
  const Vector3d n = e[0].cross(e[1]);
  const double d = n.dot(v0);
  const double r = h.x() * std::abs(n.x()) + h.y() * std::abs(n.y()) + h.z() * std::abs(n.z());
  return std::abs(d) <= r;
}

}  // namespace

Vector3d support(const Primitive& p, const Vector3d& direction) {
  const double norm = direction.norm();
  const Vector3d d = norm > 0.0 ? Vector3d(direction / norm) : Vector3d::UnitX();
  // Unit component of d perpendicular to the axis u (zero if d is along the axis).
  auto radial = [&d](const Vector3d& u) {
    const Vector3d r = d - d.dot(u) * u;
    const double n = r.norm();
    return n > 1e-15 ? Vector3d(r / n) : Vector3d::Zero();
  };
  switch (p.type) {
    case Primitive::Type::kSphere:
      return p.a + p.radius * d;
    case Primitive::Type::kCapsule:
      return (d.dot(p.b - p.a) >= 0.0 ? p.b : p.a) + p.radius * d;
    case Primitive::Type::kBox: {
      const Vector3d local = p.rotation.transpose() * d;
      const Vector3d corner(local.x() >= 0.0 ? p.half_extents.x() : -p.half_extents.x(),
                            local.y() >= 0.0 ? p.half_extents.y() : -p.half_extents.y(),
                            local.z() >= 0.0 ? p.half_extents.z() : -p.half_extents.z());
      return p.a + p.rotation * corner;
    }
    case Primitive::Type::kCylinder: {
      const Vector3d axis = p.b - p.a;
      const Vector3d u = axis.normalized();
      return (d.dot(axis) >= 0.0 ? p.b : p.a) + p.radius * radial(u);
    }
    case Primitive::Type::kCone: {
      const Vector3d u = (p.b - p.a).normalized();
      const Vector3d rim = p.b + p.radius * radial(u);
      return d.dot(rim) > d.dot(p.a) ? rim : p.a;
    }
    case Primitive::Type::kPlane:
      return p.a;
  }
  return p.a;
}

namespace {

// Closest point to the origin on a simplex of 1-4 points; keeps only the points of the sub-simplex it lies on.
// Ericson, Real-Time Collision Detection 5.1.5 / 9.5 (GJK), with barycentric weights to reduce the simplex.
Vector3d closestOnSimplex(std::vector<Vector3d>& simplex) {
  const Vector3d origin = Vector3d::Zero();
  auto segment = [&](const Vector3d& a, const Vector3d& b, std::vector<Vector3d>& keep) {
    const Vector3d ab = b - a;
    const double denominator = ab.squaredNorm();
    const double t = denominator > 0.0 ? std::clamp(-a.dot(ab) / denominator, 0.0, 1.0) : 0.0;
    keep.clear();
    if (t < 1.0) keep.push_back(a);
    if (t > 0.0) keep.push_back(b);
    return Vector3d(a + t * ab);
  };
  auto triangle = [&](const Vector3d& a, const Vector3d& b, const Vector3d& c, std::vector<Vector3d>& keep) {
    const Vector3d ab = b - a, ac = c - a, ap = origin - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    keep.clear();
    if (d1 <= 0.0 && d2 <= 0.0) return keep = {a}, a;
    const Vector3d bp = origin - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0.0 && d4 <= d3) return keep = {b}, b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return keep = {a, b}, Vector3d(a + d1 / (d1 - d3) * ab);
    const Vector3d cp = origin - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0.0 && d5 <= d6) return keep = {c}, c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return keep = {a, c}, Vector3d(a + d2 / (d2 - d6) * ac);
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
      return keep = {b, c}, Vector3d(b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b));
    }
    const double sum = va + vb + vc;
    if (!(sum > 0.0)) return segment(a, b, keep);  // degenerate (collinear) triangle
    return keep = {a, b, c}, Vector3d(a + ab * (vb / sum) + ac * (vc / sum));
  };
  std::vector<Vector3d> keep;
  Vector3d v;
  switch (simplex.size()) {
    case 1:
      return simplex[0];
    case 2:
      v = segment(simplex[0], simplex[1], keep);
      break;
    case 3:
      v = triangle(simplex[0], simplex[1], simplex[2], keep);
      break;
    default: {
      const Vector3d &a = simplex[0], &b = simplex[1], &c = simplex[2], &d = simplex[3];
      // Inside the tetrahedron: the origin is on the same side of each face as the opposite vertex.
      auto same_side = [](const Vector3d& p0, const Vector3d& p1, const Vector3d& p2, const Vector3d& opposite) {
        const Vector3d n = (p1 - p0).cross(p2 - p0);
        const double so = n.dot(-p0), sv = n.dot(opposite - p0);
        return so * sv >= 0.0;
      };
      const double volume = std::abs((b - a).dot((c - a).cross(d - a)));
      if (volume > 0.0 && same_side(a, b, c, d) && same_side(a, b, d, c) && same_side(a, c, d, b) &&
          same_side(b, c, d, a)) {
        return Vector3d::Zero();
      }
      double best = std::numeric_limits<double>::infinity();
      const int faces[4][3] = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
      std::vector<Vector3d> face_keep;
      for (const auto& f : faces) {
        const Vector3d q = triangle(simplex[f[0]], simplex[f[1]], simplex[f[2]], face_keep);
        if (q.squaredNorm() < best) {
          best = q.squaredNorm();
          v = q;
          keep = face_keep;
        }
      }
    }
  }
  simplex = keep;
  return v;
}

// GJK distance test between two convex sets given by their support mappings: true if their distance is at most
// `tolerance` (Gilbert, Johnson, Keerthi 1988; termination as in van den Bergen 1999).
template <class SupportA, class SupportB>
bool gjkWithin(const SupportA& support_a, const SupportB& support_b, double tolerance) {
  Vector3d v = support_a(Vector3d::UnitX()) - support_b(-Vector3d::UnitX());
  const double scale = std::max(1.0, v.norm()) * 1e-12;
  std::vector<Vector3d> simplex;
  for (int iteration = 0; iteration < 128; ++iteration) {
    const double vv = v.squaredNorm();
    if (vv <= scale * scale) return true;  // the origin lies in A - B
    const Vector3d w = support_a(-v) - support_b(v);
    const double vw = v.dot(w);
    // v.w / |v| is a lower bound of the distance: separated by more than the tolerance.
    if (vw > 0.0 && vw * vw > tolerance * tolerance * vv) return false;
    // No progress: |v| is the distance (up to round-off).
    if (vv - vw <= 1e-12 * vv) break;
    bool known = false;
    for (const Vector3d& p : simplex) known = known || (p - w).squaredNorm() <= scale * scale;
    if (known) break;
    simplex.push_back(w);
    v = closestOnSimplex(simplex);
    if (simplex.size() == 4) return true;  // the origin is inside a tetrahedron of A - B
  }
  return v.norm() <= tolerance + scale;
}

double sweptRadius(const Primitive& p) {
  return p.type == Primitive::Type::kSphere || p.type == Primitive::Type::kCapsule ? p.radius : 0.0;
}

Vector3d coreSupport(const Primitive& p, const Vector3d& d) {
  if (p.type == Primitive::Type::kSphere) return p.a;
  if (p.type == Primitive::Type::kCapsule) return d.dot(p.b - p.a) >= 0.0 ? p.b : p.a;
  return support(p, d);
}

double planeLowest(const Primitive& plane, const Vector3d& lowest_point) {
  return plane.normal.dot(lowest_point - plane.a);
}

}  // namespace

bool overlaps(const Primitive& first, const Primitive& second, double tolerance) {
  if (!isValid(first) || !isValid(second) || !(tolerance >= 0.0)) return false;
  const bool first_plane = first.type == Primitive::Type::kPlane;
  const bool second_plane = second.type == Primitive::Type::kPlane;
  if (first_plane && second_plane) {
    // Two half-spaces are disjoint only if their normals are opposite and there is a gap between them.
    if (first.normal.dot(second.normal) > -1.0 + 1e-12) return true;
    return first.normal.dot(second.a - first.a) <= tolerance;
  }
  if (first_plane || second_plane) {
    const Primitive& plane = first_plane ? first : second;
    const Primitive& solid = first_plane ? second : first;
    return planeLowest(plane, support(solid, -plane.normal)) <= tolerance;
  }
  // Spheres and capsules are a point / segment swept by a ball: GJK runs on the polytope cores (finite, exact
  // convergence) and the radii join the tolerance.
  return gjkWithin([&](const Vector3d& d) { return coreSupport(first, d); },
                   [&](const Vector3d& d) { return coreSupport(second, d); },
                   tolerance + sweptRadius(first) + sweptRadius(second));
}

bool overlapsTriangle(const Primitive& primitive, const Vector3d& p0, const Vector3d& p1, const Vector3d& p2,
                      double tolerance) {
  switch (primitive.type) {
    case Primitive::Type::kSphere: {
      const double r = primitive.radius + tolerance;
      return (closestPointOnTriangle(primitive.a, p0, p1, p2) - primitive.a).squaredNorm() <= r * r;
    }
    case Primitive::Type::kCapsule: {
      const double r = primitive.radius + tolerance;
      return segmentTriangleDistanceSquared(primitive.a, primitive.b, p0, p1, p2) <= r * r;
    }
    case Primitive::Type::kBox: {
      const Eigen::Matrix3d rt = primitive.rotation.transpose();
      const Vector3d h = primitive.half_extents + Vector3d::Constant(tolerance);
      return triangleBoxOverlap(rt * (p0 - primitive.a), rt * (p1 - primitive.a), rt * (p2 - primitive.a), h);
    }
    case Primitive::Type::kCylinder:
    case Primitive::Type::kCone: {
      if (!isValid(primitive) || !p0.allFinite() || !p1.allFinite() || !p2.allFinite()) return false;
      const Vector3d* corners[3] = {&p0, &p1, &p2};
      auto triangle_support = [&corners](const Vector3d& d) {
        const Vector3d* best = corners[0];
        for (const Vector3d* c : corners) best = d.dot(*c) > d.dot(*best) ? c : best;
        return *best;
      };
      return gjkWithin([&](const Vector3d& d) { return support(primitive, d); }, triangle_support, tolerance);
    }
    case Primitive::Type::kPlane:
      if (!isValid(primitive)) return false;
      return std::min({planeLowest(primitive, p0), planeLowest(primitive, p1), planeLowest(primitive, p2)}) <=
             tolerance;
  }
  return false;
}

namespace {

// The finite cylinder a-b (flat caps) of `radius` on the line origin + t * direction.
std::optional<Eigen::Vector2d> cylinderInterval(const Vector3d& a, const Vector3d& b, double radius,
                                                const Vector3d& origin, const Vector3d& direction) {
  const Vector3d axis_vec = b - a;
  const double len = axis_vec.norm();
  if (!(len > 0.0)) return std::nullopt;
  const Vector3d axis = axis_vec / len;
  const Vector3d m = origin - a;
  const Vector3d dp = direction - direction.dot(axis) * axis;
  const Vector3d mp = m - m.dot(axis) * axis;
  const double qa = dp.squaredNorm(), qb = mp.dot(dp), qc = mp.squaredNorm() - radius * radius;
  double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
  if (qa < 1e-30) {
    if (qc > 0.0) return std::nullopt;
  } else {
    const double disc = qb * qb - qa * qc;
    if (disc < 0.0) return std::nullopt;
    lo = (-qb - std::sqrt(disc)) / qa;
    hi = (-qb + std::sqrt(disc)) / qa;
  }
  const double da = direction.dot(axis), ma = m.dot(axis);
  if (std::abs(da) < 1e-30) {
    if (ma < 0.0 || ma > len) return std::nullopt;
  } else {
    double t0 = (0.0 - ma) / da, t1 = (len - ma) / da;
    if (t0 > t1) std::swap(t0, t1);
    lo = std::max(lo, t0);
    hi = std::min(hi, t1);
  }
  if (!(lo <= hi)) return std::nullopt;
  return Eigen::Vector2d(lo, hi);
}

// The cone (apex a, base centre b, base radius) on the line: the double cone |x_perp|^2 <= k^2 h^2 (a quadratic in
// t) intersected with the slab 0 <= h <= H, which keeps the one nappe of the solid.
std::optional<Eigen::Vector2d> coneInterval(const Vector3d& apex, const Vector3d& base, double radius,
                                            const Vector3d& origin, const Vector3d& direction) {
  const Vector3d axis_vec = base - apex;
  const double height = axis_vec.norm();
  if (!(height > 0.0)) return std::nullopt;
  const Vector3d u = axis_vec / height;
  const double k2 = 1.0 + (radius / height) * (radius / height);
  const Vector3d m = origin - apex;
  const double du = direction.dot(u), mu = m.dot(u);
  // Slab 0 <= mu + t du <= H.
  double slab_lo = -std::numeric_limits<double>::infinity(), slab_hi = std::numeric_limits<double>::infinity();
  if (std::abs(du) < 1e-30) {
    if (mu < 0.0 || mu > height) return std::nullopt;
  } else {
    slab_lo = (0.0 - mu) / du;
    slab_hi = (height - mu) / du;
    if (slab_lo > slab_hi) std::swap(slab_lo, slab_hi);
  }
  // q(t) = A t^2 + 2 B t + C <= 0.
  const double A = direction.squaredNorm() - k2 * du * du;
  const double B = m.dot(direction) - k2 * mu * du;
  const double C = m.squaredNorm() - k2 * mu * mu;
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<Eigen::Vector2d> pieces;
  if (std::abs(A) < 1e-30) {
    if (std::abs(B) < 1e-30) {
      if (C <= 0.0) pieces.emplace_back(-inf, inf);
    } else {
      const double t = -C / (2.0 * B);
      pieces.push_back(B > 0.0 ? Eigen::Vector2d(-inf, t) : Eigen::Vector2d(t, inf));
    }
  } else {
    const double disc = B * B - A * C;
    if (disc >= 0.0) {
      const double r0 = (-B - std::sqrt(disc)) / A, r1 = (-B + std::sqrt(disc)) / A;
      const double lo = std::min(r0, r1), hi = std::max(r0, r1);
      if (A > 0.0) {
        pieces.emplace_back(lo, hi);
      } else {
        pieces.emplace_back(-inf, lo);
        pieces.emplace_back(hi, inf);
      }
    } else if (A < 0.0) {
      pieces.emplace_back(-inf, inf);
    }
  }
  std::optional<Eigen::Vector2d> out;
  for (const Eigen::Vector2d& piece : pieces) {
    const double lo = std::max(piece[0], slab_lo), hi = std::min(piece[1], slab_hi);
    if (!(lo <= hi)) continue;
    out = out ? Eigen::Vector2d(std::min((*out)[0], lo), std::max((*out)[1], hi)) : Eigen::Vector2d(lo, hi);
  }
  return out;
}

}  // namespace

std::optional<Eigen::Vector2d> lineInterval(const Primitive& primitive, const Vector3d& origin,
                                            const Vector3d& direction) {
  switch (primitive.type) {
    case Primitive::Type::kSphere:
      return sphereInterval(primitive.a, primitive.radius, origin, direction);
    case Primitive::Type::kCapsule: {
      // Convex: the hull of the intervals of both end spheres and of the finite cylinder between them.
      std::optional<Eigen::Vector2d> out;
      auto merge = [&out](const std::optional<Eigen::Vector2d>& i) {
        if (!i) return;
        if (!out) {
          out = i;
        } else {
          out = Eigen::Vector2d(std::min((*out)[0], (*i)[0]), std::max((*out)[1], (*i)[1]));
        }
      };
      merge(sphereInterval(primitive.a, primitive.radius, origin, direction));
      merge(sphereInterval(primitive.b, primitive.radius, origin, direction));
      merge(cylinderInterval(primitive.a, primitive.b, primitive.radius, origin, direction));
      return out;
    }
    case Primitive::Type::kBox: {
      const Eigen::Matrix3d rt = primitive.rotation.transpose();
      const Vector3d o = rt * (origin - primitive.a), d = rt * direction;
      double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
      for (int i = 0; i < 3; ++i) {
        const double h = primitive.half_extents[i];
        if (std::abs(d[i]) < 1e-30) {
          if (o[i] < -h || o[i] > h) return std::nullopt;
          continue;
        }
        double t0 = (-h - o[i]) / d[i], t1 = (h - o[i]) / d[i];
        if (t0 > t1) std::swap(t0, t1);
        lo = std::max(lo, t0);
        hi = std::min(hi, t1);
      }
      if (lo > hi) return std::nullopt;
      return Eigen::Vector2d(lo, hi);
    }
    case Primitive::Type::kCylinder:
      return cylinderInterval(primitive.a, primitive.b, primitive.radius, origin, direction);
    case Primitive::Type::kCone:
      return coneInterval(primitive.a, primitive.b, primitive.radius, origin, direction);
    case Primitive::Type::kPlane: {
      const double nd = primitive.normal.dot(direction), height = primitive.normal.dot(origin - primitive.a);
      const double inf = std::numeric_limits<double>::infinity();
      if (std::abs(nd) < 1e-30) {
        if (height > 0.0) return std::nullopt;
        return Eigen::Vector2d(-inf, inf);
      }
      const double t = -height / nd;
      return nd > 0.0 ? Eigen::Vector2d(-inf, t) : Eigen::Vector2d(t, inf);
    }
  }
  return std::nullopt;
}

TriangleMesh primitiveMesh(const Primitive& primitive, int segments) {
  TriangleMesh mesh;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  switch (primitive.type) {
    case Primitive::Type::kSphere: {
      scene::SphereParams p;
      p.radius = primitive.radius;
      p.ring_count = std::max(4, segments / 2);
      mesh = scene::makeSphere(p);
      pose.translation() = primitive.a;
      break;
    }
    case Primitive::Type::kCapsule: {
      scene::CapsuleParams p;
      p.radius = primitive.radius;
      const Vector3d axis = primitive.b - primitive.a;
      p.length = axis.norm();
      p.segments = segments;
      p.cap_rings = std::max(2, segments / 4);
      mesh = scene::makeCapsule(p);
      pose.translation() = 0.5 * (primitive.a + primitive.b);
      if (p.length > 0.0)
        pose.linear() = Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), axis).toRotationMatrix();
      break;
    }
    case Primitive::Type::kBox: {
      scene::BoxParams p;
      p.size = 2.0 * primitive.half_extents;
      mesh = scene::makeBox(p);
      pose.linear() = primitive.rotation;
      pose.translation() = primitive.a;
      break;
    }
    case Primitive::Type::kCylinder:
    case Primitive::Type::kCone: {
      const Vector3d axis = primitive.b - primitive.a;
      if (!(axis.norm() > 0.0)) return mesh;
      pose.linear() = Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), axis).toRotationMatrix();
      if (primitive.type == Primitive::Type::kCylinder) {
        scene::CylinderParams p;
        p.radius = primitive.radius;
        p.length = axis.norm();
        p.segments = segments;
        mesh = scene::makeCylinder(p);
        pose.translation() = 0.5 * (primitive.a + primitive.b);
      } else {
        // makeCone: base in z = 0, apex at z = height; the primitive's apex is a, so z runs from b to a.
        scene::ConeParams p;
        p.radius = primitive.radius;
        p.height = axis.norm();
        p.segments = segments;
        mesh = scene::makeCone(p);
        pose.linear() = Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), -axis).toRotationMatrix();
        pose.translation() = primitive.b;
      }
      break;
    }
    case Primitive::Type::kPlane: {
      // A finite stand-in for the half-space's boundary: a 20 mm square facing along the normal.
      scene::PlaneParams p;
      p.size_x = p.size_y = 0.02;
      p.subdivisions = std::max(1, segments / 4);
      mesh = scene::makePlane(p);
      pose.linear() = Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), primitive.normal).toRotationMatrix();
      pose.translation() = primitive.a;
      break;
    }
  }
  scene::transformMesh(mesh, pose);
  return mesh;
}

}  // namespace collision
}  // namespace vrm_sim
