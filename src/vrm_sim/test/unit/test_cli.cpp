// The tools' shared command line (vrm_scene/cli/cli.h, issue 34 part 2): --help, usage errors with exit status 2,
// strict numbers; and every vrm_sim tool and benchmark answering --help with 0 and an unknown flag with 2.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "run_process.h"
#include "vrm_scene/cli/cli.h"

namespace {

namespace cli = vrm_sim::cli;
namespace po = vrm_sim::cli::po;

struct Parsed {
  std::optional<int> status;
  std::string error;  // what parse() wrote on stderr
};

// A tool with a number, a count, a seed, a choice, a required name and a vector, as the converted tools have.
struct Tool {
  double rate = 50.0;
  int views = 15;
  std::uint32_t seed = 0;
  std::string filter = "none", scene;
  std::vector<double> centre{0.0, 0.0, 0.0};
  cli::CommandLine command_line{"tool", "--scene NAME [--rate HZ]", "A test tool.", "Exit status: 0 ok, 2 usage."};

  Tool() {
    command_line.add()("scene", po::value(&scene)->required(), "the scene")("rate", cli::real(&rate), "Hz")(
        "views", cli::integer(&views), "views")("seed", cli::uint32(&seed), "seed")(
        "filter", cli::choice(&filter, {"none", "one_euro"}), "filter")("centre", cli::reals(&centre, 3), "X Y Z");
  }

  Parsed parse(std::vector<std::string> arguments) {
    arguments.insert(arguments.begin(), "tool");
    std::vector<const char*> argv;
    for (const std::string& argument : arguments) argv.push_back(argument.c_str());
    testing::internal::CaptureStderr();
    Parsed parsed;
    parsed.status = command_line.parse(static_cast<int>(argv.size()), argv.data());
    parsed.error = testing::internal::GetCapturedStderr();
    return parsed;
  }
};

// One line on stderr that names the tool and the option and points to --help; exit status 2.
void expectUsageError(const Parsed& parsed, const std::string& option) {
  ASSERT_TRUE(parsed.status.has_value());
  EXPECT_EQ(*parsed.status, 2);
  EXPECT_EQ(parsed.error.rfind("tool: ", 0), 0u) << parsed.error;
  EXPECT_NE(parsed.error.find(option), std::string::npos) << parsed.error;
  EXPECT_NE(parsed.error.find("tool --help"), std::string::npos) << parsed.error;
  EXPECT_EQ(std::count(parsed.error.begin(), parsed.error.end(), '\n'), 1) << parsed.error;
}

TEST(CommandLine, HelpPrintsUsageDescriptionAndOptionsAndExitsZero) {
  Tool tool;
  testing::internal::CaptureStdout();
  const Parsed parsed = tool.parse({"--rate", "nan", "--help"});  // --help wins over a bad value and a missing one
  const std::string help = testing::internal::GetCapturedStdout();
  ASSERT_TRUE(parsed.status.has_value());
  EXPECT_EQ(*parsed.status, 0);
  EXPECT_TRUE(parsed.error.empty()) << parsed.error;
  EXPECT_EQ(help.rfind("usage: tool --scene NAME [--rate HZ]\nA test tool.\n", 0), 0u) << help;
  EXPECT_NE(help.find("--rate"), std::string::npos) << help;
  EXPECT_NE(help.find("--help"), std::string::npos) << help;
  EXPECT_NE(help.find("Exit status: 0 ok, 2 usage."), std::string::npos) << help;
  testing::internal::CaptureStdout();
  EXPECT_EQ(Tool().parse({"-h"}).status, std::optional<int>(0));
  testing::internal::GetCapturedStdout();
}

TEST(CommandLine, StoresValuesInBothSpellings) {
  Tool tool;
  const Parsed parsed = tool.parse({"--scene=membrane", "--rate", "2.5e1", "--views=4", "--seed", "4294967295",
                                    "--filter", "one_euro", "--centre", "-0.001", "0", "2e-3"});
  EXPECT_FALSE(parsed.status.has_value()) << parsed.error;
  EXPECT_EQ(tool.scene, "membrane");
  EXPECT_EQ(tool.rate, 25.0);
  EXPECT_EQ(tool.views, 4);
  EXPECT_EQ(tool.seed, 4294967295u);
  EXPECT_EQ(tool.filter, "one_euro");
  EXPECT_EQ(tool.centre, (std::vector<double>{-0.001, 0.0, 0.002}));
  EXPECT_TRUE(tool.command_line.given("rate"));
  EXPECT_FALSE(tool.command_line.given("help"));
}

TEST(CommandLine, DefaultsStayWhenNotGiven) {
  Tool tool;
  EXPECT_FALSE(tool.parse({"--scene", "x"}).status.has_value());
  EXPECT_EQ(tool.rate, 50.0);
  EXPECT_EQ(tool.views, 15);
  EXPECT_FALSE(tool.command_line.given("rate"));
}

TEST(CommandLine, EmptyValueAfterEqualsIsAnEmptyValue) {
  Tool tool;  // records' "--pin=" clears a PIN, as "--pin ''" does
  EXPECT_FALSE(tool.parse({"--scene="}).status.has_value());
  EXPECT_EQ(tool.scene, "");
}

TEST(CommandLine, UnknownOptionAbbreviationAndStrayArgumentExitTwo) {
  expectUsageError(Tool().parse({"--scene", "x", "--bogus"}), "--bogus");
  expectUsageError(Tool().parse({"--sce", "x"}), "--sce");  // no guessing of abbreviations
  expectUsageError(Tool().parse({"--scene", "x", "stray"}), "stray");
}

TEST(CommandLine, MissingRequiredOptionOrValueExitsTwo) {
  expectUsageError(Tool().parse({"--rate", "5"}), "--scene");
  expectUsageError(Tool().parse({"--scene"}), "--scene");
  expectUsageError(Tool().parse({"--scene", "x", "--centre", "1", "2"}), "--centre");
}

TEST(CommandLine, BadNumbersExitTwo) {
  for (const char* bad : {"nan", "NaN", "inf", "-inf", "1x", "5 ", " 5", "", "0x", "1e999"}) {
    SCOPED_TRACE(bad);
    expectUsageError(Tool().parse({"--scene", "x", "--rate", bad}), "--rate");
  }
  for (const char* bad : {"1.5", "3x", "99999999999", ""}) {
    SCOPED_TRACE(bad);
    expectUsageError(Tool().parse({"--scene", "x", "--views", bad}), "--views");
  }
  // lexical_cast<unsigned> would take "-1" as 4294967295.
  for (const char* bad : {"-1", "+1", "4294967296", "1.0"}) {
    SCOPED_TRACE(bad);
    expectUsageError(Tool().parse({"--scene", "x", "--seed", bad}), "--seed");
  }
  expectUsageError(Tool().parse({"--scene", "x", "--centre", "0", "nan", "0"}), "--centre");
}

TEST(CommandLine, RepeatedSingleValueAndBadChoiceExitTwo) {
  expectUsageError(Tool().parse({"--scene", "x", "--scene", "y"}), "--scene");
  const Parsed parsed = Tool().parse({"--scene", "x", "--filter", "kalman"});
  expectUsageError(parsed, "--filter");
  EXPECT_NE(parsed.error.find("none or one_euro"), std::string::npos) << parsed.error;
}

TEST(CommandLine, FailNamesTheProblemOnOneLine) {
  Tool tool;
  testing::internal::CaptureStderr();
  EXPECT_EQ(tool.command_line.fail("--rate expects a positive number"), 2);
  EXPECT_EQ(testing::internal::GetCapturedStderr(),
            "tool: --rate expects a positive number (tool --help prints the usage)\n");
}

TEST(CommandLine, ParsersAreStrict) {
  EXPECT_EQ(cli::parseReal("-2.5"), std::optional<double>(-2.5));
  EXPECT_FALSE(cli::parseReal("nan"));
  EXPECT_FALSE(cli::parseReal("2.5m"));
  EXPECT_EQ(cli::parseInteger("-3"), std::optional<std::int64_t>(-3));
  EXPECT_FALSE(cli::parseInteger("3.0"));
  EXPECT_EQ(cli::parseUnsigned("18446744073709551615"), std::optional<std::uint64_t>(18446744073709551615ull));
  EXPECT_FALSE(cli::parseUnsigned("18446744073709551616"));
  EXPECT_FALSE(cli::parseUnsigned("-0"));
}

// Every vrm_sim tool and benchmark (their target files, ':'-separated in VRM_SIM_TOOLS): --help exits 0 with the usage
// on stdout, an unknown flag exits 2 with one line on stderr naming it, before any work (no master, no scene).
TEST(Tools, AnswerHelpWithZeroAndAnUnknownFlagWithTwo) {
  std::vector<std::string> tools;
  std::stringstream list(VRM_SIM_TOOLS);
  for (std::string tool; std::getline(list, tool, ':');) tools.push_back(tool);
  ASSERT_GE(tools.size(), 13u);
  for (const std::string& tool : tools) {
    vrm_sim::test::expectHelpAndUnknownFlag(tool);
  }
}

}  // namespace
