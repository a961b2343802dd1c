#include "vrm_sim/collision/primitives.h"

#include <algorithm>
#include <cmath>

#include "vrm_sim/scene/mesh_utils.h"
#include "vrm_sim/scene/primitive_meshes.h"

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

Primitive transformed(const Primitive& primitive, const Eigen::Isometry3d& pose) {
  Primitive p = primitive;
  p.a = pose * primitive.a;
  p.b = pose * primitive.b;
  p.rotation = pose.linear() * primitive.rotation;
  return p;
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
  }
  return false;
}

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
      const Vector3d axis_vec = primitive.b - primitive.a;
      const double len = axis_vec.norm();
      if (len > 0.0) {
        const Vector3d axis = axis_vec / len;
        const Vector3d m = origin - primitive.a;
        const Vector3d dp = direction - direction.dot(axis) * axis;
        const Vector3d mp = m - m.dot(axis) * axis;
        const double qa = dp.squaredNorm(), qb = mp.dot(dp),
                     qc = mp.squaredNorm() - primitive.radius * primitive.radius;
        double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
        bool hit = true;
        if (qa < 1e-30) {
          hit = qc <= 0.0;
        } else {
          const double disc = qb * qb - qa * qc;
          if (disc < 0.0) {
            hit = false;
          } else {
            lo = (-qb - std::sqrt(disc)) / qa;
            hi = (-qb + std::sqrt(disc)) / qa;
          }
        }
        const double da = direction.dot(axis), ma = m.dot(axis);
        if (hit) {
          if (std::abs(da) < 1e-30) {
            hit = ma >= 0.0 && ma <= len;
          } else {
            double t0 = (0.0 - ma) / da, t1 = (len - ma) / da;
            if (t0 > t1) std::swap(t0, t1);
            lo = std::max(lo, t0);
            hi = std::min(hi, t1);
            hit = lo <= hi;
          }
        }
        if (hit) merge(Eigen::Vector2d(lo, hi));
      }
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
  }
  scene::transformMesh(mesh, pose);
  return mesh;
}

}  // namespace collision
}  // namespace vrm_sim
