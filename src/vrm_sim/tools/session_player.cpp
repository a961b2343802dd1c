// session_player: plays a session bag into the graph for replay.launch with rosbag's own player (it execs
// /usr/lib/rosbag/play, the binary behind `rosbag play`): bag time on /clock, waits until every played topic has a
// subscriber (nothing is lost at the start), ends when the bag is done. The bag it plays (~bag) is what
// `session_replay --prepare` checked before the launch started anything — the original, or a recovered copy of an
// unfinished one — and it plays only the session's topics that the bag has (a topic nobody subscribes to would stall
// the start). A bag recorded with input frames (issue 31) plays /input_frame remapped to /recorded_input_frame and
// not the raw device topics; an older bag plays the device topics.
// The player runs as a child process (node <this node's name>_play). When it has played the bag, this node waits until
// the simulation has applied the bag's last input frame (scenario_manager publishes each applied frame on
// input_frame, with its recorded run and sequence) before it ends, and with it the launch: on a machine slower than
// real time the frames queue in the simulation, and a launch that ended with the play would cut them off.
// Parameters (private): bag (path), rate (time scale, default 1), stall_timeout (s of wall time without an applied
// frame after which the wait gives up with an error, default 20).
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <exception>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "vrm_msgs/InputFrame.h"
#include "vrm_scene/cli/cli.h"
#include "vrm_sim/bag/session_bag.h"

namespace {

// One line on stderr, unbuffered, as session_replay writes: what replay.launch's user reads.
void say(const char* format, ...) __attribute__((format(printf, 1, 2)));
void say(const char* format, ...) {
  std::fputs("session_player: ", stderr);
  va_list arguments;
  va_start(arguments, format);
  std::vfprintf(stderr, format, arguments);
  va_end(arguments);
  std::fputc('\n', stderr);
}

// A frame's place in a session: frames of a later run (the simulation restarted) come after all of an earlier one.
struct FramePosition {
  std::uint64_t run = 0, sequence = 0;
  bool reached(const FramePosition& target) const {
    return run > target.run || (run == target.run && sequence >= target.sequence);
  }
};

// Waits for the child; returns its exit status (128 + signal when killed). A shutdown of this node (roslaunch's
// SIGINT) is passed on to the player.
int waitForPlayer(pid_t player) {
  bool interrupted = false;
  while (true) {
    int status = 0;
    const pid_t done = waitpid(player, &status, interrupted ? 0 : WNOHANG);
    if (done == player) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (done < 0 && errno != EINTR) return 1;
    if (!interrupted && !ros::ok()) {
      interrupted = true;
      ::kill(player, SIGINT);
    }
    ros::WallDuration(0.02).sleep();
  }
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "session_player");  // takes the remappings (name:=value) out of argv
  {
    vrm_sim::cli::CommandLine cli("session_player", "[NAME:=VALUE ...]",
                                  "Plays a session bag into the graph for replay.launch (rosbag play, bag time on "
                                  "/clock); ends when the bag is done.",
                                  "Private parameters: ~bag (the path session_replay --prepare printed), ~rate (time "
                                  "scale, default 1), ~stall_timeout (s without an applied frame after the play, "
                                  "default 20).");
    if (const auto status = cli.parse(argc, argv)) return *status;
  }
  std::string bag_path;
  double rate = 1.0, stall_timeout = 20.0;
  {
    ros::NodeHandle private_nh("~");
    bag_path = private_nh.param<std::string>("bag", "");
    rate = private_nh.param("rate", 1.0);
    stall_timeout = private_nh.param("stall_timeout", 20.0);
  }
  if (bag_path.empty()) {
    say("no ~bag given (replay.launch sets it from `session_replay --prepare`)");
    return 2;
  }
  if (!(rate > 0.0)) {
    say("~rate must be positive, got %g", rate);
    return 2;
  }
  std::vector<std::string> topics;
  std::uint32_t played_messages = 0;
  bool frames = false;
  FramePosition last_frame;  // the bag's last input frame (frames bags)
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
    played_messages = rosbag::View(bag, rosbag::TopicQuery(topics)).size();
    if (frames) {
      rosbag::View recorded(bag, rosbag::TopicQuery(vrm_sim::bag::inputFrameTopic()));
      for (const rosbag::MessageInstance& message : recorded) {
        if (const auto frame = message.instantiate<vrm_msgs::InputFrame>()) {
          const FramePosition position{frame->run, frame->sequence};
          if (position.reached(last_frame)) last_frame = position;
        }
      }
    }
  } catch (const std::exception& error) {
    say("%s: %s", bag_path.c_str(), error.what());
    return 1;
  }
  const char* player = "/usr/lib/rosbag/play";
  std::vector<std::string> arguments = {
      player, "--clock", "--wait-for-subscribers", "--quiet", "--rate=" + std::to_string(rate),
      // The player's outgoing queue holds the whole play: a publisher drops its oldest message when a subscriber reads
      // slower than the play (its default 100 lost frames at 50x on a loaded machine: a replay that ended elsewhere).
      "--queue=" + std::to_string(std::max<std::uint32_t>(100, played_messages)), bag_path, "--topics"};
  arguments.insert(arguments.end(), topics.begin(), topics.end());
  if (frames) arguments.push_back(vrm_sim::bag::inputFrameTopic() + ":=/recorded_input_frame");
  // A name of its own (ros::init took roslaunch's remappings out of argv): two nodes of one name would make the master
  // shut this one down.
  const std::string name = ros::this_node::getName();
  arguments.push_back("__name:=" + name.substr(name.rfind('/') + 1) + "_play");
  if (ros::this_node::getNamespace() != "/") arguments.push_back("__ns:=" + ros::this_node::getNamespace());

  // Subscribed before the play starts, so no applied frame is missed.
  ros::NodeHandle nh;
  std::mutex applied_mutex;
  FramePosition applied;
  ros::WallTime last_applied_at = ros::WallTime::now();
  ros::Subscriber applied_subscriber;
  if (frames) {
    applied_subscriber = nh.subscribe<vrm_msgs::InputFrame>(vrm_sim::bag::inputFrameTopic(), 500,
                                                            [&](const vrm_msgs::InputFrame::ConstPtr& frame) {
                                                              std::lock_guard<std::mutex> lock(applied_mutex);
                                                              const FramePosition position{frame->run, frame->sequence};
                                                              if (position.reached(applied)) applied = position;
                                                              last_applied_at = ros::WallTime::now();
                                                            });
  }
  ros::AsyncSpinner spinner(1);
  spinner.start();

  say("playing %s (%zu topics) at %.2fx", bag_path.c_str(), topics.size(), rate);
  std::vector<char*> exec_arguments;
  for (std::string& argument : arguments) exec_arguments.push_back(argument.data());
  exec_arguments.push_back(nullptr);
  std::fflush(nullptr);  // stdout is a pipe under roslaunch (fully buffered): what this node said comes first
  const pid_t player_pid = fork();
  if (player_pid < 0) {
    say("cannot start %s: %s", player, std::strerror(errno));
    return 1;
  }
  if (player_pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGINT);  // the play ends with this node, also when it is killed
    execv(player, exec_arguments.data());
    const char message[] = "session_player: cannot run /usr/lib/rosbag/play\n";  // only async-signal-safe calls here
    [[maybe_unused]] const auto written = write(STDERR_FILENO, message, sizeof(message) - 1);
    _exit(127);
  }
  const int play_status = waitForPlayer(player_pid);
  if (!ros::ok()) return 0;  // the launch is ending: nothing to wait for
  if (play_status != 0) {
    say("%s ended with status %d", player, play_status);
    return play_status;
  }
  if (!frames) return 0;

  // The bag is played; the simulation may still have frames queued. A stall counts from the end of the play at the
  // earliest.
  const ros::WallTime played_at = ros::WallTime::now();
  while (ros::ok()) {
    {
      std::lock_guard<std::mutex> lock(applied_mutex);
      if (applied.reached(last_frame)) {
        say("the simulation applied the bag's last input frame (run %lu, sequence %lu)",
            static_cast<unsigned long>(last_frame.run), static_cast<unsigned long>(last_frame.sequence));
        return 0;
      }
      if ((ros::WallTime::now() - std::max(last_applied_at, played_at)).toSec() > stall_timeout) {
        say("the bag is played, but the simulation applied no frame for %.0f s; its last applied "
            "frame is sequence %lu of run %lu, the bag's last sequence %lu of run %lu (is scenario_manager running "
            "with ~input:=frames?)",
            stall_timeout, static_cast<unsigned long>(applied.sequence), static_cast<unsigned long>(applied.run),
            static_cast<unsigned long>(last_frame.sequence), static_cast<unsigned long>(last_frame.run));
        return 1;
      }
    }
    ros::WallDuration(0.02).sleep();
  }
  return 0;
}
