// The graph tools with a command line (their target files, ':'-separated in VRM_GRAPH_TOOLS) keep the contract of
// every vrm_sim tool (vrm_scene/cli/cli.h, vrm_sim's test_cli): --help exits 0 with the usage on stdout, an unknown
// flag exits 2 with one line on stderr naming it, before any work (no master).
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "run_process.h"

namespace {

TEST(GraphTools, AnswerHelpWithZeroAndAnUnknownFlagWithTwo) {
  std::vector<std::string> tools;
  std::stringstream list(VRM_GRAPH_TOOLS);
  for (std::string tool; std::getline(list, tool, ':');) tools.push_back(tool);
  ASSERT_EQ(tools.size(), 2u);
  for (const std::string& tool : tools) {
    vrm_sim::test::expectHelpAndUnknownFlag(tool);
  }
}

}  // namespace
