// ZCOLL (Alg. 4.2) and ZCOLL/F (Alg. 4.3) on the CPU backend against exact primitive truth, the cone test of
// §4.2.6, the known limits of §4.2 and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "vrm_scene/meshes/instrument_meshes.h"
#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/primitive_meshes.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/collision/primitives.h"
#include "vrm_sim/mge/membrane.h"

namespace vrm_sim {
namespace collision {
namespace {

using Eigen::Vector3d;
constexpr double kPi = 3.14159265358979323846;

// Instrument pointing down (-z of the surface frame) with its tip at `tip`, turned by `yaw` about z.
Eigen::Isometry3d pointingDown(const Vector3d& tip, double yaw = 0.0) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() =
      (Eigen::AngleAxisd(yaw, Vector3d::UnitZ()) * Eigen::AngleAxisd(kPi, Vector3d::UnitX())).toRotationMatrix();
  pose.translation() = tip;
  return pose;
}

InstrumentModel primitiveInstrument(const Primitive& primitive, int segments = 48) {
  InstrumentModel model;
  model.primitives = {primitive};
  model.mesh = primitiveMesh(primitive, segments);
  return model;
}

TriangleMesh plane(double size, int subdivisions) {
  scene::PlaneParams params;
  params.size_x = params.size_y = size;
  params.subdivisions = subdivisions;
  return scene::makePlane(params);
}

CollisionResult run(const std::string& name, const InstrumentModel& model, const Eigen::Isometry3d& pose,
                    const TriangleMesh& surface, CollisionOptions options = {}) {
  auto detector = makeCollisionDetector(name, options);
  detector->setInstrument(model);
  return detector->collide(pose, SurfaceView::of(surface));
}

// Incircle of a triangle (centre, radius).
std::pair<Vector3d, double> incircle(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const double la = (b - c).norm(), lb = (c - a).norm(), lc = (a - b).norm();
  const double s = la + lb + lc;
  const double area = 0.5 * (b - a).cross(c - a).norm();
  return {(la * a + lb * b + lc * c) / s, 2.0 * area / s};
}

class ZcollTruth : public ::testing::TestWithParam<std::string> {};

TEST_P(ZcollTruth, BoxPressingPlaneMatchesExactTriangleSetAndDepth) {
  const Vector3d half(0.0005, 0.0003, 0.0005);
  const InstrumentModel box = primitiveInstrument(Primitive::box(Vector3d(0, 0, -half.z()), half));
  const TriangleMesh surface = plane(0.004, 40);  // 0.1 mm cells
  const double depth = 0.0002;
  const Eigen::Isometry3d pose = pointingDown(Vector3d(0.0000123, -0.0000371, -depth), 0.3);
  CollisionOptions options;
  options.resolution = 64;
  const CollisionResult r = run(GetParam(), box, pose, surface, options);
  const CollisionResult exact = run("geometric", box, pose, surface, options);
  ASSERT_EQ(r.status, CollisionStatus::kOk);
  ASSERT_TRUE(r.colliding);
  const double p = r.pixel_size;
  EXPECT_NEAR(p, 0.001 / 62, 1e-9);

  const std::set<std::uint32_t> found(r.triangles.begin(), r.triangles.end());
  const std::set<std::uint32_t> truth(exact.triangles.begin(), exact.triangles.end());
  for (std::uint32_t t : found) EXPECT_TRUE(truth.count(t)) << "false positive " << t;
  // A triangle whose incircle holds a disc of radius p/sqrt(2) inside the footprint owns a pixel centre there.
  const Eigen::Isometry3d to_box = pose.inverse();
  int required = 0;
  for (std::uint32_t t : truth) {
    const auto& tri = surface.triangles[t];
    const auto [centre, radius] =
        incircle(surface.vertices[tri[0]], surface.vertices[tri[1]], surface.vertices[tri[2]]);
    const double s = p / std::sqrt(2.0) + 1e-9;
    const Vector3d local = to_box * centre;
    if (radius > s && std::abs(local.x()) < half.x() - s && std::abs(local.y()) < half.y() - s) {
      ++required;
      EXPECT_TRUE(found.count(t)) << "missed " << t;
    }
  }
  EXPECT_GT(required, 20);
  EXPECT_GE(found.size(), truth.size() * 8 / 10);

  // Flat front face: every deformation is the penetration depth along the instrument axis (Eq. 4.2).
  ASSERT_EQ(r.nodes.size(), r.deformations.size());
  std::set<std::uint32_t> truth_nodes;
  for (std::uint32_t t : truth) truth_nodes.insert(surface.triangles[t].begin(), surface.triangles[t].end());
  for (std::size_t i = 0; i < r.nodes.size(); ++i) {
    EXPECT_TRUE(truth_nodes.count(r.nodes[i]));
    EXPECT_NEAR((r.deformations[i] - Vector3d(0, 0, -depth)).norm(), 0.0, 1e-9);
  }
  // Every node well inside the footprint gets a vector.
  const std::set<std::uint32_t> nodes(r.nodes.begin(), r.nodes.end());
  const double margin = 0.0001 * std::sqrt(2.0) + p;
  for (std::size_t n = 0; n < surface.vertices.size(); ++n) {
    const Vector3d local = to_box * surface.vertices[n];
    if (std::abs(local.x()) < half.x() - margin && std::abs(local.y()) < half.y() - margin) {
      EXPECT_TRUE(nodes.count(static_cast<std::uint32_t>(n)));
    }
  }
  ASSERT_EQ(r.contact_points.size(), r.triangles.size());
  for (const Vector3d& n : r.contact_normals) EXPECT_NEAR((n - Vector3d(0, 0, -1)).norm(), 0.0, 1e-12);
  for (const Vector3d& c : r.contact_points) EXPECT_NEAR(c.z(), -depth, 1e-9);
}

TEST_P(ZcollTruth, SpherePressingPlaneWithinOnePixel) {
  const double radius = 0.001, depth = 0.0003;
  const InstrumentModel sphere = primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -radius), radius), 96);
  const TriangleMesh surface = plane(0.004, 40);
  const Vector3d axis(0.0000271, 0.0000113, 0.0);
  const Eigen::Isometry3d pose = pointingDown(axis + Vector3d(0, 0, -depth));
  CollisionOptions options;
  options.resolution = 64;
  const CollisionResult r = run(GetParam(), sphere, pose, surface, options);
  const CollisionResult exact = run("geometric", sphere, pose, surface, options);
  ASSERT_TRUE(r.colliding);
  const double p = r.pixel_size;
  const double tessellation = 5e-6;  // the 96-segment mesh lies within a few µm inside the exact sphere
  auto penetration = [&](double rho) {
    return rho >= radius ? 0.0 : std::max(0.0, depth - radius + std::sqrt(radius * radius - rho * rho));
  };
  const std::set<std::uint32_t> truth(exact.triangles.begin(), exact.triangles.end());
  for (std::uint32_t t : r.triangles) EXPECT_TRUE(truth.count(t)) << "false positive " << t;
  const double footprint = std::sqrt(radius * radius - (radius - depth) * (radius - depth));
  for (std::uint32_t t : truth) {
    const auto& tri = surface.triangles[t];
    const auto [centre, inradius] =
        incircle(surface.vertices[tri[0]], surface.vertices[tri[1]], surface.vertices[tri[2]]);
    const double s = p / std::sqrt(2.0) + tessellation;
    if (inradius > s && (centre - axis).norm() < footprint - s) {
      EXPECT_TRUE(std::binary_search(r.triangles.begin(), r.triangles.end(), t)) << "missed " << t;
    }
  }
  // Max reduction: the node's vector comes from a pixel of its 1-ring, so it lies between the exact penetration
  // one half pixel diagonal away from the node and the exact maximum over the ring (error <= one pixel).
  std::vector<std::vector<std::uint32_t>> ring(surface.vertices.size());
  for (std::size_t t = 0; t < surface.triangles.size(); ++t) {
    for (std::uint32_t n : surface.triangles[t]) ring[n].push_back(static_cast<std::uint32_t>(t));
  }
  for (std::size_t i = 0; i < r.nodes.size(); ++i) {
    const std::uint32_t n = r.nodes[i];
    const Vector3d& d = r.deformations[i];
    EXPECT_NEAR(d.x(), 0.0, 1e-12);
    EXPECT_NEAR(d.y(), 0.0, 1e-12);
    double rho_min = 1e9;
    for (std::uint32_t t : ring[n]) {
      const auto& tri = surface.triangles[t];
      rho_min = std::min(rho_min, (closestPointOnTriangle(axis, surface.vertices[tri[0]], surface.vertices[tri[1]],
                                                          surface.vertices[tri[2]]) -
                                   axis)
                                      .norm());
    }
    const double rho = (surface.vertices[n] - axis).norm();
    EXPECT_LE(-d.z(), penetration(rho_min) + 1e-9);
    EXPECT_GE(-d.z(), penetration(rho + p / std::sqrt(2.0)) - tessellation);
  }
}

INSTANTIATE_TEST_SUITE_P(CpuAndGlBackends, ZcollTruth,
                         ::testing::Values("zcoll_f_cpu", "zcoll_cpu", "zcoll_f_gl", "zcoll_gl"));

TEST(ZcollCpu, ZcollAndZcollFAgreeForConvexInstrumentAndReductionsAreConsistent) {
  const InstrumentModel capsule =
      primitiveInstrument(Primitive::capsule(Vector3d(0, 0, -0.0035), Vector3d(0, 0, -0.0005), 0.0005));
  TriangleMesh surface = plane(0.004, 50);
  const Eigen::Isometry3d pose =
      pointingDown(Vector3d(0.0001, 0, -0.0002), 0.1) * Eigen::AngleAxisd(0.2, Vector3d::UnitY());
  const CollisionResult f = run("zcoll_f_cpu", capsule, pose, surface);
  const CollisionResult z = run("zcoll_cpu", capsule, pose, surface);
  ASSERT_TRUE(f.colliding);
  EXPECT_EQ(f.triangles, z.triangles);
  EXPECT_EQ(f.nodes, z.nodes);
  CollisionOptions mean;
  mean.reduction = DeformationReduction::kMean;
  const CollisionResult m = run("zcoll_f_cpu", capsule, pose, surface, mean);
  ASSERT_EQ(m.nodes, f.nodes);
  for (std::size_t i = 0; i < m.nodes.size(); ++i)
    EXPECT_LE(m.deformations[i].norm(), f.deformations[i].norm() + 1e-12);
  CollisionOptions yes_no;
  yes_no.readback = ReadbackMode::kYesNo;
  EXPECT_TRUE(run("zcoll_f_cpu", capsule, pose, surface, yes_no).colliding);
  EXPECT_FALSE(run("zcoll_f_cpu", capsule, pointingDown(Vector3d(0, 0, 0.0001)), surface, yes_no).colliding);
  CollisionOptions triangles_only;
  triangles_only.readback = ReadbackMode::kTrianglesOnly;
  const CollisionResult t = run("zcoll_f_cpu", capsule, pose, surface, triangles_only);
  EXPECT_EQ(t.triangles, f.triangles);
  EXPECT_TRUE(t.nodes.empty());
  // The MGE membrane's arrays give the same answer as the mesh.
  auto membrane = mge::buildMembrane(surface);
  auto detector = makeCollisionDetector("zcoll_f_cpu");
  detector->setInstrument(capsule);
  const CollisionResult on_membrane = detector->collide(pose, SurfaceView::of(*membrane));
  EXPECT_EQ(on_membrane.triangles.size(), f.triangles.size());
}

TEST(ZcollCpu, CachesInstrumentDepthUntilShapeOrDirectionChanges) {
  TriangleMesh surface = plane(0.004, 40);
  auto detector = makeCollisionDetector("zcoll_f_cpu");
  detector->setInstrument(primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -0.0005), 0.0005)));
  const Eigen::Isometry3d pose = pointingDown(Vector3d(0, 0, -0.0002));
  const CollisionResult first = detector->collide(pose, SurfaceView::of(surface));
  const CollisionResult again = detector->collide(pose, SurfaceView::of(surface));
  EXPECT_EQ(first.triangles, again.triangles);
  EXPECT_EQ(first.pixel_size, again.pixel_size);
  // A new shape (think: the forceps jaws opened) is re-rendered.
  detector->setInstrument(primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -0.001), 0.001)));
  const CollisionResult bigger = detector->collide(pose, SurfaceView::of(surface));
  EXPECT_GT(bigger.triangles.size(), first.triangles.size());
  EXPECT_GT(bigger.pixel_size, first.pixel_size);
  // A new z direction: deformation vectors follow it (thesis §4.2.2: choose z along the motion).
  InstrumentModel tilted = primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -0.001), 0.001));
  tilted.projection_direction = Vector3d(std::sin(0.3), 0.0, std::cos(0.3));
  detector->setInstrument(tilted);
  const CollisionResult along = detector->collide(pose, SurfaceView::of(surface));
  ASSERT_TRUE(along.colliding);
  const Vector3d z = (pose.linear() * tilted.projection_direction).normalized();
  for (const Vector3d& d : along.deformations) EXPECT_NEAR(d.normalized().dot(z), 1.0, 1e-9);
}

// Bounded error: every image-space backend raises the resolution until the pixel size near the tip is within the
// bound, reports it per query, and keeps the configured resolution when that already satisfies the bound.
TEST_P(ZcollTruth, BoundedPixelSize) {
  const InstrumentModel sphere = primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -0.0005), 0.0005));
  const TriangleMesh surface = plane(0.004, 20);
  const Eigen::Isometry3d pose = pointingDown(Vector3d(0, 0, -0.0001));
  CollisionOptions options;
  options.resolution = 32;
  const CollisionResult free_size = run(GetParam(), sphere, pose, surface, options);
  ASSERT_EQ(free_size.status, CollisionStatus::kOk) << toString(free_size.status);
  EXPECT_EQ(free_size.resolution, 32);
  EXPECT_GT(free_size.pixel_size, 30e-6);  // 1 mm over 30 pixels
  options.max_pixel_size = 10e-6;
  const CollisionResult bounded = run(GetParam(), sphere, pose, surface, options);
  ASSERT_EQ(bounded.status, CollisionStatus::kOk) << toString(bounded.status);
  EXPECT_LE(bounded.pixel_size, 10e-6);
  EXPECT_GT(bounded.pixel_size, 9e-6) << "the smallest resolution within the bound";
  EXPECT_GT(bounded.resolution, 32);
  EXPECT_TRUE(bounded.colliding);
  // Same volume on every backend (the GL viewport follows the CPU choice).
  EXPECT_EQ(bounded.resolution, run("zcoll_f_cpu", sphere, pose, surface, options).resolution);
  // A bound looser than the configured resolution's pixel changes nothing; max_resolution caps the raise.
  options.max_pixel_size = 1e-3;
  EXPECT_EQ(run(GetParam(), sphere, pose, surface, options).resolution, 32);
  options.max_pixel_size = 1e-6;
  options.max_resolution = 200;
  const CollisionResult capped = run(GetParam(), sphere, pose, surface, options);
  EXPECT_EQ(capped.resolution, 200);
  EXPECT_GT(capped.pixel_size, 1e-6);
}

// Thesis §4.2.6, Fig. 4.13/4.14: a 4 x 4 grid of cones (alpha = 50°) sinks into a disc; all cones are detected
// from depth d ~ p / (2 tan(alpha/2)) (= (r tan(alpha/2))^-1 for a unit volume, p = 2/r). A cone is detected once
// its cross-section (diameter 2 d tan(alpha/2)) covers a pixel centre: between 1x (centre on the axis) and
// sqrt(2)x (axis at a pixel corner) the prediction.
TEST(ZcollCpu, ConeTestDepthScalesAsOneOverResolution) {
  const double alpha = 50.0 * kPi / 180.0, height = 0.0005, pitch = 0.001;
  const double cone_radius = height * std::tan(alpha / 2);
  InstrumentModel cones;
  std::vector<Vector3d> apexes;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      scene::ConeParams params;
      params.radius = cone_radius;
      params.height = height;
      params.segments = 96;
      TriangleMesh cone = scene::makeCone(params);
      // Irrational offsets spread the apexes over sub-pixel positions.
      const Vector3d apex((i - 1.5) * pitch + 0.000031 * std::sqrt(2.0) * j,
                          (j - 1.5) * pitch + 0.000017 * std::sqrt(3.0) * i, 0.0);
      scene::transformMesh(cone, Eigen::Isometry3d(Eigen::Translation3d(apex - Vector3d(0, 0, height))));
      scene::appendMesh(cones.mesh, cone);
      apexes.push_back(apex);
    }
  }
  cones.tip_region_length = height;
  scene::DiscParams disc_params;
  disc_params.radius = 0.003;
  disc_params.ring_count = 60;  // ~50 µm triangles: each sees at most one cone
  const TriangleMesh disc = scene::makeDisc(disc_params);
  auto detector = makeCollisionDetector("zcoll_f_cpu");
  detector->setInstrument(cones);
  auto all_detected = [&](double d) {
    const Eigen::Isometry3d pose = pointingDown(Vector3d(0.00011, -0.00007, -d));
    const CollisionResult r = detector->collide(pose, SurfaceView::of(disc));
    std::vector<bool> seen(apexes.size(), false);
    for (const Vector3d& c : r.contact_points) {
      const Vector3d local = pose.inverse() * c;
      std::size_t best = 0;
      for (std::size_t k = 1; k < apexes.size(); ++k) {
        if ((apexes[k] - local).head<2>().norm() < (apexes[best] - local).head<2>().norm()) best = k;
      }
      seen[best] = true;
    }
    return std::all_of(seen.begin(), seen.end(), [](bool b) { return b; });
  };
  std::vector<double> log_r, log_d;
  for (int r : {30, 60, 100, 200, 300}) {
    CollisionOptions options;
    options.resolution = r;
    detector->setOptions(options);
    double lo = 0.0, hi = 0.9 * height;
    ASSERT_TRUE(all_detected(hi));
    for (int it = 0; it < 30; ++it) {
      const double mid = 0.5 * (lo + hi);
      (all_detected(mid) ? hi : lo) = mid;
    }
    const double p = detector->collide(pointingDown(Vector3d(0, 0, -hi)), SurfaceView::of(disc)).pixel_size;
    const double predicted = p / (2.0 * std::tan(alpha / 2));
    const double ratio = hi / predicted;
    RecordProperty("r" + std::to_string(r), std::to_string(hi) + " m, predicted " + std::to_string(predicted));
    std::printf("cone test r=%3d pixel=%.2f um depth=%.2f um predicted=%.2f um ratio=%.3f\n", r, p * 1e6, hi * 1e6,
                predicted * 1e6, ratio);
    EXPECT_GE(ratio, 1.0 - 1e-3) << r;
    EXPECT_LE(ratio, std::sqrt(2.0) * 1.01) << r;  // 1 % for the 96-gon cross-section and the bisection
    log_r.push_back(std::log(r));
    log_d.push_back(std::log(hi));
  }
  // Least-squares slope of log d over log r.
  const double n = log_r.size();
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < log_r.size(); ++i) {
    sx += log_r[i];
    sy += log_d[i];
    sxx += log_r[i] * log_r[i];
    sxy += log_r[i] * log_d[i];
  }
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  std::printf("cone test log-log slope %.3f\n", slope);
  EXPECT_NEAR(slope, -1.0, 0.1);
}

// Known limits (thesis §4.2, §4.2.6).
TEST(ZcollLimits, GrazingAngleGivesLongVectorsAlongZ) {
  // The surface tilted 80° against the image plane: the z-buffer difference is the penetration along z, which is
  // much longer than the penetration along the surface normal (lower accuracy at grazing angles).
  const double radius = 0.0005, normal_depth = 0.0001, tilt = 80.0 * kPi / 180.0;
  TriangleMesh surface = plane(0.004, 80);
  scene::transformMesh(surface, Eigen::Isometry3d(Eigen::AngleAxisd(tilt, Vector3d::UnitX())));
  const Vector3d normal = Eigen::AngleAxisd(tilt, Vector3d::UnitX()) * Vector3d::UnitZ();
  const Vector3d centre = (radius - normal_depth) * normal;
  const Eigen::Isometry3d pose = pointingDown(centre + Vector3d(0, 0, -radius));
  const CollisionResult r =
      run("zcoll_f_cpu", primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -radius), radius)), pose, surface);
  ASSERT_TRUE(r.colliding);
  double longest = 0.0;
  for (const Vector3d& d : r.deformations) longest = std::max(longest, d.norm());
  EXPECT_GT(longest, 3.0 * normal_depth);
}

TEST(ZcollLimits, SeveralTrianglesPerPixelOnlyOneIdentified) {
  CollisionOptions options;
  options.resolution = 16;
  const InstrumentModel sphere = primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -0.0005), 0.0005));
  const TriangleMesh fine = plane(0.002, 100);  // 20 µm cells, pixels ~ 70 µm
  const Eigen::Isometry3d pose = pointingDown(Vector3d(0, 0, -0.0002));
  const CollisionResult r = run("zcoll_f_cpu", sphere, pose, fine, options);
  const CollisionResult exact = run("geometric", sphere, pose, fine, options);
  ASSERT_TRUE(r.colliding);
  const double footprint = std::sqrt(0.0005 * 0.0005 - 0.0003 * 0.0003);
  const double max_pixels = kPi * std::pow(footprint / r.pixel_size + 1.5, 2);
  EXPECT_LE(r.triangles.size(), max_pixels);
  EXPECT_LT(r.triangles.size() * 3, exact.triangles.size());
}

TEST(ZcollLimits, VitrectorPortIsNotZConvex) {
  // Tissue caught in the cutting port (thesis §4.2.7, Figs. 4.8/4.9): it is not inside the instrument, but ZCOLL/F
  // sees the tip face in front of it and pushes it to the tip; ZCOLL's stencil parity counts two surfaces (tip face
  // and the port's distal wall) in front of it and reports nothing.
  scene::VitrectorParams params;
  InstrumentModel vitrector;
  vitrector.mesh = scene::makeVitrector(params);
  const double r = 0.5 * params.shaft.diameter;
  const double z = -params.port_distance_from_tip - 0.5 * params.port_length;
  const double x = r - 0.5 * params.port_depth;
  scene::PlaneParams patch_params;
  patch_params.size_x = patch_params.size_y = 0.00004;
  patch_params.subdivisions = 2;
  TriangleMesh patch = scene::makePlane(patch_params);
  scene::transformMesh(patch, Eigen::Isometry3d(Eigen::Translation3d(x, 0.0, z)));
  CollisionOptions options;
  options.resolution = 128;
  const Eigen::Isometry3d identity = Eigen::Isometry3d::Identity();
  const CollisionResult f = run("zcoll_f_cpu", vitrector, identity, patch, options);
  ASSERT_TRUE(f.colliding);
  for (const Vector3d& d : f.deformations) {
    EXPECT_GT(d.z(), 0.0);  // towards the tip
    EXPECT_NEAR(d.z(), -z, 0.1 * params.port_length);
  }
  EXPECT_FALSE(run("zcoll_cpu", vitrector, identity, patch, options).colliding);
  // Truth: the patch does not touch the instrument.
  EXPECT_FALSE(run("fcl", vitrector, identity, patch, options).colliding);
}

TEST(ZcollLimits, NoSelfCollision) {
  // A self-intersecting surface (two crossing sheets) with the instrument far away: only instrument-vs-surface
  // contacts exist.
  TriangleMesh surface = plane(0.002, 10);
  TriangleMesh crossing = plane(0.002, 10);
  scene::transformMesh(crossing, Eigen::Isometry3d(Eigen::AngleAxisd(kPi / 2, Vector3d::UnitX())));
  scene::appendMesh(surface, crossing);
  for (const std::string name : {"zcoll_f_cpu", "zcoll_cpu", "geometric", "fcl"}) {
    const CollisionResult r = run(name, primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -0.0005), 0.0005)),
                                  pointingDown(Vector3d(0, 0, 0.01)), surface);
    EXPECT_FALSE(r.colliding) << name;
  }
}

// Alg. 4.1 (Myszkowski et al. 1995): a closed z-convex object A (here a rigid sphere) against the instrument. Unlike
// the one-pass surface variants it sees an instrument wholly inside A and an A wholly behind the instrument.
TEST(ZcollVolume, MyszkowskiTwoPassOnClosedObject) {
  const double small = 0.0002;
  const InstrumentModel instrument = primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -small), small));
  auto sphere_surface = [](const Vector3d& centre, double radius) {
    TriangleMesh mesh = primitiveMesh(Primitive::sphere(centre, radius), 48);
    return mesh;
  };
  const Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // instrument frame = object frame
  struct Case {
    const char* what;
    Vector3d centre;
    double radius;
    bool truth, zcoll_f;
  };
  const std::vector<Case> cases = {
      {"overlapping", Vector3d(0.00025, 0, -small), 0.0002, true, true},
      {"instrument inside A", Vector3d(0, 0, -small), 0.0008, true, true},  // A's back face behind the tip
      {"A behind the instrument", Vector3d(0, 0, -0.0011), 0.0003, false, true},
      {"A beside the instrument", Vector3d(0.0006, 0, -small), 0.0002, false, false},
  };
  CollisionOptions options;
  options.resolution = 64;
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const TriangleMesh object = sphere_surface(c.centre, c.radius);
    InstrumentModel wide = instrument;
    const CollisionResult volume = run("myszkowski_cpu", wide, pose, object, options);
    EXPECT_EQ(volume.colliding, c.truth);
    EXPECT_EQ(run("zcoll_f_cpu", wide, pose, object, options).colliding, c.zcoll_f);
    EXPECT_EQ((c.centre - Vector3d(0, 0, -small)).norm() < c.radius + small, c.truth);
    EXPECT_TRUE(volume.deformations.empty());
  }
}

TEST(CollisionBadInput, ClearStatusNoCrash) {
  const InstrumentModel sphere = primitiveInstrument(Primitive::sphere(Vector3d(0, 0, -0.0005), 0.0005));
  const TriangleMesh surface = plane(0.004, 10);
  const Eigen::Isometry3d pose = pointingDown(Vector3d(0, 0, -0.0002));
  for (const std::string& name : collisionDetectorNames()) {
    SCOPED_TRACE(name);
    auto detector = makeCollisionDetector(name);
    if (name != "none") {
      EXPECT_EQ(detector->collide(pose, SurfaceView::of(surface)).status, CollisionStatus::kNoInstrument);
    }
    detector->setInstrument(sphere);
    EXPECT_EQ(detector->collide(pose, SurfaceView::of(TriangleMesh{})).colliding, false);
    if (name == "none") continue;
    EXPECT_TRUE(detector->collide(pose, SurfaceView::of(surface)).colliding);
    EXPECT_EQ(detector->collide(pose, SurfaceView::of(TriangleMesh{})).status, CollisionStatus::kEmptyInput);
    Eigen::Isometry3d nan_pose = pose;
    nan_pose.translation().x() = std::numeric_limits<double>::quiet_NaN();
    const CollisionResult n = detector->collide(nan_pose, SurfaceView::of(surface));
    EXPECT_EQ(n.status, CollisionStatus::kInvalidInput);
    EXPECT_FALSE(n.colliding);
    TriangleMesh broken = surface;
    broken.vertices[3].z() = std::numeric_limits<double>::infinity();
    EXPECT_EQ(detector->collide(pose, SurfaceView::of(broken)).status, CollisionStatus::kInvalidInput);
    broken = surface;
    broken.triangles[0][1] = 100000;
    EXPECT_EQ(detector->collide(pose, SurfaceView::of(broken)).status, CollisionStatus::kInvalidInput);
    const CollisionResult far = detector->collide(pointingDown(Vector3d(1.0, 2.0, -0.0002)), SurfaceView::of(surface));
    EXPECT_FALSE(far.colliding);
    if (name.rfind("fcl", 0) != 0) {
      EXPECT_EQ(far.status, CollisionStatus::kOutsideVolume);
    }
    // Still working after the bad calls.
    EXPECT_TRUE(detector->collide(pose, SurfaceView::of(surface)).colliding);
  }
  // An instrument without triangles.
  auto detector = makeCollisionDetector("zcoll_f_cpu");
  detector->setInstrument(InstrumentModel{});
  EXPECT_EQ(detector->collide(pose, SurfaceView::of(surface)).status, CollisionStatus::kEmptyInput);
  EXPECT_THROW(makeCollisionDetector("rapid"), std::invalid_argument);
}

}  // namespace
}  // namespace collision
}  // namespace vrm_sim
