#pragma once
// Running a built tool as a process in a test and checking the command-line contract every tool keeps
// (vrm_scene/cli/cli.h): --help exits 0 with "usage: <name>" on stdout, an unknown flag exits 2 with one line on
// stderr naming it, before any work. Shared by the tool tests of vrm_sim, vrm_graph, vrm_tracking and eyesi_gui.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace vrm_sim {
namespace test {

struct Process {
  int status = -1;  // exit status, -1 when the process did not exit normally (or could not start)
  std::string out;  // its stdout (redirect in `command` for stderr)
};

// Runs `command` with /bin/sh and collects its stdout.
inline Process run(const std::string& command) {
  Process result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  char buffer[4096];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0) result.out.append(buffer, n);
  const int status = pclose(pipe);
  result.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

// --help and an unknown flag answer as cli.h promises.
inline void expectHelpAndUnknownFlag(const std::string& tool) {
  SCOPED_TRACE(tool);
  const std::string name = tool.substr(tool.rfind('/') + 1);
  const Process help = run(tool + " --help 2>/dev/null");
  EXPECT_EQ(help.status, 0);
  EXPECT_EQ(help.out.rfind("usage: " + name, 0), 0u) << help.out;
  const Process unknown = run(tool + " --no-such-flag 2>&1 >/dev/null");
  EXPECT_EQ(unknown.status, 2);
  EXPECT_EQ(unknown.out, name + ": unrecognised option '--no-such-flag' (" + name + " --help prints the usage)\n");
}

}  // namespace test
}  // namespace vrm_sim
