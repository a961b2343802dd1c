// importMesh(): assimp in a helper process with a time limit (issue 39). Why a process and not a thread: a thread
// stuck in an importer loop cannot be stopped, and a crash in it takes the nodelet manager down. Why posix_spawn and
// not fork: the caller is multi-threaded (roscpp's spinners, the nodelet workers); a forked copy of such a process may
// hold another thread's locks, while posix_spawn runs exec at once.

#include <dlfcn.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "mesh_import_wire.h"
#include "vrm_scene/meshes/mesh_io.h"

extern char** environ;

namespace vrm_sim {
namespace scene {

std::string encodeMeshReply(const TriangleMesh& mesh) {
  const std::uint64_t counts[2] = {mesh.vertices.size(), mesh.triangles.size()};
  std::string bytes(kMeshReplyMagic, sizeof(kMeshReplyMagic));
  bytes.append(reinterpret_cast<const char*>(counts), sizeof(counts));
  for (const Eigen::Vector3d& vertex : mesh.vertices) {
    bytes.append(reinterpret_cast<const char*>(vertex.data()), 3 * sizeof(double));
  }
  for (const auto& triangle : mesh.triangles) {
    bytes.append(reinterpret_cast<const char*>(triangle.data()), 3 * sizeof(std::uint32_t));
  }
  return bytes;
}

std::string decodeMeshReply(const std::string& bytes, TriangleMesh* mesh) {
  constexpr std::size_t kHeader = sizeof(kMeshReplyMagic) + 2 * sizeof(std::uint64_t);
  if (bytes.size() < kHeader || std::memcmp(bytes.data(), kMeshReplyMagic, sizeof(kMeshReplyMagic)) != 0) {
    return "the reply does not start with a mesh header (" + std::to_string(bytes.size()) + " bytes)";
  }
  std::uint64_t counts[2];
  std::memcpy(counts, bytes.data() + sizeof(kMeshReplyMagic), sizeof(counts));
  const std::size_t vertex_bytes = 3 * sizeof(double), triangle_bytes = 3 * sizeof(std::uint32_t);
  const std::size_t payload = bytes.size() - kHeader;
  if (counts[0] > payload / vertex_bytes || counts[1] > payload / triangle_bytes ||
      counts[0] * vertex_bytes + counts[1] * triangle_bytes != payload) {
    return "the reply's counts (" + std::to_string(counts[0]) + " vertices, " + std::to_string(counts[1]) +
           " triangles) do not match its " + std::to_string(payload) + " bytes";
  }
  const char* cursor = bytes.data() + kHeader;
  mesh->vertices.resize(counts[0]);
  for (Eigen::Vector3d& vertex : mesh->vertices) {
    std::memcpy(vertex.data(), cursor, vertex_bytes);
    cursor += vertex_bytes;
  }
  mesh->triangles.resize(counts[1]);
  for (auto& triangle : mesh->triangles) {
    std::memcpy(triangle.data(), cursor, triangle_bytes);
    cursor += triangle_bytes;
    for (std::uint32_t index : triangle) {
      if (index >= counts[0]) return "the reply's triangles refer to vertex " + std::to_string(index);
    }
  }
  return "";
}

std::string meshImportHelperPath() {
  if (const char* configured = std::getenv("VRM_MESH_IMPORT_HELPER"); configured != nullptr && *configured) {
    return configured;
  }
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&meshImportHelperPath), &info) == 0 || info.dli_fname == nullptr) return "";
  std::error_code error;
  const std::filesystem::path library = std::filesystem::canonical(info.dli_fname, error);
  if (error) return "";
  return (library.parent_path() / "vrm_scene" / "vrm_mesh_import").string();
}

namespace {

struct Pipe {
  int read = -1, write = -1;
  Pipe() {
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error(std::string("pipe2: ") + std::strerror(errno));
    read = fds[0];
    write = fds[1];
  }
  ~Pipe() {
    if (read >= 0) close(read);
    if (write >= 0) close(write);
  }
  void closeWrite() {
    close(write);
    write = -1;
  }
};

std::string describeStatus(int status) {
  if (WIFSIGNALED(status)) {
    const char* name = strsignal(WTERMSIG(status));
    return "the importer died of signal " + std::to_string(WTERMSIG(status)) + " (" + (name ? name : "?") + ")";
  }
  return "the importer exited with status " + std::to_string(WEXITSTATUS(status));
}

}  // namespace

TriangleMesh importMesh(const std::string& path, const MeshImportOptions& options) {
  checkImportRequest(path, options);  // what needs no importer is refused here, with importMeshInProcess's words
  if (!(options.time_limit > 0.0)) throw MeshIoError(path, "the import time limit must be positive");
  const std::string helper = meshImportHelperPath();
  if (helper.empty() || access(helper.c_str(), X_OK) != 0) {
    throw MeshIoError(path, "cannot import: the mesh import helper '" + helper +
                                "' is missing (build vrm_scene's vrm_mesh_import, or set VRM_MESH_IMPORT_HELPER)");
  }

  char scale[64];
  std::snprintf(scale, sizeof(scale), "%.17g", options.scale);
  std::vector<std::string> arguments = {helper, "--scale", scale};
  if (!options.join_identical_vertices) arguments.push_back("--no-join");
  arguments.push_back("--");
  arguments.push_back(path);
  std::vector<char*> argv;
  for (std::string& argument : arguments) argv.push_back(argument.data());
  argv.push_back(nullptr);

  Pipe reply, problems;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, reply.write, 1);
  posix_spawn_file_actions_adddup2(&actions, problems.write, 2);
  pid_t pid = -1;
  const int spawned = posix_spawn(&pid, helper.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) {
    throw MeshIoError(path,
                      "cannot import: cannot start the mesh import helper '" + helper + "': " + std::strerror(spawned));
  }
  reply.closeWrite();
  problems.closeWrite();

  // Both pipes are drained together: a helper blocked on a full stderr pipe would otherwise look like a hang.
  std::string out, err;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(options.time_limit);
  bool timed_out = false;
  std::array<pollfd, 2> fds = {pollfd{reply.read, POLLIN, 0}, pollfd{problems.read, POLLIN, 0}};
  std::array<std::string*, 2> sinks = {&out, &err};
  while (fds[0].fd >= 0 || fds[1].fd >= 0) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      timed_out = true;
      break;
    }
    const int ready = poll(fds.data(), fds.size(), static_cast<int>(std::min<long long>(left.count() + 1, 1 << 30)));
    if (ready < 0 && errno == EINTR) continue;
    if (ready < 0) break;
    for (std::size_t i = 0; i < fds.size(); ++i) {
      if (fds[i].fd < 0 || fds[i].revents == 0) continue;
      char buffer[1 << 16];
      const ssize_t got = ::read(fds[i].fd, buffer, sizeof(buffer));
      if (got > 0) {
        sinks[i]->append(buffer, static_cast<std::size_t>(got));
      } else if (got == 0 || (errno != EINTR && errno != EAGAIN)) {
        fds[i].fd = -1;  // end of file: poll ignores negative descriptors
      }
    }
  }
  if (timed_out) kill(pid, SIGKILL);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (timed_out) {
    char limit[32];
    std::snprintf(limit, sizeof(limit), "%g", options.time_limit);
    throw MeshIoError(path, std::string("cannot import: the importer did not finish within ") + limit +
                                " s and was stopped (a malformed or very large file?)");
  }
  while (!err.empty() && (err.back() == '\n' || err.back() == '\r')) err.pop_back();
  if (WIFEXITED(status) && WEXITSTATUS(status) == kMeshImportFailed) {
    throw MeshIoError(path, err.empty() ? "cannot import (no reason given)" : err);
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw MeshIoError(path, "cannot import: " + describeStatus(status) + (err.empty() ? "" : ": " + err));
  }
  TriangleMesh mesh;
  if (const std::string problem = decodeMeshReply(out, &mesh); !problem.empty()) {
    throw MeshIoError(path, "cannot import: the mesh import helper's reply is malformed: " + problem);
  }
  mesh.name = options.name.empty() ? std::filesystem::path(path).stem().string() : options.name;
  return mesh;
}

}  // namespace scene
}  // namespace vrm_sim
