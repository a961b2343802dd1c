// Geometric properties of the procedural assets: retina, membrane, primitives and instruments.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "vrm_scene/meshes/eye_meshes.h"
#include "vrm_scene/meshes/instrument_meshes.h"
#include "vrm_scene/meshes/mesh_generators.h"
#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/mesh_validation.h"
#include "vrm_scene/meshes/primitive_meshes.h"

namespace vrm_sim {
namespace scene {
namespace {

constexpr double kPi = 3.14159265358979323846;

void expectClosedAndOutward(const TriangleMesh& mesh) {
  const MeshReport report = validateMesh(mesh);
  EXPECT_TRUE(report.isClosed()) << mesh.name << ": " << report.summary();
  EXPECT_EQ(report.degenerate_triangles, 0u) << mesh.name << ": " << report.summary();
  EXPECT_EQ(report.duplicate_vertices, 0u) << mesh.name << ": " << report.summary();
  EXPECT_GT(signedVolume(mesh), 0.0) << mesh.name;
}

// Number of times the line {origin + t * direction} crosses the mesh (Moeller-Trumbore on every triangle).
int lineCrossings(const TriangleMesh& mesh, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) {
  int crossings = 0;
  for (const auto& triangle : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices[triangle[0]];
    const Eigen::Vector3d edge1 = mesh.vertices[triangle[1]] - a, edge2 = mesh.vertices[triangle[2]] - a;
    const Eigen::Vector3d p = direction.cross(edge2);
    const double determinant = edge1.dot(p);
    if (std::abs(determinant) < 1e-20) continue;
    const Eigen::Vector3d s = origin - a;
    const double u = s.dot(p) / determinant;
    const Eigen::Vector3d q = s.cross(edge1);
    const double v = direction.dot(q) / determinant;
    if (u >= 0.0 && v >= 0.0 && u + v <= 1.0) ++crossings;
  }
  return crossings;
}

double maxRadiusFromZAxis(const TriangleMesh& mesh, double z_min, double z_max) {
  double radius = 0.0;
  for (const auto& vertex : mesh.vertices) {
    if (vertex.z() >= z_min && vertex.z() <= z_max) radius = std::max(radius, vertex.head<2>().norm());
  }
  return radius;
}

TEST(Retina, TriangleCountRadiusAndOrientation) {
  const RetinaParams params;
  const TriangleMesh retina = makeRetina(params);
  EXPECT_GE(retina.triangleCount(), 9000u);
  EXPECT_LE(retina.triangleCount(), 11000u);
  for (const auto& vertex : retina.vertices) {
    EXPECT_NEAR(vertex.norm(), 0.012, 1e-9);
    EXPECT_LE(vertex.z(), 1e-12);  // posterior hemisphere
  }
  // Every triangle faces the eye centre, so the vitreous side is the front face.
  for (std::size_t i = 0; i < retina.triangleCount(); ++i) {
    const auto& triangle = retina.triangles[i];
    const Eigen::Vector3d centroid =
        (retina.vertices[triangle[0]] + retina.vertices[triangle[1]] + retina.vertices[triangle[2]]) / 3.0;
    ASSERT_LT(triangleAreaVector(retina, i).dot(centroid), 0.0) << "triangle " << i;
  }
  const MeshReport report = validateMesh(retina);
  EXPECT_TRUE(report.isClean()) << report.summary();
  EXPECT_EQ(report.inconsistent_edges, 0u);
  // Open shell: the boundary is exactly the rim, and the rim is what is fixed.
  EXPECT_EQ(report.boundary_edges, retina.fixed_vertices.size());
  EXPECT_GT(retina.fixed_vertices.size(), 100u);
  for (std::uint32_t fixed : retina.fixed_vertices) EXPECT_NEAR(retina.vertices[fixed].z(), 0.0, 1e-12);
  // The area of a hemisphere, 2 pi r^2, to within the polyhedral approximation.
  EXPECT_NEAR(surfaceArea(retina), 2.0 * kPi * 0.012 * 0.012, 0.005 * 2.0 * kPi * 0.012 * 0.012);
}

TEST(Retina, TrianglesAreWellShaped) {
  const TriangleMesh retina = makeRetina({});
  double shortest = 1.0, longest = 0.0;
  for (const auto& triangle : retina.triangles) {
    for (int corner = 0; corner < 3; ++corner) {
      const double length = (retina.vertices[triangle[corner]] - retina.vertices[triangle[(corner + 1) % 3]]).norm();
      shortest = std::min(shortest, length);
      longest = std::max(longest, length);
    }
  }
  EXPECT_LT(longest / shortest, 3.0);  // no slivers at the posterior pole (unlike a latitude-longitude sphere)
}

TEST(Retina, IsDeterministic) {
  const TriangleMesh first = makeRetina({}), second = makeRetina({});
  EXPECT_EQ(first.triangles, second.triangles);
  EXPECT_EQ(first.vertices, second.vertices);
  EXPECT_EQ(first.fixed_vertices, second.fixed_vertices);
}

TEST(Retina, RejectsInvalidParameters) {
  RetinaParams params;
  params.coverage_deg = 180.0;
  EXPECT_THROW(makeRetina(params), std::invalid_argument);
  params = RetinaParams{};
  params.radius = std::nan("");
  EXPECT_THROW(makeRetina(params), std::invalid_argument);
}

TEST(Membrane, FollowsRetinaCurvatureAtHeight) {
  MembraneParams params;
  params.height_above_retina = 0.0004;
  params.centre_offset_deg = 10.0;
  params.centre_azimuth_deg = 90.0;
  const TriangleMesh membrane = makeMembrane(params);
  for (const auto& vertex : membrane.vertices) EXPECT_NEAR(vertex.norm(), 0.012 - 0.0004, 1e-9);
  // Centre (vertex 0) 10 deg from the posterior pole towards +y.
  const Eigen::Vector3d centre_direction = membrane.vertices[0].normalized();
  EXPECT_NEAR(std::acos(-centre_direction.z()) * 180.0 / kPi, 10.0, 1e-9);
  EXPECT_NEAR(centre_direction.x(), 0.0, 1e-12);
  EXPECT_GT(centre_direction.y(), 0.0);
  // Diameter along the surface: every vertex within half of it from the centre (geodesic on the membrane sphere).
  double farthest = 0.0;
  for (const auto& vertex : membrane.vertices) {
    farthest = std::max(farthest, std::acos(std::min(1.0, vertex.normalized().dot(centre_direction))) * vertex.norm());
  }
  EXPECT_NEAR(farthest, 0.5 * params.diameter, 1e-9);
  for (std::size_t i = 0; i < membrane.triangleCount(); ++i) {
    EXPECT_LT(triangleAreaVector(membrane, i).dot(membrane.vertices[membrane.triangles[i][0]]), 0.0);
  }
  EXPECT_TRUE(validateMesh(membrane).isClean()) << validateMesh(membrane).summary();
}

TEST(Membrane, AdhesionPoints) {
  MembraneParams params;
  params.adhesion_point_count = 7;
  params.adhesion_ring_fraction = 0.5;
  const TriangleMesh membrane = makeMembrane(params);
  ASSERT_EQ(membrane.fixed_vertices.size(), 7u);
  EXPECT_TRUE(std::is_sorted(membrane.fixed_vertices.begin(), membrane.fixed_vertices.end()));
  EXPECT_EQ(membrane.fixed_vertices[0], 0u);  // the centre
  const Eigen::Vector3d centre = membrane.vertices[0];
  for (std::size_t k = 1; k < membrane.fixed_vertices.size(); ++k) {
    const double distance = (membrane.vertices[membrane.fixed_vertices[k]] - centre).norm();
    EXPECT_NEAR(distance, 0.25 * params.diameter, 0.2 * 0.25 * params.diameter);
  }
  params.adhesion_point_count = 0;
  EXPECT_TRUE(makeMembrane(params).fixed_vertices.empty());
}

TEST(Membrane, ResolutionIsTunable) {
  MembraneParams coarse, fine;
  coarse.ring_count = 8;
  fine.ring_count = 24;
  EXPECT_LT(makeMembrane(coarse).triangleCount() * 4, makeMembrane(fine).triangleCount());
}

TEST(Primitives, ClosedWithOutwardNormalsAndExpectedVolume) {
  const double r = 0.001;
  SphereParams sphere;
  sphere.radius = r;
  sphere.ring_count = 24;
  const TriangleMesh sphere_mesh = makeSphere(sphere);
  expectClosedAndOutward(sphere_mesh);
  EXPECT_NEAR(signedVolume(sphere_mesh), 4.0 / 3.0 * kPi * r * r * r, 0.02 * 4.0 / 3.0 * kPi * r * r * r);
  for (const auto& vertex : sphere_mesh.vertices) EXPECT_NEAR(vertex.norm(), r, 1e-12);

  BoxParams box;
  box.size = Eigen::Vector3d(0.001, 0.002, 0.003);
  expectClosedAndOutward(makeBox(box));
  EXPECT_NEAR(signedVolume(makeBox(box)), 6e-9, 1e-18);

  CylinderParams cylinder;
  expectClosedAndOutward(makeCylinder(cylinder));
  EXPECT_NEAR(signedVolume(makeCylinder(cylinder)), kPi * 0.0005 * 0.0005 * 0.002,
              0.02 * kPi * 0.0005 * 0.0005 * 0.002);

  CapsuleParams capsule;
  expectClosedAndOutward(makeCapsule(capsule));
  capsule.length = 0.0;  // degenerates to a sphere: still closed
  expectClosedAndOutward(makeCapsule(capsule));

  ConeParams cone;
  expectClosedAndOutward(makeCone(cone));
  EXPECT_NEAR(signedVolume(makeCone(cone)), kPi * 0.0005 * 0.0005 * 0.001 / 3.0,
              0.02 * kPi * 0.0005 * 0.0005 * 0.001 / 3.0);

  TorusParams torus;
  expectClosedAndOutward(makeTorus(torus));
  const double torus_volume = 2.0 * kPi * kPi * torus.major_radius * torus.minor_radius * torus.minor_radius;
  EXPECT_NEAR(signedVolume(makeTorus(torus)), torus_volume, 0.03 * torus_volume);
}

TEST(Primitives, OpenSurfacesFacePlusZ) {
  for (const TriangleMesh& mesh : {makeDisc({}), makePlane({})}) {
    const MeshReport report = validateMesh(mesh);
    EXPECT_TRUE(report.isClean()) << mesh.name << ": " << report.summary();
    EXPECT_GT(report.boundary_edges, 0u);
    for (std::size_t i = 0; i < mesh.triangleCount(); ++i) EXPECT_GT(triangleAreaVector(mesh, i).z(), 0.0);
  }
  DiscParams disc;
  EXPECT_NEAR(surfaceArea(makeDisc(disc)), kPi * disc.radius * disc.radius, 0.01 * kPi * disc.radius * disc.radius);
  EXPECT_NEAR(surfaceArea(makePlane({})), 0.004 * 0.004, 1e-15);
}

TEST(Instruments, ClosedOutwardAndTipAtOrigin) {
  const std::vector<TriangleMesh> instruments = {makeLightPipe({}), makeForceps({}), makeVitrector({}), makeNeedle({}),
                                                 makeHook({})};
  for (const auto& mesh : instruments) {
    SCOPED_TRACE(mesh.name);
    const Eigen::AlignedBox3d box = boundingBox(mesh);
    EXPECT_NEAR(box.max().z(), 0.0, 1e-12);     // the most distal point is in the plane z = 0
    EXPECT_NEAR(box.min().z(), -0.030, 0.002);  // 30 mm shaft along -z
    if (mesh.name == "forceps") {
      // Shaft and jaws are separate closed parts that touch: check each part instead of the union.
      const ForcepsMeshes parts = makeForcepsParts({});
      for (const auto* part : {&parts.shaft, &parts.upper_jaw, &parts.lower_jaw}) expectClosedAndOutward(*part);
    } else {
      expectClosedAndOutward(mesh);
    }
  }
}

TEST(Instruments, ShaftDiameterIs23Gauge) {
  for (const TriangleMesh& mesh : {makeLightPipe({}), makeForceps({}), makeVitrector({}), makeHook({})}) {
    SCOPED_TRACE(mesh.name);
    // The proximal end ring belongs to the plain shaft in every instrument.
    EXPECT_NEAR(2.0 * maxRadiusFromZAxis(mesh, -1.0, -0.01), 0.0006, 1e-12);
    if (mesh.name != "hook") {  // the hook bends sideways by design
      EXPECT_NEAR(2.0 * maxRadiusFromZAxis(mesh, -1.0, 1.0), 0.0006, 1e-12);
    }
  }
  EXPECT_NEAR(2.0 * maxRadiusFromZAxis(makeNeedle({}), -1.0, 1.0), 0.0004, 1e-12);
}

TEST(Instruments, LightPipeTipIsRoundedToThePole) {
  const TriangleMesh light_pipe = makeLightPipe({});
  EXPECT_EQ(std::count_if(light_pipe.vertices.begin(), light_pipe.vertices.end(),
                          [](const Eigen::Vector3d& vertex) { return vertex.z() > -1e-12; }),
            1);
}

TEST(Instruments, ForcepsJawsOpenWithAngle) {
  ForcepsParams params;
  const ForcepsMeshes closed = makeForcepsParts(params);
  EXPECT_NEAR(boundingBox(closed.upper_jaw).max().z(), 0.0, 1e-12);
  EXPECT_NEAR(boundingBox(closed.upper_jaw).min().y(), 0.0, 1e-12);  // jaws meet in the plane y = 0
  EXPECT_NEAR(boundingBox(closed.lower_jaw).max().y(), 0.0, 1e-12);

  params.jaw_angle_deg = 40.0;
  const ForcepsMeshes open = makeForcepsParts(params);
  const double tip_gap = boundingBox(open.upper_jaw).max().y() - boundingBox(open.lower_jaw).min().y();
  EXPECT_GT(tip_gap, 2.0 * params.jaw_length * std::sin(20.0 * kPi / 180.0));
  EXPECT_LT(boundingBox(open.upper_jaw).max().z(), 0.0);  // opening swings the jaws back
  expectClosedAndOutward(open.upper_jaw);
  expectClosedAndOutward(open.lower_jaw);
  // Upper and lower jaw are mirror images in y.
  for (std::size_t i = 0; i < open.upper_jaw.vertexCount(); ++i) {
    const Eigen::Vector3d mirrored(open.upper_jaw.vertices[i].x(), -open.upper_jaw.vertices[i].y(),
                                   open.upper_jaw.vertices[i].z());
    EXPECT_TRUE(mirrored.isApprox(open.lower_jaw.vertices[i], 1e-12));
  }
  EXPECT_EQ(makeForceps(params).triangleCount(),
            open.shaft.triangleCount() + open.upper_jaw.triangleCount() + open.lower_jaw.triangleCount());
}

TEST(Instruments, VitrectorPortMakesItNonZConvex) {
  const VitrectorParams params;
  const TriangleMesh vitrector = makeVitrector(params);
  const double radius = 0.5 * params.shaft.diameter;
  // A line along the shaft through the pocket enters the tip, leaves into the port, re-enters behind it and leaves
  // at the handle end: two intervals, i.e. not z-convex (thesis §4.2).
  const Eigen::Vector3d through_port(radius - 0.5 * params.port_depth, 0.0, 1.0);
  EXPECT_EQ(lineCrossings(vitrector, through_port, Eigen::Vector3d::UnitZ()), 4);
  // Away from the port the shaft is an ordinary solid: one interval.
  const Eigen::Vector3d opposite_port(-(radius - 0.5 * params.port_depth), 0.0, 1.0);
  EXPECT_EQ(lineCrossings(vitrector, opposite_port, Eigen::Vector3d::UnitZ()), 2);
}

TEST(Instruments, NeedleBevel) {
  const NeedleParams params;
  const TriangleMesh needle = makeNeedle(params);
  const Eigen::Vector3d point = needlePoint(params);
  EXPECT_NEAR(point.z(), 0.0, 1e-15);
  const bool point_is_vertex =
      std::any_of(needle.vertices.begin(), needle.vertices.end(),
                  [&point](const Eigen::Vector3d& vertex) { return (vertex - point).norm() < 1e-12; });
  EXPECT_TRUE(point_is_vertex);
  // The heel of the bevel lies 2r / tan(bevel angle) behind the point on the opposite side.
  const double radius = 0.5 * params.shaft.diameter;
  const double heel_z = -2.0 * radius / std::tan(params.bevel_angle_deg * kPi / 180.0);
  double heel_found = 1.0;
  for (const auto& vertex : needle.vertices) {
    if (std::abs(vertex.x() - radius) < 1e-12 && vertex.z() > -0.01) heel_found = vertex.z();
  }
  EXPECT_NEAR(heel_found, heel_z, 1e-12);
}

TEST(Instruments, HookTipIsBentSideways) {
  const HookParams params;
  const Eigen::Vector3d tip = hookTipPoint(params);
  EXPECT_GT(tip.x(), params.bend_radius);  // bent towards +x by 90 deg
  EXPECT_LE(tip.z(), 0.0);
  const TriangleMesh hook = makeHook(params);
  EXPECT_TRUE(std::any_of(hook.vertices.begin(), hook.vertices.end(),
                          [&tip](const Eigen::Vector3d& vertex) { return (vertex - tip).norm() < 1e-12; }));
}

TEST(Generators, NamesDefaultsAndDispatch) {
  const std::vector<std::string>& names = generatorNames();
  EXPECT_EQ(names.size(), 16u);
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
  for (const auto& name : names) {
    const std::optional<GeneratorParams> params = defaultGeneratorParams(name);
    ASSERT_TRUE(params.has_value()) << name;
    EXPECT_EQ(generatorName(*params), name);
    const TriangleMesh mesh = generateMesh(*params);
    EXPECT_TRUE(validateMesh(mesh).isUsable()) << name;
    EXPECT_EQ(validateMesh(mesh).degenerate_triangles, 0u) << name;
  }
  EXPECT_FALSE(defaultGeneratorParams("teapot").has_value());
}

}  // namespace
}  // namespace scene
}  // namespace vrm_sim
