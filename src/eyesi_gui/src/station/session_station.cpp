// session_station: the simulator host's side of the console (thesis §2.4, §7.3). A console asks it — only through
// services and topics, so from any host of the ROS graph — for the scene library and to start a session: the
// station then runs one session graph (launch/simulator.launch, headless, the console's scene / difficulty / seed /
// user, START from the console; or launch/replay.launch for a recorded bag) as a child roslaunch under the same
// master, reports its loading progress and state on `station_status`, and stops it once the session is over (which
// also closes its bag). One graph per session: every session starts from a freshly loaded scene, its bag begins with
// that scene's session_info, and a scene switch reloads everything that depends on the scene (simulation, rendering,
// the simulated devices) the same way.
//
// Services (private): list_scenes (vrm_msgs/ListScenes), load_session (vrm_msgs/LoadSession), end_session
//   (std_srvs/Trigger), play_ghost (vrm_msgs/PlayGhost: a recorded session's instruments as ghosts).
// Publishes: station_status (vrm_msgs/StationStatus, latched, on every change and at 2 Hz while loading).
// Subscribes (the running graph's): session_info, scenario_status, simulation_state, session_result.
// Parameters (private): simulator_launch, replay_launch (launch file paths), records_dir (bags, results and graph
//   logs; default ~/.ros/eyesi/sessions), launch_args (extra roslaunch arguments for every session graph, e.g.
//   "sim:=true tracking:=false"), script (scripted surgeon of a simulated session, default scenario:expert),
//   load_timeout (s, default 90), end_tail (s of wall time recorded after the session's end, default 1.0).
#include <fcntl.h>
#include <ros/master.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <signal.h>
#include <std_srvs/Trigger.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <boost/make_shared.hpp>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <fstream>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "vrm_msgs/ListScenes.h"
#include "vrm_msgs/LoadSession.h"
#include "vrm_msgs/PlayGhost.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/SessionInfo.h"
#include "vrm_msgs/SessionResult.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_msgs/StationStatus.h"
#include "vrm_sim/package_data.h"
#include "vrm_sim/scene/scene_loader.h"

namespace {

std::string expandHome(const std::string& path) {
  if (path.rfind("~/", 0) != 0) return path;
  const char* home = std::getenv("HOME");
  return std::string(home ? home : "/tmp") + path.substr(1);
}

// Folders it creates are private (0700): the sessions' bags, results and logs name the trainee (SECURITY.md).
// Existing folders keep their mode.
void makeDirectories(const std::string& path) {
  for (std::size_t slash = path.find('/', 1); slash != std::string::npos; slash = path.find('/', slash + 1))
    ::mkdir(path.substr(0, slash).c_str(), 0700);
  ::mkdir(path.c_str(), 0700);
}

// Names safe in a file name: letters, digits, '-', '_'.
std::string fileSafe(const std::string& text) {
  std::string out;
  for (char c : text) out += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
  return out.empty() ? "guest" : out;
}

// Whether the bag holds messages on `topic` (its index only; false when it cannot be read).
bool bagHasTopic(const std::string& path, const std::string& topic) {
  try {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    return rosbag::View(bag, rosbag::TopicQuery(topic)).size() > 0;
  } catch (const rosbag::BagException&) {
    return false;
  }
}

std::string hostName() {
  char host[256] = {0};
  return gethostname(host, sizeof(host) - 1) == 0 ? host : "";
}

// A child process in its own process group (roslaunch and everything it starts), output to a log file.
class ChildProcess {
 public:
  ChildProcess(const std::vector<std::string>& argv, const std::string& log_path) {
    // Everything the child needs is prepared before fork: after it, only async-signal-safe calls until exec.
    std::vector<char*> args;
    for (const std::string& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
    args.push_back(nullptr);
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
    if (pid_ == 0) {
      ::setpgid(0, 0);
      // A ROS thread forked us with signals blocked: roslaunch must see SIGINT to shut its nodes down (else they are
      // orphaned and rosbag never closes its bag).
      sigset_t none;
      sigemptyset(&none);
      ::sigprocmask(SIG_SETMASK, &none, nullptr);
      for (int signal_number : {SIGINT, SIGTERM, SIGHUP, SIGPIPE}) ::signal(signal_number, SIG_DFL);
      const int log = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (log >= 0) {
        ::dup2(log, STDOUT_FILENO);
        ::dup2(log, STDERR_FILENO);
        ::close(log);
      }
      ::execvp(args[0], args.data());
      static const char kFailed[] = "session_station: exec failed\n";
      (void)!::write(STDERR_FILENO, kFailed, sizeof(kFailed) - 1);
      ::_exit(127);
    }
    ::setpgid(pid_, pid_);
  }
  ~ChildProcess() { stop(10.0); }

  // Exit status once it ended (waitpid), else nullopt.
  std::optional<int> poll() {
    if (status_) return status_;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_)
      status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    return status_;
  }

  // SIGINT to the group (roslaunch shuts its nodes down cleanly, rosbag closes its bag), then SIGTERM, SIGKILL.
  void stop(double grace_seconds) {
    if (poll()) return;
    for (int signal_number : {SIGINT, SIGTERM, SIGKILL}) {
      ::kill(-pid_, signal_number);
      const double limit = signal_number == SIGINT ? grace_seconds : 3.0;
      for (double waited = 0.0; waited < limit; waited += 0.05) {
        if (poll()) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    }
  }

 private:
  pid_t pid_ = -1;
  std::optional<int> status_;
};

std::string lastLines(const std::string& path, std::size_t count) {
  std::ifstream file(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(file, line);)
    if (!line.empty()) lines.push_back(line);
  std::string out;
  for (std::size_t i = lines.size() > count ? lines.size() - count : 0; i < lines.size(); ++i) out += lines[i] + "\n";
  return out;
}

}  // namespace

class SessionStation {
 public:
  SessionStation() : private_nh_("~") {
    vrm_sim::usePackageData();  // the scene library (~list_scenes): vrm_sim's shipped scenes
    simulator_launch_ = private_nh_.param<std::string>("simulator_launch", "");
    replay_launch_ = private_nh_.param<std::string>("replay_launch", "");
    records_dir_ = expandHome(private_nh_.param<std::string>("records_dir", "~/.ros/eyesi/sessions"));
    launch_args_ = private_nh_.param<std::string>("launch_args", "");
    script_ = private_nh_.param<std::string>("script", "scenario:expert");
    load_timeout_ = private_nh_.param("load_timeout", 90.0);
    end_tail_ = private_nh_.param("end_tail", 1.0);
    makeDirectories(records_dir_);
    status_.station = hostName();
    status_.state = vrm_msgs::StationStatus::IDLE;

    status_publisher_ = private_nh_.advertise<vrm_msgs::StationStatus>("station_status", 5, true);
    services_.push_back(private_nh_.advertiseService("list_scenes", &SessionStation::listScenes, this));
    services_.push_back(private_nh_.advertiseService("load_session", &SessionStation::loadSession, this));
    services_.push_back(private_nh_.advertiseService("end_session", &SessionStation::endSession, this));
    services_.push_back(private_nh_.advertiseService("play_ghost", &SessionStation::playGhost, this));
    info_subscriber_ = nh_.subscribe("session_info", 1, &SessionStation::onSessionInfo, this);
    status_subscriber_ = nh_.subscribe("scenario_status", 5, &SessionStation::onScenarioStatus, this);
    state_subscriber_ = nh_.subscribe("simulation_state", 1, &SessionStation::onSimulationState, this);
    result_subscriber_ = nh_.subscribe("session_result", 1, &SessionStation::onSessionResult, this);
    timer_ = nh_.createWallTimer(ros::WallDuration(0.5), &SessionStation::onTimer, this);
    publishStatus("station ready: records in " + records_dir_);
    ROS_INFO("session_station on %s: records in %s, session graphs from %s", status_.station.c_str(),
             records_dir_.c_str(), simulator_launch_.c_str());
    if (private_nh_.hasParam("initial_scene")) {
      vrm_msgs::LoadSession::Request request;
      vrm_msgs::LoadSession::Response response;
      request.scene = private_nh_.param<std::string>("initial_scene", "");
      request.user = private_nh_.param<std::string>("initial_user", "guest");
      if (!request.scene.empty()) loadSession(request, response);
    }
  }

  ~SessionStation() {
    std::lock_guard<std::mutex> lock(mutex_);
    ghost_.reset();
    graph_.reset();
  }

 private:
  bool listScenes(vrm_msgs::ListScenes::Request&, vrm_msgs::ListScenes::Response& response) {
    for (const std::string& name : vrm_sim::scene::shippedScenes()) {
      try {
        const auto scene = vrm_sim::scene::loadScene(vrm_sim::scene::shippedScenePath(name));
        vrm_msgs::SceneEntry entry;
        entry.name = scene.name;
        entry.description = scene.description;
        if (scene.scenario) {
          entry.scenario = scene.scenario->type;
          entry.scenario_description = scene.scenario->description;
          entry.difficulties = scene.scenario->difficulty_levels;
          entry.default_difficulty = scene.scenario->difficulty;
          entry.time_limit = scene.scenario->time_limit;
          for (const auto& rule : scene.scenario->scoring) {
            entry.score_items.push_back(rule.item);
            entry.score_weights.push_back(rule.weight);
          }
        }
        for (const auto& instrument : scene.instruments) {
          vrm_msgs::InstrumentSlot slot;
          slot.slot = vrm_sim::scene::toString(instrument.slot);
          slot.type = vrm_sim::scene::toString(instrument.type);
          for (const auto type : instrument.alternatives) slot.alternatives.push_back(vrm_sim::scene::toString(type));
          entry.instruments.push_back(slot);
        }
        response.scenes.push_back(entry);
      } catch (const std::exception& error) {
        response.errors.push_back(name + ": " + error.what());
      }
    }
    return true;
  }

  bool loadSession(vrm_msgs::LoadSession::Request& request, vrm_msgs::LoadSession::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    const bool replay = request.mode == "replay";
    if (!replay && request.mode != "session" && !request.mode.empty()) {
      response.message = "unknown mode '" + request.mode + "' (session or replay)";
      return true;
    }
    if (replay ? request.bag.empty() : request.scene.empty()) {
      response.message = replay ? "replay needs a bag" : "no scene given";
      return true;
    }
    if (!replay && request.scene.find('/') != std::string::npos) {
      response.message = "scene '" + request.scene + "' is not a name of the station's scene library";
      return true;
    }
    if (replay && ::access(request.bag.c_str(), R_OK) != 0) {
      response.message = "bag " + request.bag + " is not readable on station " + status_.station;
      return true;
    }
    stopGraph();
    std::uint32_t seed = request.seed;
    if (!replay && seed == 0) seed = std::random_device{}() % 1000000 + 1;
    char stamp[32];
    const std::time_t now = std::time(nullptr);
    std::strftime(stamp, sizeof(stamp), "%Y%m%d-%H%M%S", std::gmtime(&now));
    const std::string user = request.user.empty() ? "guest" : request.user;
    const std::string stem =
        records_dir_ + "/" + stamp + "_" + fileSafe(user) + "_" + fileSafe(replay ? "replay" : request.scene);
    std::vector<std::string> argv = {"roslaunch", "--skip-log-check"};
    vrm_msgs::StationStatus next;
    next.station = status_.station;
    next.user = user;
    next.seed = seed;
    if (replay) {
      argv.push_back(replay_launch_);
      argv.push_back("bag:=" + request.bag);
      next.mode = "replay";
      next.bag = request.bag;
    } else {
      argv.push_back(simulator_launch_);
      for (const std::string& arg :
           std::vector<std::string>{"headless:=true", "auto_start:=false", "ghosts:=true", "scene:=" + request.scene,
                                    "difficulty:=" + request.difficulty, "seed:=" + std::to_string(seed),
                                    "user:=" + user, "script:=" + (request.script.empty() ? script_ : request.script),
                                    std::string("record:=") + (request.record ? "true" : "false")})
        argv.push_back(arg);
      next.mode = "session";
      next.scene = request.scene;
      next.difficulty = request.difficulty;
      next.recording = request.record;
      if (request.record) {
        next.bag = stem + ".bag";
        next.result_file = stem + ".result.json";  // scenario_manager writes it next to the bag
        argv.push_back("bag:=" + next.bag);
      } else {
        next.result_file = stem + ".result.json";
        argv.push_back("result_file:=" + next.result_file);
      }
    }
    std::istringstream extra(launch_args_);
    for (std::string arg; extra >> arg;) argv.push_back(arg);
    // A replay leaves use_sim_time set on the master; a live graph must run on the wall clock.
    if (!replay) ros::param::del("/use_sim_time");
    log_path_ = stem + ".log";
    try {
      graph_ = std::make_unique<ChildProcess>(argv, log_path_);
    } catch (const std::exception& error) {
      response.message = error.what();
      return true;
    }
    launched_at_ = ros::WallTime::now();
    launched_stamp_ = ros::Time::now();
    seen_info_ = seen_idle_ = seen_frame_ = seen_result_ = false;
    ended_at_ = ros::WallTime();
    next.state = vrm_msgs::StationStatus::LOADING;
    next.progress = 0.05f;
    status_ = next;
    std::string command;
    for (const std::string& arg : argv) command += " " + arg;
    ROS_INFO("session_station: starting%s (log %s)", command.c_str(), log_path_.c_str());
    publishStatus(replay ? "replaying " + request.bag : "loading " + request.scene);
    response.accepted = true;
    response.seed = seed;
    response.bag = next.bag;
    response.result_file = next.result_file;
    response.message = status_.message;
    return true;
  }

  bool endSession(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    const bool running = graph_ != nullptr;
    stopGraph();
    if (status_.state != vrm_msgs::StationStatus::ENDED) status_.state = vrm_msgs::StationStatus::IDLE;
    publishStatus(running ? "session graph stopped" : "no session graph was running");
    response.success = true;
    response.message = status_.message;
    return true;
  }

  bool playGhost(vrm_msgs::PlayGhost::Request& request, vrm_msgs::PlayGhost::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    ghost_.reset();
    if (request.bag.empty()) {
      response.accepted = true;
      response.message = "ghost stopped";
      return true;
    }
    if (::access(request.bag.c_str(), R_OK) != 0) {
      response.message = "bag " + request.bag + " is not readable on station " + status_.station;
      return true;
    }
    const double rate = request.rate > 0.0 ? request.rate : 1.0;
    // The recorded input frames (the instruments as the instructor's World applied them), under the ghost topic the
    // renderer draws translucent; their stamps stay the recorded ones (the renderer does not let ghost stamps stamp
    // a frame). A bag recorded before input frames (issue 31) has only the raw instrument states: those, onto the
    // renderer's legacy ghost topic.
    const std::string topic = bagHasTopic(request.bag, "/input_frame") ? "/input_frame" : "/instrument_state";
    ghost_ = std::make_unique<ChildProcess>(
        std::vector<std::string>{"rosbag", "play", "--quiet", "-r", std::to_string(rate), request.bag, "--topics",
                                 topic, topic + ":=/ghost" + topic},
        records_dir_ + "/ghost.log");
    response.accepted = true;
    response.message = "ghost of " + request.bag;
    ROS_INFO("session_station: playing %s as ghost instruments", request.bag.c_str());
    return true;
  }

  void onSessionInfo(const vrm_msgs::SessionInfo::ConstPtr& info) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (status_.state != vrm_msgs::StationStatus::LOADING) return;
    // A replay's session_info comes from the bag (old stamp); a live one is stamped when its graph started.
    if (status_.mode == "session" && info->header.stamp < launched_stamp_) return;
    seen_info_ = true;
    if (status_.mode == "replay") {
      status_.scene = info->scene;
      status_.difficulty = info->difficulty;
      status_.seed = info->seed;
    }
  }

  void onScenarioStatus(const vrm_msgs::ScenarioStatus::ConstPtr& scenario) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!graph_ || scenario->scenario != status_.scene) return;
    if (scenario->state == vrm_msgs::ScenarioStatus::IDLE) seen_idle_ = true;
    if (scenario->state == vrm_msgs::ScenarioStatus::RUNNING &&
        (status_.state == vrm_msgs::StationStatus::READY || status_.state == vrm_msgs::StationStatus::LOADING)) {
      status_.state = vrm_msgs::StationStatus::RUNNING;
      publishStatus("session running");
    }
  }

  void onSimulationState(const vrm_msgs::SimulationState::ConstPtr& state) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (status_.mode == "replay" || state->header.stamp >= launched_stamp_) seen_frame_ = true;
  }

  void onSessionResult(const vrm_msgs::SessionResult::ConstPtr& result) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!graph_ || seen_result_) return;
    if (status_.mode == "session" && result->header.stamp < launched_stamp_) return;  // the previous graph's
    seen_result_ = true;
    ended_at_ = ros::WallTime::now();
    ROS_INFO("session_station: session over (final state %s); stopping its graph in %.1f s",
             result->final_state_hash.c_str(), end_tail_);
  }

  void onTimer(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (ghost_ && ghost_->poll()) ghost_.reset();
    if (!graph_) return;
    if (const auto exit_status = graph_->poll()) {
      graph_.reset();
      if (seen_result_ || (status_.mode == "replay" && *exit_status == 0)) {
        status_.state = vrm_msgs::StationStatus::ENDED;
        publishStatus(status_.mode == "replay" ? "replay finished" : "session over");
      } else {
        status_.state = vrm_msgs::StationStatus::FAILED;
        publishStatus("the session graph ended (exit " + std::to_string(*exit_status) +
                      "): " + lastLines(log_path_, 3));
      }
      return;
    }
    if (seen_result_) {
      if ((ros::WallTime::now() - ended_at_).toSec() >= end_tail_) {
        stopGraph();
        status_.state = vrm_msgs::StationStatus::ENDED;
        publishStatus("session over");
      }
      return;
    }
    if (status_.state != vrm_msgs::StationStatus::LOADING) return;
    const bool recorder_ready = !status_.recording || recorderListens();
    const float progress = 0.05f + 0.25f * seen_info_ + 0.3f * seen_idle_ + 0.3f * seen_frame_ + 0.1f * recorder_ready;
    const bool ready =
        status_.mode == "replay" ? seen_frame_ : seen_info_ && seen_idle_ && seen_frame_ && recorder_ready;
    if (ready) {
      status_.state = status_.mode == "replay" ? vrm_msgs::StationStatus::RUNNING : vrm_msgs::StationStatus::READY;
      status_.progress = 1.0f;
      publishStatus(status_.mode == "replay" ? "replay playing" : "ready: " + status_.scene);
    } else if ((ros::WallTime::now() - launched_at_).toSec() > load_timeout_) {
      stopGraph();
      status_.state = vrm_msgs::StationStatus::FAILED;
      publishStatus("the session graph did not get ready within " + std::to_string(int(load_timeout_)) +
                    " s: " + lastLines(log_path_, 3));
    } else {
      status_.progress = progress;
      publishStatus(std::string("loading ") + status_.scene + (seen_frame_ ? ": waiting for the recorder" : ""));
    }
  }

  // The recorder of this graph subscribes to every recorded input (else START could go unrecorded).
  bool recorderListens() const {
    ros::master::V_TopicInfo unused;
    XmlRpc::XmlRpcValue request, response, payload;
    request[0] = ros::this_node::getName();
    if (!ros::master::execute("getSystemState", request, response, payload, false)) return false;
    const XmlRpc::XmlRpcValue& subscriptions = payload[1];
    int topics = 0;
    for (int i = 0; i < subscriptions.size(); ++i) {
      const std::string topic = static_cast<std::string>(subscriptions[i][0]);
      // The input frames too: a START lost there would never start the replay's scenario.
      if (topic != "/scenario_command" && topic != "/instrument_state" && topic != "/session_info" &&
          topic != "/input_frame")
        continue;
      for (int j = 0; j < subscriptions[i][1].size(); ++j)
        if (static_cast<std::string>(subscriptions[i][1][j]) == "/session_recorder") ++topics;
    }
    return topics == 4;
  }

  void stopGraph() {
    ghost_.reset();
    if (!graph_) return;
    graph_->stop(15.0);
    graph_.reset();
  }

  void publishStatus(const std::string& message) {
    status_.message = message;
    status_.header.stamp = ros::Time::now();  // the station's own wall clock: not part of any session's inputs
    auto out = boost::make_shared<vrm_msgs::StationStatus>(status_);
    status_publisher_.publish(out);
  }

  ros::NodeHandle nh_, private_nh_;
  std::mutex mutex_;
  std::string simulator_launch_, replay_launch_, records_dir_, launch_args_, script_, log_path_;
  double load_timeout_ = 90.0, end_tail_ = 1.0;
  vrm_msgs::StationStatus status_;
  std::unique_ptr<ChildProcess> graph_, ghost_;
  ros::WallTime launched_at_, ended_at_;
  ros::Time launched_stamp_;
  bool seen_info_ = false, seen_idle_ = false, seen_frame_ = false, seen_result_ = false;
  ros::Publisher status_publisher_;
  std::vector<ros::ServiceServer> services_;
  ros::Subscriber info_subscriber_, status_subscriber_, state_subscriber_, result_subscriber_;
  ros::WallTimer timer_;
};

int main(int argc, char** argv) {
  ros::init(argc, argv, "station");
  // Several threads: a graph stop (up to 15 s) in a service call must not stall the status timer for long.
  ros::AsyncSpinner spinner(2);
  SessionStation station;
  spinner.start();
  ros::waitForShutdown();
  return 0;
}
