// The graph tools with a command line (their target files, ':'-separated in VRM_GRAPH_TOOLS) keep the contract of
// every vrm_sim tool (vrm_scene/cli/cli.h, vrm_sim's test_cli): --help exits 0 with the usage on stdout, an unknown
// flag exits 2 with one line on stderr naming it, before any work (no master).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct Process {
  int status = -1;
  std::string out;
};

Process run(const std::string& command) {
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

TEST(GraphTools, AnswerHelpWithZeroAndAnUnknownFlagWithTwo) {
  std::vector<std::string> tools;
  std::stringstream list(VRM_GRAPH_TOOLS);
  for (std::string tool; std::getline(list, tool, ':');) tools.push_back(tool);
  ASSERT_EQ(tools.size(), 2u);
  for (const std::string& tool : tools) {
    SCOPED_TRACE(tool);
    const std::string name = tool.substr(tool.rfind('/') + 1);
    const Process help = run(tool + " --help 2>/dev/null");
    EXPECT_EQ(help.status, 0);
    EXPECT_EQ(help.out.rfind("usage: " + name, 0), 0u) << help.out;
    const Process unknown = run(tool + " --no-such-flag 2>&1 >/dev/null");
    EXPECT_EQ(unknown.status, 2);
    EXPECT_EQ(unknown.out, name + ": unrecognised option '--no-such-flag' (" + name + " --help prints the usage)\n");
  }
}

}  // namespace
