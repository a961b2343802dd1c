// session_control: frames a recorded session so that its bag holds all of it (thesis §2.4.2). The recorder and the
// simulation start independently, so either may see inputs the other missed; the world therefore waits (auto_start
// off) and this node sends ScenarioCommand START once the recorder subscribes to every recorded topic, stamped a
// little after the newest simulated frame, and STOP once the session has run `duration` s of input time (unless its
// scenario ended before). Both commands are recorded inputs with stamps ahead of the frames they apply to, so the
// live session and every replay apply them to the same frames and end in the same state. After a short tail it
// exits, which ends the launch (required) and lets the recorder close the bag.
// Parameters (private): recorder (node name, default /session_recorder), topics (list the recorder must subscribe
// to), duration (s of input time; 0 = until Ctrl-C), start (default true; false: a console sends START),
// start_delay (s of input time between the newest frame and START, default 0.5), tail (s of input time recorded
// after STOP, default 1.0), bag (the first part's path; empty = no part report), recorder_timeout (s of wall time
// after the first simulated frame; a recorder that does not listen by then ends the session, default 30),
// min_free_mb (default 20: below this free space on the bag's file system the session stops with a recorded STOP
// that names the full disk, so the recording, its journal and its result stay whole, issue 39).
//
// Faults (issues 14, 39). A simulation that comes back after a crash of its nodelet manager announces it on
// simulation_resume (vrm_msgs/SessionResume). Crash = pause: when it resumed the session from its journal, the session
// goes on, one session with one result; its STOP moves by the time the clock stood still. When it had nothing to
// resume (no journal), the scenario is restarted cleanly: LOAD of the same scene, difficulty and seed, then START,
// both recorded, so a replay of the bag resets its world where the live one was restarted (the interrupted session's
// result is kept, marked interrupted, by scenario_manager). A recorder that dies (its process no longer answers) is
// respawned by the launch into the next bag part; the gap is logged while it lasts, and at the end the killed parts
// are recovered (indexed copies at their own names) and <bag without .bag>.recording.json lists every part with its
// first and last message stamps, the gaps between them and the restarts of the simulation.
#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <ros/xmlrpc_manager.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sys/statvfs.h>

#include <boost/make_shared.hpp>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "master_queries.h"
#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/SessionInfo.h"
#include "vrm_msgs/SessionResume.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_scene/cli/cli.h"
#include "vrm_sim/bag/session_bag.h"

namespace {

using vrm_graph::tools::lookupNode;

// Subscribers of each topic according to the master.
std::map<std::string, std::vector<std::string>> subscribersByTopic() {
  std::map<std::string, std::vector<std::string>> result;
  XmlRpc::XmlRpcValue request, response, payload;
  request[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", request, response, payload, false)) return result;
  const XmlRpc::XmlRpcValue& subscriptions = payload[1];
  for (int i = 0; i < subscriptions.size(); ++i) {
    std::vector<std::string>& nodes = result[static_cast<std::string>(subscriptions[i][0])];
    for (int j = 0; j < subscriptions[i][1].size(); ++j)
      nodes.push_back(static_cast<std::string>(subscriptions[i][1][j]));
  }
  return result;
}

// The pid of the process behind `uri` (0: it does not answer).
int processId(const std::string& uri) {
  std::string host;
  std::uint32_t port = 0;
  if (!ros::network::splitURI(uri, host, port)) return 0;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue request, response;
  request[0] = ros::this_node::getName();
  int pid = 0;
  if (client.execute("getPid", request, response) && !client.isFault() && response.size() >= 3 &&
      response[2].getType() == XmlRpc::XmlRpcValue::TypeInt) {
    pid = static_cast<int>(response[2]);
  }
  client.close();
  return pid;
}

// Whether the process behind `uri` still answers (the master keeps a killed node registered until it is replaced).
bool answers(const std::string& uri) { return processId(uri) > 0; }

struct Gap {
  ros::Time from, to;  // input time: the newest frame when the recorder was found dead / listening again
};

class SessionControl {
 public:
  SessionControl() : private_nh_("~") {
    recorder_ = private_nh_.param<std::string>("recorder", "/session_recorder");
    private_nh_.getParam("topics", topics_);
    duration_ = private_nh_.param("duration", 0.0);
    send_start_ = private_nh_.param("start", true);
    start_delay_ = ros::Duration(private_nh_.param("start_delay", 0.5));
    tail_ = ros::Duration(private_nh_.param("tail", 1.0));
    bag_ = private_nh_.param<std::string>("bag", "");
    recorder_timeout_ = private_nh_.param("recorder_timeout", 30.0);
    min_free_mb_ = private_nh_.param("min_free_mb", 20.0);
    info_subscriber_ = nh_.subscribe("session_info", 1, &SessionControl::onSessionInfo, this);
    health_timer_ = nh_.createWallTimer(ros::WallDuration(0.5), &SessionControl::checkHealth, this);
    command_publisher_ = nh_.advertise<vrm_msgs::ScenarioCommand>("scenario_command", 5);
    state_subscriber_ = nh_.subscribe("simulation_state", 50, &SessionControl::onFrame, this);
    status_subscriber_ = nh_.subscribe("scenario_status", 5, &SessionControl::onStatus, this);
    resume_subscriber_ = nh_.subscribe("simulation_resume", 1, &SessionControl::onResume, this);
    timer_ = nh_.createWallTimer(ros::WallDuration(0.1), &SessionControl::onTimer, this);
  }

 private:
  void onFrame(const vrm_msgs::SimulationState::ConstPtr& state) {
    newest_ = std::max(newest_, state->header.stamp);
    if (!started_ || (duration_ <= 0.0 && forced_end_.isZero())) return;
    const ros::Time end = forced_end_.isZero() ? start_ + ros::Duration(duration_) : forced_end_;
    // STOP goes out ahead of the frame it applies to (like START), so its arrival never races that frame.
    if (!stop_sent_ && newest_ + start_delay_ >= end) {
      stop_sent_ = true;
      if (scenario_ended_) {
        ROS_INFO("session_control: the scenario ended before the %.1f s of the session; no STOP", duration_);
      } else {
        char reason[64];
        std::snprintf(reason, sizeof(reason), "recording ended after %.1f s", duration_);
        send(vrm_msgs::ScenarioCommand::STOP, end, reason);
      }
    }
    // The tail counts from where the session ended. A STOP takes effect in the frame of its stamp, or in the first
    // frame the simulation's mediator closes after the STOP arrives if that is later (a STOP sent late: a console's,
    // or one delayed on a loaded or sanitizer-built machine), and a recording closed `tail` after the stamp would end
    // before it.
    const bool ended = !ended_at_.isZero();
    // A simulation that lags its inputs applies the STOP that much later (stop_lag_), so the grace grows by it.
    const ros::Duration grace = tail_ + kStopGrace + stop_lag_;
    const bool over = ended ? newest_ >= std::max(end, ended_at_) + tail_ : newest_ >= end + grace;
    if (over) {
      if (!ended) {
        ROS_WARN(
            "session_control: the session did not end within %.1f s of input time after its STOP at %.3f (the "
            "simulation lagged its inputs by %.1f s when it was sent); ending the recording anyway",
            grace.toSec(), end.toSec(), stop_lag_.toSec());
      }
      ROS_INFO("session_control: session over (%.1f s from START); ending the recording", (end - start_).toSec());
      closeRecording();
      reportParts();
      ros::shutdown();
    }
  }

  void onSessionInfo(const vrm_msgs::SessionInfo::ConstPtr& info) { info_ = info; }

  // A simulation node loaded again after a crash of its manager (one announcement per new process, latched).
  void onResume(const vrm_msgs::SessionResume::ConstPtr& resume) {
    if (session_over_) return;
    if (!resume->resumed) {
      if (started_) restartScenario();
      return;
    }
    ++restarts_;
    ++resumes_;
    const ros::Duration paused = resume->header.stamp - resume->paused_at;
    // The session's input time stood still from the pause to the resume: its end moves by as much. A STOP sent for a
    // frame the crashed process never closed was lost with the process's mediator: it goes out again at the new end.
    if (started_ && !resume->session_start.isZero()) start_ += paused;
    if (stop_sent_ && forced_end_.isZero() && stop_stamp_ > resume->paused_at) stop_sent_ = false;
    if (!forced_end_.isZero() && forced_end_ > resume->paused_at) {
      forced_end_ += paused;
      send(vrm_msgs::ScenarioCommand::STOP, forced_end_, stop_reason_);
    }
    newest_ = std::max(newest_, resume->header.stamp);
    ROS_WARN(
        "session_control: the simulation resumed the session after a crash (%u frames restored in %.2f s); paused "
        "%.2f s of input time, the session goes on (resume %u)",
        resume->frames_restored, resume->restore_seconds, paused.toSec(), resumes_);
  }

  // The recorder's process (a respawn), twice a second.
  void checkHealth(const ros::WallTimerEvent&) {
    if (final_part_ == 0) ros::param::get(recorder_ + "/part", next_part_);
    if (!started_) return;
    checkDiskSpace();
    const std::string recorder_uri = lookupNode(recorder_);
    const bool recording =
        !recorder_uri.empty() && answers(recorder_uri) && topicsRecorderMisses(subscribersByTopic()).empty();
    if (!recording && !gap_open_) {
      gap_open_ = true;
      gaps_.push_back({newest_, ros::Time()});
      ROS_WARN(
          "session_control: the recorder %s is gone at input time %.3f; inputs from now on are not recorded "
          "until it is back (a respawned recorder writes the next bag part)",
          recorder_.c_str(), newest_.toSec());
    } else if (recording && gap_open_) {
      gap_open_ = false;
      gaps_.back().to = newest_;
      ROS_WARN(
          "session_control: the recorder is back after %.2f s of input time (%.3f .. %.3f); the simulation resends "
          "it the input frames of that time (the raw device topics of it are not in the bag)",
          (gaps_.back().to - gaps_.back().from).toSec(), gaps_.back().from.toSec(), gaps_.back().to.toSec());
    }
  }

  // The recorded topics the recorder does not subscribe to according to the master (" /a /b"; "" = it listens).
  std::string topicsRecorderMisses(const std::map<std::string, std::vector<std::string>>& subscribers) const {
    std::string missing;
    for (const std::string& topic : topics_) {
      const auto nodes = subscribers.find(topic);
      if (nodes == subscribers.end() ||
          std::find(nodes->second.begin(), nodes->second.end(), recorder_) == nodes->second.end()) {
        missing += " " + topic;
      }
    }
    return missing;
  }

  // A new simulation process (its manager crashed and was restarted) starts from a fresh world: the scenario starts
  // again, with a recorded LOAD first so that a replay's world (which saw the old session's inputs) is fresh too.
  void restartScenario() {
    ++restarts_;
    ROS_WARN(
        "session_control: the simulation restarted with nothing to resume; its interrupted session keeps its "
        "result, marked interrupted; the scenario starts again (restart %u)",
        restarts_);
    started_ = false;
    stop_sent_ = false;
    scenario_ended_ = false;
    ended_at_ = ros::Time();
    reload_ = true;
    newest_ = ros::Time();
  }

  void onStatus(const vrm_msgs::ScenarioStatus::ConstPtr& status) {
    scenario_ended_ =
        status->state == vrm_msgs::ScenarioStatus::FINISHED || status->state == vrm_msgs::ScenarioStatus::FAILED;
    if (!scenario_ended_) {
      ended_at_ = ros::Time();
    } else if (ended_at_.isZero()) {
      ended_at_ = status->header.stamp.isZero() ? newest_ : status->header.stamp;
    }
  }

  void onTimer(const ros::WallTimerEvent&) {
    if (started_) return;
    const auto subscribers = subscribersByTopic();
    const std::string missing = topicsRecorderMisses(subscribers);
    // Every subscriber the master knows of /scenario_command (recorder, simulation) must be connected to us.
    const auto command_subscribers = subscribers.find(command_publisher_.getTopic());
    const std::size_t expected = command_subscribers == subscribers.end() ? 0 : command_subscribers->second.size();
    const bool connected = expected >= 2 && command_publisher_.getNumSubscribers() >= expected;
    // A recorder that never listens (an unwritable bag: it exits and is respawned in vain) ends the session with a
    // reason instead of leaving it waiting for ever.
    if (!newest_.isZero() && !missing.empty() && !restarts_) {
      if (first_frame_wall_.isZero()) first_frame_wall_ = ros::WallTime::now();
      if ((ros::WallTime::now() - first_frame_wall_).toSec() > recorder_timeout_) {
        ROS_FATAL(
            "session_control: %s did not subscribe to%s within %.0f s of the first simulated frame (see its "
            "log: is the bag's folder writable?); ending the session",
            recorder_.c_str(), missing.c_str(), recorder_timeout_);
        ros::shutdown();
        return;
      }
    }
    if (!missing.empty() || !connected || newest_.isZero()) {
      if ((ros::WallTime::now() - last_note_).toSec() > 5.0) {
        last_note_ = ros::WallTime::now();
        ROS_INFO("session_control: waiting for %s%s%s",
                 missing.empty() ? "" : (recorder_ + " to subscribe to" + missing + "; ").c_str(),
                 connected ? "" : "the scenario_command subscribers; ",
                 newest_.isZero() ? "the first simulated frame" : "");
      }
      return;
    }
    started_ = true;
    start_ = newest_ + start_delay_;
    if (reload_) {
      reload_ = false;
      send(vrm_msgs::ScenarioCommand::LOAD, newest_, info_ ? info_->difficulty : "");
      send(vrm_msgs::ScenarioCommand::START, start_, "");
    } else if (send_start_) {
      send(vrm_msgs::ScenarioCommand::START, start_, "");
    } else {
      ROS_INFO("session_control: recording; the session starts with the console's START");
    }
  }

  void send(std::uint8_t command, const ros::Time& stamp, const std::string& argument) {
    if (command == vrm_msgs::ScenarioCommand::STOP) {
      stop_stamp_ = stamp;
      stop_reason_ = argument;
      // The devices stamp their inputs with the present. The STOP does not queue behind their inputs (scenario_manager
      // takes commands on a queue of their own), but its frame closes only once the simulation has applied the inputs
      // up to its stamp: a simulation this far behind the present applies it about this much later.
      stop_lag_ = std::max(ros::Duration(0.0), ros::Time::now() - newest_);
    }
    auto message = boost::make_shared<vrm_msgs::ScenarioCommand>();
    message->header.stamp = stamp;
    message->command = command;
    message->argument = argument;
    if (command == vrm_msgs::ScenarioCommand::LOAD && info_) message->seed = info_->seed;
    command_publisher_.publish(message);
    const char* name = command == vrm_msgs::ScenarioCommand::START  ? "START"
                       : command == vrm_msgs::ScenarioCommand::LOAD ? "LOAD (the same scene)"
                                                                    : "STOP";
    ROS_INFO("session_control: %s at input time %.3f%s%s", name, stamp.toSec(), argument.empty() ? "" : ": ",
             argument.c_str());
  }

 public:
  // After the session: the parts the (respawned) recorder wrote, the killed ones recovered, and the gaps between
  // them, in <bag without .bag>.recording.json. Runs while the current recorder still writes its part.
  std::string bagStem() const {
    return bag_.size() > 4 && bag_.compare(bag_.size() - 4, 4, ".bag") == 0 ? bag_.substr(0, bag_.size() - 4) : bag_;
  }
  // Part 1 is the bag itself, part k > 1 <stem>.part<k>.bag (session_recorder's names).
  std::string partPath(int part) const {
    return part == 1 ? bag_ : bagStem() + ".part" + std::to_string(part) + ".bag";
  }

  // Disk full (issue 39): the session stops, with a recorded STOP naming why, while the bag's file system still has
  // min_free_mb: the recording up to there, the journal and the result file are whole, and a replay reaches the
  // state the session stopped in. A full disk would otherwise cut the bag and the journal at random.
  void checkDiskSpace() {
    if (bag_.empty() || stop_sent_ || session_over_ || newest_.isZero()) return;
    struct statvfs space {};
    const std::string folder = std::filesystem::path(bag_).parent_path().string();
    if (::statvfs(folder.empty() ? "." : folder.c_str(), &space) != 0) return;
    const double free_mb = static_cast<double>(space.f_bavail) * static_cast<double>(space.f_frsize) / 1048576.0;
    if (free_mb >= min_free_mb_) return;
    stop_sent_ = true;
    forced_end_ = newest_ + start_delay_;
    char reason[256];
    std::snprintf(reason, sizeof(reason), "the disk of the recording is full (%.1f MB free in %s, below %.0f MB)",
                  free_mb, folder.c_str(), min_free_mb_);
    ROS_ERROR("session_control: %s: the session stops; what was recorded is kept and replays", reason);
    if (scenario_ended_) return;
    send(vrm_msgs::ScenarioCommand::STOP, forced_end_, reason);
  }

  // The manifest describes closed parts (issue 39): the recorder is asked to close its part (SIGINT: rosbag record
  // writes the index and drops .active) and not to record again (~part 0: the respawned session_recorder idles),
  // and the part is waited for, before reportParts writes the manifest.
  void closeRecording() {
    if (bag_.empty() || session_over_) return;
    ros::param::get(recorder_ + "/part", next_part_);
    final_part_ = std::max(1, next_part_ - 1);
    ros::param::set(recorder_ + "/part", 0);
    const std::string uri = lookupNode(recorder_);
    const int pid = uri.empty() ? 0 : processId(uri);
    const std::string path = partPath(final_part_);
    std::string host;
    std::uint32_t port = 0;
    // Only a recorder on this machine can be signalled; another's part is described as still recording.
    if (pid <= 0 || !ros::network::splitURI(uri, host, port) ||
        (host != "localhost" && host != ros::network::getHost()) || ::kill(pid, SIGINT) != 0) {
      ROS_WARN("session_control: cannot ask the recorder %s to close its part; the manifest lists it as recording",
               recorder_.c_str());
      return;
    }
    namespace fs = std::filesystem;
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(15.0);
    std::error_code error;
    while (ros::WallTime::now() < deadline && (fs::exists(path + ".active", error) || !fs::exists(path, error))) {
      ros::WallDuration(0.05).sleep();
    }
    part_closed_ = !fs::exists(path + ".active", error) && fs::exists(path, error);
    if (!part_closed_) ROS_ERROR("session_control: the recorder did not close %s within 15 s", path.c_str());
  }

  void reportParts() {
    if (session_over_ || bag_.empty()) return;
    session_over_ = true;
    namespace fs = std::filesystem;
    const std::string stem = bagStem();
    const int current = final_part_ > 0 ? final_part_ : std::max(1, next_part_ - 1);
    std::ostringstream json;
    json << std::setprecision(15) << "{\"bag\": \"" << bag_ << "\", \"parts\": [";
    std::vector<std::string> lines;
    for (int part = 1; part <= current; ++part) {
      const std::string path = partPath(part);
      std::string state = "recording";  // the current part, unless closeRecording closed it
      std::error_code error;
      double first = 0.0, last = 0.0;
      std::uint64_t messages = 0;
      if (part < current || part_closed_) {
        state = "complete";
        if (!fs::exists(path, error) && fs::exists(path + ".active", error)) {
          try {
            const vrm_sim::bag::RecoveryReport report = vrm_sim::bag::recoverBag(path + ".active", path);
            state = "recovered";
            ROS_WARN("session_control: part %d was cut off by its recorder's crash; %lu messages recovered into %s",
                     part, static_cast<unsigned long>(report.messages), path.c_str());
          } catch (const std::exception& failure) {
            state = "lost";
            ROS_ERROR("session_control: part %d (%s.active) cannot be recovered: %s", part, path.c_str(),
                      failure.what());
          }
        }
        if (state != "lost") {
          try {
            rosbag::Bag bag(path, rosbag::bagmode::Read);
            rosbag::View view(bag);
            messages = view.size();
            if (messages > 0) {
              first = view.getBeginTime().toSec();
              last = view.getEndTime().toSec();
            }
          } catch (const std::exception& failure) {
            state = "unreadable";
          }
        }
      }
      std::ostringstream line;
      line << std::setprecision(15) << "{\"part\": " << part << ", \"path\": \"" << path << "\", \"state\": \"" << state
           << "\", \"messages\": " << messages << ", \"first_stamp\": " << first << ", \"last_stamp\": " << last << "}";
      lines.push_back(line.str());
    }
    for (std::size_t i = 0; i < lines.size(); ++i) json << (i ? ", " : "") << lines[i];
    json << "], \"gaps\": [";
    for (std::size_t i = 0; i < gaps_.size(); ++i) {
      json << (i ? ", " : "") << "{\"from\": " << gaps_[i].from.toSec()
           << ", \"to\": " << (gaps_[i].to.isZero() ? newest_.toSec() : gaps_[i].to.toSec())
           << ", \"seconds\": " << ((gaps_[i].to.isZero() ? newest_ : gaps_[i].to) - gaps_[i].from).toSec() << "}";
    }
    json << "], \"simulation_restarts\": " << restarts_ << ", \"simulation_resumes\": " << resumes_ << "}\n";
    const std::string report = stem + ".recording.json";
    std::ofstream(report) << json.str();
    if (current > 1 || !gaps_.empty() || restarts_ > 0) {
      ROS_WARN("session_control: %d bag parts, %zu recording gaps, %u simulation restarts: %s", current, gaps_.size(),
               restarts_, report.c_str());
    }
  }

 private:
  ros::NodeHandle nh_, private_nh_;
  std::string recorder_;
  std::vector<std::string> topics_;
  double duration_ = 0.0;
  bool send_start_ = true;
  ros::Duration start_delay_, tail_;
  ros::Publisher command_publisher_;
  ros::Subscriber state_subscriber_, status_subscriber_, info_subscriber_, resume_subscriber_;
  ros::WallTimer timer_, health_timer_;
  std::string bag_;
  vrm_msgs::SessionInfo::ConstPtr info_;
  std::vector<Gap> gaps_;
  bool gap_open_ = false, reload_ = false, session_over_ = false;
  unsigned restarts_ = 0, resumes_ = 0;  // restarts of the simulation node; of them resumed from the journal
  int final_part_ = 0;                   // closeRecording: the last part
  bool part_closed_ = false;             // closeRecording: closed before the manifest
  int next_part_ = 2;
  double recorder_timeout_ = 30.0;
  double min_free_mb_ = 20.0;
  ros::Time forced_end_;  // a STOP of this node's own (disk full)
  ros::Time stop_stamp_;  // of the STOP sent
  ros::Time ended_at_;    // stamp of the scenario_status that first reported the session ended (FINISHED/FAILED)
  // Input time after the session's planned end (plus tail, plus the simulation's lag when the STOP went out) at which
  // a session whose STOP never took effect is closed anyway (a simulation that stopped applying commands).
  const ros::Duration kStopGrace{10.0};
  ros::Duration stop_lag_;  // input time by which the simulation's newest frame trailed the present at the STOP
  std::string stop_reason_;
  ros::WallTime first_frame_wall_;  // the recorder's ~part: the part its next start records into
  ros::WallTime last_note_;
  ros::Time newest_, start_;
  bool started_ = false, stop_sent_ = false, scenario_ended_ = false;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "session_control");  // takes the remappings (name:=value) out of argv
  vrm_sim::cli::CommandLine cli(
      "session_control", "[NAME:=VALUE ...]",
      "Frames a recorded session: START once the recorder listens, STOP after ~duration s of input time.",
      "Private parameters: recorder (/session_recorder), topics, duration (s; 0 = until Ctrl-C), start (true),\n"
      "start_delay (0.5 s), tail (1.0 s), bag, recorder_timeout (30 s), min_free_mb (20: the session stops below\n"
      "this free space on the bag's file system).");
  if (const auto status = cli.parse(argc, argv)) return *status;
  SessionControl control;
  ros::spin();
  control.reportParts();
  return 0;
}
