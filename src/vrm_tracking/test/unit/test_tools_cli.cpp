// vrm_tracking's tools on the shared command line (vrm_scene/cli/cli.h, issue 34 part 2), run as processes: --help
// exits 0 with the usage, an unknown flag or a bad value exits 2 with one line on stderr, before any work.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <string>

#include "run_process.h"

namespace {

using vrm_sim::test::Process;
using vrm_sim::test::run;

void expectUsageError(const std::string& tool, const std::string& arguments, const std::string& named) {
  SCOPED_TRACE(tool + " " + arguments);
  const Process process = run(tool + " " + arguments + " 2>&1 >/dev/null");
  EXPECT_EQ(process.status, 2);
  EXPECT_NE(process.out.find(named), std::string::npos) << process.out;
  EXPECT_EQ(process.out.find('\n'), process.out.size() - 1) << "one line: " << process.out;
}

TEST(ToolsCommandLine, HelpExitsZeroAndUsageErrorsExitTwo) {
  for (const std::string tool : {VRM_TRACKING_EVAL, VRM_TRACKING_CALIBRATE_RIG, VRM_TRACKING_BENCH}) {
    SCOPED_TRACE(tool);
    const std::string name = tool.substr(tool.rfind('/') + 1);
    const Process help = run(tool + " --help 2>/dev/null");
    EXPECT_EQ(help.status, 0);
    EXPECT_EQ(help.out.rfind("usage: " + name, 0), 0u) << help.out;
    expectUsageError(tool, "--no-such-flag", "--no-such-flag");
  }
  const std::string eval = VRM_TRACKING_EVAL;
  expectUsageError(eval, "", "--trajectory");
  expectUsageError(eval, "--trajectory x.yaml --noise-px nan", "--noise-px");
  expectUsageError(eval, "--trajectory x.yaml --frames 5x", "--frames");
  expectUsageError(eval, "--trajectory x.yaml --filter kalman", "--filter");
  const std::string calibrate = VRM_TRACKING_CALIBRATE_RIG;
  expectUsageError(calibrate, "--synthetic", "--out");
  expectUsageError(calibrate, "--synthetic --out /nonexistent --views 2", "--views");
  expectUsageError(calibrate, "--synthetic --out /nonexistent --centre 0 0", "--centre");
  expectUsageError(calibrate, "--synthetic --images d --out /nonexistent", "--images");
}

}  // namespace
