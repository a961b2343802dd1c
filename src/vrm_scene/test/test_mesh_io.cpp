// Mesh import through assimp (OBJ, PLY, STL), its error cases, and the writeObj -> importMesh round trip.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>

#include "vrm_scene/meshes/eye_meshes.h"
#include "vrm_scene/meshes/instrument_meshes.h"
#include "vrm_scene/meshes/mesh_io.h"
#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/mesh_validation.h"

namespace vrm_sim {
namespace scene {
namespace {

const std::string kMeshDir = std::string(VRM_SCENE_SOURCE_DIR) + "/test/data/meshes/";

std::string importError(const std::string& file) {
  try {
    importMesh(kMeshDir + file);
  } catch (const MeshIoError& error) {
    EXPECT_EQ(error.path(), kMeshDir + file);
    return error.what();
  }
  ADD_FAILURE() << "expected a MeshIoError for " << file;
  return "";
}

// A unique temporary file, removed at the end of the test.
class TemporaryFile {
 public:
  explicit TemporaryFile(const std::string& suffix)
      : path_((std::filesystem::temp_directory_path() /
               ("vrm_scene_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name() + suffix))
                  .string()) {}
  ~TemporaryFile() { std::remove(path_.c_str()); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// The triangles of `copy` expressed in the vertex indices of `original` (matching positions within `tolerance`),
// each rotated to start at its smallest index (keeps the orientation), sorted: equal for meshes that differ only
// in vertex order and float rounding.
std::vector<std::array<std::uint32_t, 3>> canonicalTriangles(const TriangleMesh& copy, const TriangleMesh& original,
                                                             double tolerance) {
  std::vector<std::uint32_t> original_index(copy.vertexCount(), ~0u);
  for (std::size_t i = 0; i < copy.vertexCount(); ++i) {
    for (std::size_t j = 0; j < original.vertexCount(); ++j) {
      if ((copy.vertices[i] - original.vertices[j]).norm() <= tolerance) {
        original_index[i] = static_cast<std::uint32_t>(j);
        break;
      }
    }
    EXPECT_NE(original_index[i], ~0u) << "vertex " << i << " has no counterpart";
  }
  std::vector<std::array<std::uint32_t, 3>> triangles;
  for (const auto& triangle : copy.triangles) {
    std::array<std::uint32_t, 3> mapped = {original_index[triangle[0]], original_index[triangle[1]],
                                           original_index[triangle[2]]};
    std::rotate(mapped.begin(), std::min_element(mapped.begin(), mapped.end()), mapped.end());
    triangles.push_back(mapped);
  }
  std::sort(triangles.begin(), triangles.end());
  return triangles;
}

TEST(MeshImport, ObjQuadsAreTriangulatedAndJoined) {
  MeshImportOptions options;
  options.scale = 0.001;
  const TriangleMesh mesh = importMesh(kMeshDir + "cube_quads.obj", options);
  EXPECT_EQ(mesh.name, "cube_quads");
  EXPECT_EQ(mesh.vertexCount(), 8u);
  EXPECT_EQ(mesh.triangleCount(), 12u);
  EXPECT_TRUE(mesh.normals.empty());
  const MeshReport report = validateMesh(mesh);
  EXPECT_TRUE(report.isClean()) << report.summary();
  EXPECT_TRUE(report.isClosed()) << report.summary();
  EXPECT_NEAR(signedVolume(mesh), 1e-9, 1e-15);
  EXPECT_NEAR(boundingBox(mesh).max().x(), 0.001, 1e-12);
}

TEST(MeshImport, WithoutJoiningObjKeepsOneVertexPerCorner) {
  MeshImportOptions options;
  options.join_identical_vertices = false;
  options.name = "loose";
  const TriangleMesh mesh = importMesh(kMeshDir + "cube_quads.obj", options);
  EXPECT_EQ(mesh.name, "loose");
  EXPECT_GT(mesh.vertexCount(), 8u);
  EXPECT_GT(validateMesh(mesh).duplicate_vertices, 0u);
}

TEST(MeshImport, Ply) {
  const TriangleMesh mesh = importMesh(kMeshDir + "tetrahedron.ply");
  EXPECT_EQ(mesh.vertexCount(), 4u);
  EXPECT_EQ(mesh.triangleCount(), 4u);
  EXPECT_TRUE(validateMesh(mesh).isClosed());
  EXPECT_NEAR(signedVolume(mesh), 1.0 / 6.0, 1e-7);
}

TEST(MeshImport, AsciiStlIsWelded) {
  const TriangleMesh mesh = importMesh(kMeshDir + "tetrahedron_ascii.stl");
  EXPECT_EQ(mesh.vertexCount(), 4u);  // 12 corners in the file
  EXPECT_EQ(mesh.triangleCount(), 4u);
  const MeshReport report = validateMesh(mesh);
  EXPECT_TRUE(report.isClosed()) << report.summary();
  EXPECT_NEAR(signedVolume(mesh), 1.0 / 6.0, 1e-7);
}

TEST(MeshImport, DegenerateTriangleIsImportedAndReported) {
  const TriangleMesh mesh = importMesh(kMeshDir + "degenerate.obj");
  EXPECT_EQ(mesh.triangleCount(), 3u);
  EXPECT_EQ(validateMesh(mesh).degenerate_triangles, 1u);
}

TEST(MeshImportErrors, MissingFile) {
  const std::string message = importError("no_such_file.obj");
  EXPECT_NE(message.find("no_such_file.obj: file not found"), std::string::npos) << message;
}

TEST(MeshImportErrors, MalformedObj) {
  const std::string message = importError("malformed.obj");
  EXPECT_NE(message.find("malformed.obj: cannot import"), std::string::npos) << message;
}

TEST(MeshImportErrors, NanVertex) {
  const std::string message = importError("nan_vertex.obj");
  EXPECT_NE(message.find("nan_vertex.obj: "), std::string::npos) << message;
  EXPECT_NE(message.find("non-finite coordinate"), std::string::npos) << message;
}

TEST(MeshImportErrors, IndexOutOfRange) {
  const std::string message = importError("bad_index.obj");
  EXPECT_NE(message.find("bad_index.obj: "), std::string::npos) << message;
  EXPECT_NE(message.find("index out of range"), std::string::npos) << message;
}

TEST(MeshImportErrors, NoTriangles) {
  const std::string message = importError("empty.obj");
  EXPECT_NE(message.find("empty.obj: "), std::string::npos) << message;
}

TEST(MeshImportErrors, UnsupportedFormat) {
  TemporaryFile file(".xyz123");
  std::FILE* handle = std::fopen(file.path().c_str(), "w");
  ASSERT_NE(handle, nullptr);
  std::fputs("hello\n", handle);
  std::fclose(handle);
  EXPECT_THROW(importMesh(file.path()), MeshIoError);
}

TEST(MeshImportErrors, InvalidScale) {
  MeshImportOptions options;
  options.scale = -1.0;
  EXPECT_THROW(importMesh(kMeshDir + "tetrahedron.ply", options), MeshIoError);
}

// --- the helper process (issue 39): same result as in this process; a hang, a crash, a bad reply are errors ---

TEST(MeshImportHelper, SameMeshAsInProcess) {
  for (const char* file : {"cube_quads.obj", "tetrahedron.ply", "tetrahedron_ascii.stl", "degenerate.obj"}) {
    for (const bool join : {true, false}) {
      MeshImportOptions options;
      options.scale = 0.001;
      options.join_identical_vertices = join;
      const TriangleMesh helper = importMesh(kMeshDir + file, options);
      const TriangleMesh here = importMeshInProcess(kMeshDir + file, options);
      EXPECT_EQ(helper.name, here.name) << file;
      EXPECT_EQ(helper.triangles, here.triangles) << file;
      ASSERT_EQ(helper.vertices.size(), here.vertices.size()) << file;
      for (std::size_t i = 0; i < here.vertices.size(); ++i) {
        EXPECT_EQ(helper.vertices[i], here.vertices[i]) << file << " vertex " << i;  // bit for bit
      }
    }
  }
}

TEST(MeshImportHelper, ErrorsReadAsInProcess) {
  for (const char* file : {"malformed.obj", "nan_vertex.obj", "bad_index.obj", "empty.obj"}) {
    std::string helper_error, here_error;
    try {
      importMesh(kMeshDir + file);
    } catch (const MeshIoError& error) {
      helper_error = error.what();
    }
    try {
      importMeshInProcess(kMeshDir + file);
    } catch (const MeshIoError& error) {
      here_error = error.what();
    }
    EXPECT_FALSE(here_error.empty()) << file;
    EXPECT_EQ(helper_error, here_error) << file;
  }
}

// A stand-in for the helper (a shell script), set through VRM_MESH_IMPORT_HELPER for one test.
class FakeHelper {
 public:
  explicit FakeHelper(const std::string& body) : script_(".sh") {
    std::FILE* handle = std::fopen(script_.path().c_str(), "w");
    std::fprintf(handle, "#!/bin/sh\n%s\n", body.c_str());
    std::fclose(handle);
    std::filesystem::permissions(script_.path(), std::filesystem::perms::owner_all);
    setenv("VRM_MESH_IMPORT_HELPER", script_.path().c_str(), 1);
  }
  ~FakeHelper() { unsetenv("VRM_MESH_IMPORT_HELPER"); }

 private:
  TemporaryFile script_;
};

std::string helperError(const MeshImportOptions& options = {}) {
  try {
    importMesh(kMeshDir + "tetrahedron.ply", options);
  } catch (const MeshIoError& error) {
    return error.what();
  }
  return "no error";
}

TEST(MeshImportHelper, HangingImporterIsStoppedAtTheTimeLimit) {
  FakeHelper helper("exec sleep 60");
  MeshImportOptions options;
  options.time_limit = 0.3;
  const auto start = std::chrono::steady_clock::now();
  const std::string error = helperError(options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_NE(error.find("did not finish within 0.3 s"), std::string::npos) << error;
  EXPECT_GE(seconds, 0.3);
  EXPECT_LT(seconds, 5.0);
}

TEST(MeshImportHelper, CrashingImporterIsAnError) {
  FakeHelper helper("echo 'half a line' >&2; kill -SEGV $$");
  const std::string error = helperError();
  EXPECT_NE(error.find("died of signal 11"), std::string::npos) << error;
  EXPECT_NE(error.find("half a line"), std::string::npos) << error;
}

TEST(MeshImportHelper, MalformedReplyIsAnError) {
  FakeHelper helper("printf 'VRMMESH1garbage'");
  EXPECT_NE(helperError().find("reply is malformed"), std::string::npos) << helperError();
}

TEST(MeshImportHelper, MissingHelperIsNamed) {
  setenv("VRM_MESH_IMPORT_HELPER", "/nonexistent/vrm_mesh_import", 1);
  const std::string error = helperError();
  unsetenv("VRM_MESH_IMPORT_HELPER");
  EXPECT_NE(error.find("'/nonexistent/vrm_mesh_import' is missing"), std::string::npos) << error;
}

TEST(MeshExport, RoundTripOfGeneratedMeshes) {
  RetinaParams retina_params;
  retina_params.ring_count = 12;
  // (Not the merged forceps: its closed jaws share positions, which importMesh() rightly joins.)
  for (const TriangleMesh& original : {makeRetina(retina_params), makeVitrector({}), makeMembrane({})}) {
    TemporaryFile file("_" + original.name + ".obj");
    writeObj(original, file.path());
    const TriangleMesh copy = importMesh(file.path());
    EXPECT_EQ(copy.vertexCount(), original.vertexCount()) << original.name;
    EXPECT_EQ(copy.triangleCount(), original.triangleCount()) << original.name;
    // assimp reads single precision: positions agree to ~1e-9 m, far below any edge length.
    EXPECT_EQ(canonicalTriangles(copy, original, 1e-8), canonicalTriangles(original, original, 0.0)) << original.name;
    EXPECT_NEAR(signedVolume(copy), signedVolume(original), 1e-6 * std::abs(signedVolume(original)));
  }
}

TEST(MeshExport, WritesNormalsAndFixedVertices) {
  TriangleMesh mesh = makeMembrane({});
  computeVertexNormals(mesh);
  TemporaryFile file(".obj");
  writeObj(mesh, file.path());
  const TriangleMesh copy = importMesh(file.path());
  EXPECT_EQ(copy.vertexCount(), mesh.vertexCount());
  std::FILE* handle = std::fopen(file.path().c_str(), "r");
  ASSERT_NE(handle, nullptr);
  std::string content(1 << 20, '\0');
  content.resize(std::fread(&content[0], 1, content.size(), handle));
  std::fclose(handle);
  EXPECT_NE(content.find("\nvn "), std::string::npos);
  EXPECT_NE(content.find("# fixed_vertices 1 "), std::string::npos);  // the centre vertex, 1-based
}

TEST(MeshExport, UnwritablePathNamesTheFile) {
  try {
    writeObj(makeRetina({}), "/nonexistent_directory/retina.obj");
    FAIL() << "no error";
  } catch (const MeshIoError& error) {
    EXPECT_NE(std::string(error.what()).find("/nonexistent_directory/retina.obj: cannot open"), std::string::npos);
  }
}

}  // namespace
}  // namespace scene
}  // namespace vrm_sim
