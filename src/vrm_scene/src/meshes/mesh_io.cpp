#include "vrm_scene/meshes/mesh_io.h"

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <assimp/Importer.hpp>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>

#include "mesh_import_wire.h"

// assimp 5.2 as Debian builds it keeps its ai_assert checks, and a failed one calls Assimp::aiAssertViolation, which
// aborts: one malformed mesh file would end the nodelet manager (fuzz_mesh_import found several PLY files that reach
// TriangulateProcess's assert). The function is exported and called through the PLT, so this definition takes its
// place in every process that links vrm_scene, and a failed assert becomes an exception that assimp's ReadFile turns
// into an import error (or that reaches importMesh), like any other broken file.
namespace Assimp {
[[noreturn]] void aiAssertViolation(const char* failed, const char* file, int line) {
  throw std::runtime_error(std::string("assimp internal check failed: ") + failed + " (" + file + ":" +
                           std::to_string(line) + ")");
}
}  // namespace Assimp

namespace vrm_sim {
namespace scene {
namespace {

std::string describeVertex(const aiVector3D& vertex) {
  std::ostringstream text;
  text << "(" << vertex.x << ", " << vertex.y << ", " << vertex.z << ")";
  return text.str();
}

// Maps bit-for-bit equal positions (value equality, so -0 == +0) to the first vertex that had them.
void joinIdenticalVertices(TriangleMesh& mesh) {
  std::map<std::array<double, 3>, std::uint32_t> first_at_position;
  std::vector<std::uint32_t> remap(mesh.vertices.size());
  std::vector<Eigen::Vector3d> kept;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3d& vertex = mesh.vertices[i];
    const auto inserted = first_at_position.emplace(std::array<double, 3>{vertex.x(), vertex.y(), vertex.z()},
                                                    static_cast<std::uint32_t>(kept.size()));
    if (inserted.second) kept.push_back(vertex);
    remap[i] = inserted.first->second;
  }
  for (auto& triangle : mesh.triangles) {
    for (auto& index : triangle) index = remap[index];
  }
  mesh.vertices = std::move(kept);
}

// assimp's PLY reader does not return on some malformed headers (a NUL byte in a comment and no end_header: a
// 136-byte file kept it busy for over a minute; found by fuzz_mesh_import, issue 14 §1). A PLY file must start with
// a text header that declares its elements and ends in "end_header"; one that does not is refused here, before
// assimp sees it.
bool plyType(const std::string& type) {
  for (const char* known : {"char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8",
                            "int16", "uint16", "int32", "uint32", "float32", "float64"}) {
    if (type == known) return true;
  }
  return false;
}

// "property TYPE NAME" or "property list COUNT_TYPE ITEM_TYPE NAME".
bool plyPropertyKnown(const std::string& line) {
  std::istringstream words(line);
  std::string keyword, type, second, third, rest;
  words >> keyword >> type >> second >> third >> rest;
  if (type == "list") return plyType(second) && plyType(third) && !rest.empty() && !(words >> rest);
  return plyType(type) && !second.empty() && third.empty();
}

std::string plyHeaderProblem(const std::string& path) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) return "";  // assimp reports unreadable files
  std::string head(64 * 1024, '\0');
  head.resize(std::fread(head.data(), 1, head.size(), file));
  std::fclose(file);
  // assimp also takes a file for PLY when "ply" comes a few bytes in (or by the extension), and then aborts on an
  // ai_assert in its triangulation for such garbage (found by fuzz_mesh_import): a PLY file starts with "ply".
  const std::string extension = std::filesystem::path(path).extension().string();
  const bool ply_extension = extension.size() == 4 && std::tolower(extension[1]) == 'p' &&
                             std::tolower(extension[2]) == 'l' && std::tolower(extension[3]) == 'y';
  if (head.compare(0, 3, "ply") != 0) {
    if (ply_extension || head.substr(0, 16).find("ply") != std::string::npos) {
      return "not a PLY file: it does not start with 'ply'";
    }
    return "";
  }
  std::size_t end = head.find("\nend_header\n");
  if (end == std::string::npos) end = head.find("\nend_header\r\n");
  if (end == std::string::npos) return "PLY header without an end_header line in its first 64 KiB";
  ++end;  // at "end_header"
  if (head.find("\nelement vertex ") > end) return "PLY header declares no vertex element";
  // Nor does it return on a header that declares no element, or has a line it does not know (a misspelt
  // "property"): the second and third fuzz_mesh_import timeouts. Every header line must be one of the PLY keywords.
  if (head.find("\nelement ") > end) return "PLY header declares no element";
  std::size_t line = head.find('\n');
  while (line != std::string::npos && line + 1 < end) {
    const std::size_t next = head.find('\n', line + 1);
    const std::string text = head.substr(line + 1, (next == std::string::npos ? end : next) - line - 1);
    bool known = false;
    for (const char* keyword : {"format ", "comment", "obj_info", "element ", "property ", "end_header"}) {
      known = known || text.compare(0, std::strlen(keyword), keyword) == 0;
    }
    if (!known && !text.empty() && text != "\r") return "PLY header line '" + text.substr(0, 40) + "' is not PLY";
    // A property of an unknown type ("property fii 1.0") reaches an ai_assert in assimp's triangulation.
    if (text.compare(0, 9, "property ") == 0 && !plyPropertyKnown(text)) {
      return "PLY header line '" + text.substr(0, 40) + "' declares a property of an unknown type";
    }
    line = next;
  }
  // An ASCII PLY has no control bytes in its body either (assimp's triangulation asserts on some).
  const bool ascii = head.find("format ascii") < end;
  const std::size_t checked = ascii ? head.size() : end;
  for (std::size_t i = 0; i < checked; ++i) {
    const unsigned char c = static_cast<unsigned char>(head[i]);
    if ((c < 0x20 && c != '\n' && c != '\r' && c != '\t') || (ascii && c > 0x7e)) {
      return std::string(i < end ? "PLY header" : "ASCII PLY") + " with a control or non-ASCII byte at offset " +
             std::to_string(i);
    }
  }
  return "";
}

}  // namespace

MeshIoError::MeshIoError(const std::string& path, const std::string& problem)
    : std::runtime_error(path + ": " + problem), path_(path) {}

void checkImportRequest(const std::string& path, const MeshImportOptions& options) {
  std::error_code error;
  if (!std::filesystem::exists(path, error)) throw MeshIoError(path, "file not found");
  if (!std::filesystem::is_regular_file(path, error)) throw MeshIoError(path, "not a regular file");
  if (!(options.scale > 0.0) || !std::isfinite(options.scale)) {
    throw MeshIoError(path, "the import scale must be a positive finite number");
  }
}

TriangleMesh importMeshInProcess(const std::string& path, const MeshImportOptions& options) {
  checkImportRequest(path, options);
  if (const std::string problem = plyHeaderProblem(path); !problem.empty()) {
    throw MeshIoError(path, "cannot import: " + problem);
  }

  Assimp::Importer importer;
  // ValidateDataStructure turns out-of-range indices into an import error instead of a crash later on.
  const aiScene* scene = nullptr;
  try {
    scene = importer.ReadFile(path,
                              aiProcess_Triangulate | aiProcess_PreTransformVertices | aiProcess_ValidateDataStructure);
  } catch (const std::exception& failure) {
    throw MeshIoError(path, std::string("cannot import: ") + failure.what());
  }
  if (scene == nullptr) throw MeshIoError(path, std::string("cannot import: ") + importer.GetErrorString());

  TriangleMesh mesh;
  mesh.name = options.name.empty() ? std::filesystem::path(path).stem().string() : options.name;
  for (unsigned mesh_index = 0; mesh_index < scene->mNumMeshes; ++mesh_index) {
    const aiMesh* part = scene->mMeshes[mesh_index];
    const auto offset = static_cast<std::uint32_t>(mesh.vertices.size());
    for (unsigned i = 0; i < part->mNumVertices; ++i) {
      const aiVector3D& vertex = part->mVertices[i];
      if (!std::isfinite(vertex.x) || !std::isfinite(vertex.y) || !std::isfinite(vertex.z)) {
        throw MeshIoError(path, "vertex " + std::to_string(i) + " of mesh " + std::to_string(mesh_index) +
                                    " has a non-finite coordinate " + describeVertex(vertex));
      }
      mesh.vertices.emplace_back(options.scale * static_cast<double>(vertex.x),
                                 options.scale * static_cast<double>(vertex.y),
                                 options.scale * static_cast<double>(vertex.z));
    }
    for (unsigned f = 0; f < part->mNumFaces; ++f) {
      const aiFace& face = part->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines carry no surface
      std::array<std::uint32_t, 3> triangle;
      for (int corner = 0; corner < 3; ++corner) {
        if (face.mIndices[corner] >= part->mNumVertices) {
          throw MeshIoError(path, "face " + std::to_string(f) + " refers to vertex " +
                                      std::to_string(face.mIndices[corner]) + " but the mesh has only " +
                                      std::to_string(part->mNumVertices));
        }
        triangle[corner] = offset + face.mIndices[corner];
      }
      mesh.triangles.push_back(triangle);
    }
  }
  if (mesh.triangles.empty()) throw MeshIoError(path, "contains no triangles");
  if (options.join_identical_vertices) joinIdenticalVertices(mesh);
  return mesh;
}

void writeObj(const TriangleMesh& mesh, const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "w"), &std::fclose);
  if (!file) throw MeshIoError(path, std::string("cannot open for writing: ") + std::strerror(errno));
  const bool write_normals = !mesh.normals.empty() && mesh.normals.size() == mesh.vertices.size();
  std::fprintf(file.get(), "# %s: %zu vertices, %zu triangles (written by vrm_sim)\n", mesh.name.c_str(),
               mesh.vertices.size(), mesh.triangles.size());
  if (!mesh.name.empty()) std::fprintf(file.get(), "o %s\n", mesh.name.c_str());
  for (const auto& vertex : mesh.vertices) {
    std::fprintf(file.get(), "v %.17g %.17g %.17g\n", vertex.x(), vertex.y(), vertex.z());
  }
  if (write_normals) {
    for (const auto& normal : mesh.normals) {
      std::fprintf(file.get(), "vn %.17g %.17g %.17g\n", normal.x(), normal.y(), normal.z());
    }
  }
  if (!mesh.fixed_vertices.empty()) {
    std::fprintf(file.get(), "# fixed_vertices");
    for (std::uint32_t fixed : mesh.fixed_vertices) std::fprintf(file.get(), " %u", fixed + 1);
    std::fprintf(file.get(), "\n");
  }
  for (const auto& triangle : mesh.triangles) {
    for (std::uint32_t index : triangle) {
      if (index >= mesh.vertices.size()) {
        throw MeshIoError(
            path, "triangle refers to vertex " + std::to_string(index) + " of " + std::to_string(mesh.vertices.size()));
      }
    }
    if (write_normals) {
      std::fprintf(file.get(), "f %u//%u %u//%u %u//%u\n", triangle[0] + 1, triangle[0] + 1, triangle[1] + 1,
                   triangle[1] + 1, triangle[2] + 1, triangle[2] + 1);
    } else {
      std::fprintf(file.get(), "f %u %u %u\n", triangle[0] + 1, triangle[1] + 1, triangle[2] + 1);
    }
  }
  if (std::ferror(file.get()) != 0) throw MeshIoError(path, "write failed");
  if (std::fclose(file.release()) != 0) throw MeshIoError(path, "write failed on close");
}

}  // namespace scene
}  // namespace vrm_sim
