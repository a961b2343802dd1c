// The console's mirror of vrm_msgs constants (message_constants.h) against the .msg files themselves: every constant
// of ScenarioCommand, StationStatus and ScenarioStatus is in the console's list under its name and number, and the
// list has nothing else. ros_link.cpp static_asserts the numbers against the generated headers; this test catches a
// constant added to or removed from a message, which no static_assert can see.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <string>

#include "eyesi_gui/console/message_constants.h"
#include "vrm_msgs/msg_constants.h"

namespace eyesi_gui {
namespace {

template <std::size_t N>
void expectMirrors(const std::string& message, const MessageConstant (&mirror)[N]) {
  const std::string path = std::string(VRM_MSGS_MSG_DIR) + "/" + message + ".msg";
  std::map<std::string, long long> in_file;
  for (const vrm_msgs::MsgConstant& constant : vrm_msgs::readMsgConstants(path))
    in_file[constant.name] = constant.value;
  ASSERT_FALSE(in_file.empty()) << path << " has no integer constants: the parser or the path is wrong";
  std::map<std::string, long long> in_console;
  for (const MessageConstant& constant : mirror) in_console[constant.name] = constant.value;
  EXPECT_EQ(in_file, in_console) << message
                                 << ".msg and eyesi_gui/console/message_constants.h differ: a constant was added, "
                                    "removed or renumbered in the message; update the console's list (and its labels)";
  for (const MessageConstant& constant : mirror) {
    EXPECT_STREQ(constantLabel(mirror, constant.value), constant.label) << message << " " << constant.name;
  }
}

TEST(MessageConstants, ScenarioCommandMatchesTheMessage) {
  expectMirrors("ScenarioCommand", kScenarioCommandConstants);
}
TEST(MessageConstants, StationStatusMatchesTheMessage) { expectMirrors("StationStatus", kStationStatusConstants); }
TEST(MessageConstants, ScenarioStatusMatchesTheMessage) { expectMirrors("ScenarioStatus", kScenarioStatusConstants); }
TEST(MessageConstants, InstrumentTypesMatchTheMessage) {
  expectMirrors("InstrumentTypes", kInstrumentTypeConstants);
  EXPECT_STREQ(instrumentTypeLabel("laser_probe"), "laser probe");
  EXPECT_STREQ(instrumentTypeLabel("light_pipe"), "light pipe");
  EXPECT_EQ(instrumentTypeLabel("laser"), nullptr);
  EXPECT_EQ(instrumentTypeLabel("laser_probes"), nullptr);
  EXPECT_EQ(instrumentTypeLabel("LASER_PROBE"), nullptr) << "scene names are lower case";
}

TEST(MessageConstants, ParserReadsOnlyIntegerConstants) {
  const std::string path = ::testing::TempDir() + "/constants_probe.msg";
  {
    std::ofstream file(path);
    file << "# header\nuint8 A=0   # first\n  int32 NEGATIVE = -3\nstring NAME=\"x\"\nfloat64 SCALE=0.5\nuint8 "
            "field\nstd_msgs/Header header\nuint8 B=7\n";
  }
  const std::vector<vrm_msgs::MsgConstant> constants = vrm_msgs::readMsgConstants(path);
  ASSERT_EQ(constants.size(), 3u);
  EXPECT_EQ(constants[0].name, "A");
  EXPECT_EQ(constants[1].value, -3);
  EXPECT_EQ(constants[2].name, "B");
  EXPECT_EQ(constants[2].value, 7);
  EXPECT_THROW(vrm_msgs::readMsgConstants(path + ".missing"), std::runtime_error);
}

TEST(MessageConstants, UnknownValueHasAnUnknownLabel) {
  EXPECT_STREQ(constantLabel(kStationStatusConstants, 99), "unknown");
  EXPECT_STREQ(constantLabel(kScenarioStatusConstants, -1), "unknown");
}

}  // namespace
}  // namespace eyesi_gui
