// session_player: plays a session bag into the graph for replay.launch with rosbag's own player (it execs
// /usr/lib/rosbag/play, the binary behind `rosbag play`): bag time on /clock, waits until every played topic has a
// subscriber (nothing is lost at the start), ends when the bag is done. The bag it plays (~bag) is what
// `session_replay --prepare` checked before the launch started anything — the original, or a recovered copy of an
// unfinished one — and it plays only the session's topics that the bag has (a topic nobody subscribes to would stall
// the start). A bag recorded with input frames (issue 31) plays /input_frame remapped to /recorded_input_frame and
// not the raw device topics; an older bag plays the device topics.
// Parameters (private): bag (path), rate (time scale, default 1).
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <exception>
#include <set>
#include <string>
#include <vector>

#include "vrm_sim/bag/session_bag.h"
#include "vrm_sim/cli/cli.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "session_player");  // takes the remappings (name:=value) out of argv
  {
    vrm_sim::cli::CommandLine cli("session_player", "[NAME:=VALUE ...]",
                                  "Plays a session bag into the graph for replay.launch (rosbag play, bag time on "
                                  "/clock); ends when the bag is done.",
                                  "Private parameters: ~bag (the path session_replay --prepare printed), ~rate (time "
                                  "scale, default 1).");
    if (const auto status = cli.parse(argc, argv)) return *status;
  }
  std::string bag_path;
  double rate = 1.0;
  {
    ros::NodeHandle private_nh("~");
    bag_path = private_nh.param<std::string>("bag", "");
    rate = private_nh.param("rate", 1.0);
  }
  if (bag_path.empty()) {
    ROS_FATAL("session_player: no ~bag given (replay.launch sets it from `session_replay --prepare`)");
    return 2;
  }
  if (!(rate > 0.0)) {
    ROS_FATAL("session_player: ~rate must be positive, got %g", rate);
    return 2;
  }
  std::vector<std::string> topics;
  bool frames = false;
  try {
    std::set<std::string> present;
    rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
    rosbag::View view(bag);
    for (const rosbag::ConnectionInfo* connection : view.getConnections()) present.insert(connection->topic);
    // A bag with input frames plays them (onto recorded_input_frame: scenario_manager with ~input:=frames applies
    // them and publishes its own input_frame for renderer and tf), not the device topics; an older bag plays those.
    frames = present.count(vrm_sim::bag::inputFrameTopic()) > 0;
    for (const std::string& topic : vrm_sim::bag::sessionTopics()) {
      const bool device = std::find(vrm_sim::bag::deviceTopics().begin(), vrm_sim::bag::deviceTopics().end(), topic) !=
                          vrm_sim::bag::deviceTopics().end();
      if (frames && device) continue;
      if (present.count(topic)) topics.push_back(topic);
    }
  } catch (const std::exception& error) {
    ROS_FATAL("session_player: %s: %s", bag_path.c_str(), error.what());
    return 1;
  }
  const char* player = "/usr/lib/rosbag/play";
  std::vector<std::string> arguments = {
      player, "--clock", "--wait-for-subscribers", "--quiet", "--rate=" + std::to_string(rate), bag_path, "--topics"};
  arguments.insert(arguments.end(), topics.begin(), topics.end());
  if (frames) arguments.push_back(vrm_sim::bag::inputFrameTopic() + ":=/recorded_input_frame");
  // roslaunch's __name / __log remappings, so the player keeps this node's name.
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "__", 2) == 0) arguments.push_back(argv[i]);
  }
  ROS_INFO("session_player: playing %s (%zu topics) at %.2fx", bag_path.c_str(), topics.size(), rate);
  ros::shutdown();
  std::vector<char*> exec_arguments;
  for (std::string& argument : arguments) exec_arguments.push_back(argument.data());
  exec_arguments.push_back(nullptr);
  execv(player, exec_arguments.data());
  std::fprintf(stderr, "session_player: cannot run %s: %s\n", player, std::strerror(errno));
  return 1;
}
