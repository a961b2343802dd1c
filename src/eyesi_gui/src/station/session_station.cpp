// session_station: the simulator host's side of the console (thesis §2.4, §7.3). A console asks it — only through
// services and topics, so from any host of the ROS graph — for the scene library and to start a session. The station
// runs one session graph (launch/simulator.launch, headless, under the same master as a child roslaunch) and keeps it
// up across sessions (issue 32): the first live session launches it with its scene; every later one switches the
// scene with a ScenarioCommand LOAD (scene, difficulty, seed) and follows scenario_manager, the one scene owner, until
// it announces the scene on `running_scene` (a higher load count) or refuses it (the old scene then keeps running and
// the console is told why). The new scene's first frame comes 0.05-0.5 s after the request instead of 4-6 s.
// Only the recorder is per session: each recorded session gets its own recorder graph (launch/recorder.launch) and
// bag, started once the new scene's session_info is out, so the bag begins with it; the station reports READY (and the
// console sends START) only once that recorder listens. The result file next to the bag is the station's: the graph's
// scenario_manager was started for the first session only, so the station writes each session's result (from
// session_result) with that session's bag and user.
// A station that crashes loses nothing (issue 39 §2): simulator.launch starts it again, and it takes over the graph,
// the recorder and the session its predecessor left (the state file <records_dir>/station_state.json, takeOver()); a
// session that ended meanwhile gets its result file from the latched session_result, and one whose graph died
// meanwhile from a replay of its bag.
// A replay (mode "replay") runs launch/replay.launch instead, a graph of its own (bag time, the bag's scene); the
// live graph is stopped for it, and the next live session launches a new one. A live graph that died is launched
// again by the next session, as is one whose surgeon script differs from the requested one (a launch argument).
//
// Services (private): list_scenes (vrm_msgs/ListScenes), load_session (vrm_msgs/LoadSession), end_session
//   (std_srvs/Trigger: ends the session and its recording; the live graph stays up), play_ghost (vrm_msgs/PlayGhost:
//   a recorded session's instruments as ghosts).
// Publishes: station_status (vrm_msgs/StationStatus, latched, on every change and at 2 Hz while loading);
//   scenario_command (the LOADs).
// Subscribes (the running graph's): running_scene, session_info, scenario_status, simulation_state, session_result.
// Parameters (private): simulator_launch, replay_launch, recorder_launch (launch file paths; recorder_launch defaults
//   to recorder.launch next to simulator_launch), records_dir (bags, results and graph logs; default
//   ~/.ros/eyesi/sessions), launch_args (extra roslaunch arguments for every session graph, e.g.
//   "sim:=true tracking:=false"), script (scripted surgeon of a simulated session, default scenario:expert),
//   load_timeout (s, default 90), end_tail (s of wall time recorded after the session's end, default 1.0),
//   scene_owner (the node whose start-up scene parameters follow each accepted LOAD, default /scenario_manager).
#include <fcntl.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <ros/xmlrpc_manager.h>
#include <signal.h>
#include <spawn.h>
#include <std_srvs/Trigger.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/make_shared.hpp>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "vrm_msgs/ListScenes.h"
#include "vrm_msgs/LoadSession.h"
#include "vrm_msgs/PlayGhost.h"
#include "vrm_msgs/RunningScene.h"
#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/SessionInfo.h"
#include "vrm_msgs/SessionResult.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_msgs/StationStatus.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/result/session_result.h"

namespace {

// recorder.launch's default node name, and the prefix of the per-session names the station gives (startRecorder).
constexpr const char* kRecorderNodePrefix = "/session_recorder";

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

// Whether the bag holds messages on `topic` (false when it cannot be read). Asked of `rosbag info` (its index only,
// ~0.7 s) in a spawned process rather than through librosbag: the station links no bag library (issue 42), and this
// is its one question about a bag's content.
bool bagHasTopic(const std::string& path, const std::string& topic) {
  int pipe_ends[2];
  if (::pipe(pipe_ends) != 0) return false;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_ends[1], STDOUT_FILENO);
  posix_spawn_file_actions_addclose(&actions, pipe_ends[0]);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  std::vector<std::string> arguments = {"rosbag", "info", "--yaml", "--key=topics", path};
  std::vector<char*> argv;
  for (std::string& argument : arguments) argv.push_back(argument.data());
  argv.push_back(nullptr);
  pid_t child = -1;
  const int spawned = posix_spawnp(&child, "rosbag", &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(pipe_ends[1]);
  std::string output;
  char buffer[4096];
  for (ssize_t n; spawned == 0 && (n = ::read(pipe_ends[0], buffer, sizeof(buffer))) != 0;) {
    if (n > 0)
      output.append(buffer, static_cast<std::size_t>(n));
    else if (errno != EINTR)
      break;
  }
  ::close(pipe_ends[0]);
  int status = 0;
  if (spawned != 0 || ::waitpid(child, &status, 0) != child || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return false;
  }
  // A list of {topic, type, messages, frequency}: the entry of `topic` and its message count.
  std::istringstream lines(output);
  bool in_entry = false;
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("- topic: ", 0) == 0) in_entry = line.substr(9) == topic;
    const auto messages = line.find("messages: ");
    if (in_entry && messages != std::string::npos) return std::atol(line.c_str() + messages + 10) > 0;
  }
  return false;
}

std::string hostName() {
  char host[256] = {0};
  return gethostname(host, sizeof(host) - 1) == 0 ? host : "";
}

// /proc/<pid>/stat after the command name (which may hold spaces and parentheses): state, ppid, pgrp, ... ; empty
// when there is no such process.
std::vector<std::string> procStatFields(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(stat, line)) return {};
  const std::size_t close = line.rfind(')');
  if (close == std::string::npos) return {};
  std::istringstream rest(line.substr(close + 1));
  std::vector<std::string> fields;
  for (std::string field; rest >> field;) fields.push_back(field);
  return fields;
}

// The process's start time (clock ticks after boot, /proc/<pid>/stat field 22): with the pid it names one process,
// not a later one that reuses the number. 0 when there is no such process.
std::uint64_t processStartTime(pid_t pid) {
  const std::vector<std::string> fields = procStatFields(pid);
  return fields.size() > 19 ? std::stoull(fields[19]) : 0;
}

// Whether the process runs (exists and is not a zombie: an orphan's reaper may be slow or absent in a container).
bool processRuns(pid_t pid) {
  const std::vector<std::string> fields = procStatFields(pid);
  return !fields.empty() && fields[0] != "Z" && fields[0] != "X";
}

std::string processCommandLine(pid_t pid) {
  std::ifstream file("/proc/" + std::to_string(pid) + "/cmdline");
  std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  std::replace(text.begin(), text.end(), '\0', ' ');
  return text;
}

// A child process in its own process group (roslaunch and everything it starts), output to a log file.
class ChildProcess {
 public:
  static constexpr int kUnknownExit = -1;  // an adopted process's exit status: it was not ours to wait for

  // A process group this station started before it crashed and was started again (the station's state file names
  // it): its leader's pid and start time. It is not our child, so poll() reads /proc instead of waitpid().
  static std::unique_ptr<ChildProcess> adopt(pid_t pid, std::uint64_t start_time) {
    if (pid <= 1 || start_time == 0 || processStartTime(pid) != start_time || ::getpgid(pid) != pid ||
        !processRuns(pid))
      return nullptr;
    std::unique_ptr<ChildProcess> process(new ChildProcess());
    process->pid_ = pid;
    process->start_time_ = start_time;
    process->adopted_ = true;
    return process;
  }

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
    start_time_ = processStartTime(pid_);  // set by the fork, kept across the exec
  }
  ~ChildProcess() { stop(10.0); }

  pid_t pid() const { return pid_; }
  // Its start time (/proc), read once: with the pid it names the process in the station's state file.
  std::uint64_t startTime() const { return start_time_; }

  // SIGINT to the group now; finishStopping() escalates later, so the caller is not blocked while it shuts down.
  void interrupt() {
    if (poll()) return;
    ::kill(-pid_, SIGINT);
    interrupted_at_ = std::chrono::steady_clock::now();
  }

  // Whether it ended; `grace_seconds` after interrupt() SIGTERM, 3 s later SIGKILL.
  bool finishStopping(double grace_seconds) {
    if (poll()) return true;
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - interrupted_at_).count();
    if (waited > grace_seconds) ::kill(-pid_, waited > grace_seconds + 3.0 ? SIGKILL : SIGTERM);
    return false;
  }

  // Exit status once it ended (waitpid), else nullopt.
  std::optional<int> poll() {
    if (status_) return status_;
    if (adopted_) {
      if (!processRuns(pid_)) status_ = kUnknownExit;
      return status_;
    }
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
  ChildProcess() = default;

  pid_t pid_ = -1;
  std::uint64_t start_time_ = 0;
  bool adopted_ = false;
  std::optional<int> status_;
  std::chrono::steady_clock::time_point interrupted_at_;
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

// Whether `pid` is `ancestor` or one of its descendants (/proc): roslaunch starts its nodes in sessions of their own,
// so the process group does not tell which launch a node belongs to.
bool descendsFrom(pid_t pid, pid_t ancestor) {
  for (int depth = 0; pid > 1 && depth < 16; ++depth) {
    if (pid == ancestor) return true;
    const std::vector<std::string> fields = procStatFields(pid);
    if (fields.size() < 2) return false;
    pid = static_cast<pid_t>(std::stol(fields[1]));
  }
  return false;
}

// The process id of a registered node (master lookupNode, then the node's getPid), or -1.
pid_t nodePid(const std::string& node) {
  XmlRpc::XmlRpcValue request, response, payload;
  request[0] = ros::this_node::getName();
  request[1] = node;
  if (!ros::master::execute("lookupNode", request, response, payload, false) ||
      payload.getType() != XmlRpc::XmlRpcValue::TypeString)
    return -1;
  std::string host;
  std::uint32_t port = 0;
  if (!ros::network::splitURI(static_cast<std::string>(payload), host, port)) return -1;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue pid_request, pid_response;
  pid_request[0] = ros::this_node::getName();
  const bool ok = client.execute("getPid", pid_request, pid_response) && !client.isFault() &&
                  pid_response.getType() == XmlRpc::XmlRpcValue::TypeArray && pid_response.size() == 3 &&
                  pid_response[2].getType() == XmlRpc::XmlRpcValue::TypeInt;
  client.close();
  return ok ? static_cast<int>(pid_response[2]) : -1;
}

std::string dirName(const std::string& path) {
  const std::size_t slash = path.rfind('/');
  return slash == std::string::npos ? "." : path.substr(0, slash);
}

}  // namespace

class SessionStation {
 public:
  SessionStation() : private_nh_("~") {
    vrm_sim::usePackageData();  // the scene library (~list_scenes): vrm_sim's shipped scenes
    simulator_launch_ = private_nh_.param<std::string>("simulator_launch", "");
    replay_launch_ = private_nh_.param<std::string>("replay_launch", "");
    recorder_launch_ =
        private_nh_.param<std::string>("recorder_launch", dirName(simulator_launch_) + "/recorder.launch");
    records_dir_ = expandHome(private_nh_.param<std::string>("records_dir", "~/.ros/eyesi/sessions"));
    launch_args_ = private_nh_.param<std::string>("launch_args", "");
    script_ = private_nh_.param<std::string>("script", "scenario:expert");
    load_timeout_ = private_nh_.param("load_timeout", 90.0);
    end_tail_ = private_nh_.param("end_tail", 1.0);
    scene_owner_ = private_nh_.param<std::string>("scene_owner", "/scenario_manager");
    makeDirectories(records_dir_);
    status_.station = hostName();
    status_.state = vrm_msgs::StationStatus::IDLE;

    status_publisher_ = private_nh_.advertise<vrm_msgs::StationStatus>("station_status", 5, true);
    command_publisher_ = nh_.advertise<vrm_msgs::ScenarioCommand>("scenario_command", 5);
    services_.push_back(private_nh_.advertiseService("list_scenes", &SessionStation::listScenes, this));
    services_.push_back(private_nh_.advertiseService("load_session", &SessionStation::loadSession, this));
    services_.push_back(private_nh_.advertiseService("end_session", &SessionStation::endSession, this));
    services_.push_back(private_nh_.advertiseService("play_ghost", &SessionStation::playGhost, this));
    scene_subscriber_ = nh_.subscribe("running_scene", 5, &SessionStation::onRunningScene, this);
    info_subscriber_ = nh_.subscribe("session_info", 5, &SessionStation::onSessionInfo, this);
    status_subscriber_ = nh_.subscribe("scenario_status", 20, &SessionStation::onScenarioStatus, this);
    state_subscriber_ = nh_.subscribe("simulation_state", 5, &SessionStation::onSimulationState, this);
    result_subscriber_ = nh_.subscribe("session_result", 2, &SessionStation::onSessionResult, this);
    // 10 Hz: a session is READY within 0.1 s of its last condition (the switch time the console sees).
    timer_ = nh_.createWallTimer(ros::WallDuration(0.1), &SessionStation::onTimer, this);
    ROS_INFO("session_station on %s: records in %s, session graph from %s", status_.station.c_str(),
             records_dir_.c_str(), simulator_launch_.c_str());
    std::string took_over;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      took_over = takeOver();
      publishStatus(took_over.empty() ? "station ready: records in " + records_dir_ : took_over);
    }
    if (!took_over.empty()) ROS_WARN("session_station: %s", took_over.c_str());
    if (took_over.empty() && private_nh_.hasParam("initial_scene")) {
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
    recorder_.reset();  // first: the bag closes while the graph still runs
    closing_recorders_.clear();
    graph_.reset();
    // Stopped on purpose: nothing for a next station to take over, unless a result was still being recovered.
    if (!recovery_) std::remove(statePath().c_str());
    recovery_.reset();
  }

 private:
  // The live session's progress towards READY: the scene owner's announcement of its scene, that scene's
  // session_info, a frame of it and (recorded) its own recorder listening.
  struct Loading {
    bool launched = false;  // a new graph; else a LOAD into the running one
    bool load_sent = false;
    ros::Time load_stamp;            // the LOAD's input stamp
    std::uint32_t loads_before = 0;  // running_scene's load count when the LOAD went out
    bool announced = false, seen_info = false, seen_frame = false;
    ros::WallTime requested_at, announced_at, first_frame_at;
  };

  // A session whose graph ended while no station ran: its result comes from a replay of its bag (session_replay, a
  // process of its own), for the file and trainee the session had.
  struct Recovery {
    std::unique_ptr<ChildProcess> replay;
    std::string output, result_file, bag, user;
  };

  // What a refused LOAD returns to: the session that ran before the request.
  struct Session {
    vrm_msgs::StationStatus status;
    ros::Time stamp;
    std::string stem;
    bool seen_result = false;
  };

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
    const ros::WallTime requested_at = ros::WallTime::now();
    // The previous session's bag closes as it is: it must not hold the LOAD, or its replay would end in the next
    // scene instead of the state its result reports (the LOAD waits until that recorder no longer listens).
    const bool was_recording = recorder_ != nullptr;
    closeRecorder();
    ghost_.reset();
    previous_ = {status_, session_stamp_, session_stem_, seen_result_};
    if (was_recording) previous_.status.recording = false;
    std::uint32_t seed = request.seed;
    if (!replay && seed == 0) seed = std::random_device{}() % 1000000 + 1;
    char stamp[32];
    const std::time_t now = std::time(nullptr);
    std::strftime(stamp, sizeof(stamp), "%Y%m%d-%H%M%S", std::gmtime(&now));
    const std::string user = request.user.empty() ? "guest" : request.user;
    const std::string stem =
        records_dir_ + "/" + stamp + "_" + fileSafe(user) + "_" + fileSafe(replay ? "replay" : request.scene);
    const std::string script = request.script.empty() ? script_ : request.script;
    vrm_msgs::StationStatus next;
    next.station = status_.station;
    next.user = user;
    next.seed = seed;
    next.mode = replay ? "replay" : "session";
    if (replay) {
      next.bag = request.bag;
    } else {
      next.scene = request.scene;
      next.difficulty = request.difficulty;
      next.recording = request.record;
      if (request.record) next.bag = stem + ".bag";
      next.result_file = stem + ".result.json";  // written by the station from session_result
    }
    // The surgeon's script is a launch argument of the graph: another one needs another graph.
    const bool reuse = !replay && graph_ && !graph_->poll() && graph_mode_ == "session" && graph_script_ == script;
    loading_ = Loading();
    loading_.requested_at = requested_at;
    seen_result_ = false;
    session_stem_ = stem;
    if (reuse) {
      status_ = next;
      status_.state = vrm_msgs::StationStatus::LOADING;
      status_.progress = 0.05f;
      sendLoad();
      publishStatus("switching to " + request.scene);
    } else {
      std::vector<std::string> argv = {"roslaunch", "--skip-log-check"};
      if (replay) {
        argv.push_back(replay_launch_);
        argv.push_back("bag:=" + request.bag);
      } else {
        argv.push_back(simulator_launch_);
        // No bag, result file or user: the graph outlives this session; the station writes each session's result.
        for (const std::string& arg :
             std::vector<std::string>{"headless:=true", "auto_start:=false", "ghosts:=true", "scene:=" + request.scene,
                                      "difficulty:=" + request.difficulty, "seed:=" + std::to_string(seed),
                                      "script:=" + script, "record:=false"})
          argv.push_back(arg);
      }
      std::istringstream extra(launch_args_);
      for (std::string arg; extra >> arg;) argv.push_back(arg);
      stopGraph();
      // A replay leaves use_sim_time set on the master; a live graph must run on the wall clock.
      if (!replay) ros::param::del("/use_sim_time");
      graph_log_ = stem + ".log";
      try {
        graph_ = std::make_unique<ChildProcess>(argv, graph_log_);
      } catch (const std::exception& error) {
        response.message = error.what();
        return true;
      }
      graph_mode_ = next.mode;
      graph_script_ = script;
      launched_stamp_ = ros::Time::now();
      session_stamp_ = launched_stamp_;
      loading_.launched = true;
      status_ = next;
      status_.state = vrm_msgs::StationStatus::LOADING;
      status_.progress = 0.05f;
      std::string command;
      for (const std::string& arg : argv) command += " " + arg;
      ROS_INFO("session_station: starting%s (log %s)", command.c_str(), graph_log_.c_str());
      publishStatus(replay ? "replaying " + request.bag : "loading " + request.scene);
    }
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
    const bool replay = graph_mode_ == "replay";
    // A live graph stays up for the next session (which switches its scene); only the session's recording ends.
    if (replay) {
      stopGraph();
    } else {
      closeRecorder();
      ghost_.reset();
    }
    loading_ = Loading();
    if (status_.state != vrm_msgs::StationStatus::ENDED) status_.state = vrm_msgs::StationStatus::IDLE;
    status_.recording = false;
    publishStatus(!running ? "no session graph was running"
                  : replay ? "replay graph stopped"
                           : "session ended; the session graph stays up for the next one");
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

  bool liveLoading() const { return status_.state == vrm_msgs::StationStatus::LOADING && status_.mode == "session"; }

  // The scene owner's decision (scenario_manager): the requested scene runs once it is announced here.
  void onRunningScene(const vrm_msgs::RunningScene::ConstPtr& scene) {
    std::lock_guard<std::mutex> lock(mutex_);
    loads_announced_ = scene->load;
    if (!liveLoading() || loading_.announced || scene->name != status_.scene) return;
    if (!status_.difficulty.empty() && scene->difficulty != status_.difficulty) return;
    // A new graph announces its start-up scene; a LOAD shows as a higher load count.
    if (!loading_.launched && !(loading_.load_sent && scene->load > loading_.loads_before)) return;
    loading_.announced = true;
    loading_.announced_at = ros::WallTime::now();
    if (!loading_.launched) {
      session_stamp_ = scene->header.stamp;
      // A manager that crashes is restarted with its start-up parameters: those now name the running scene, so a
      // restarted scene owner comes back with it (session_control then restarts the scenario on it).
      ros::param::set(scene_owner_ + "/scene", scene->file);
      ros::param::set(scene_owner_ + "/difficulty", scene->difficulty);
      ros::param::set(scene_owner_ + "/seed", static_cast<int>(scene->seed));
    }
    ROS_INFO("session_station: scene '%s' (%s) runs (load %u), %.2f s after the request", scene->name.c_str(),
             scene->difficulty.empty() ? "no difficulty" : scene->difficulty.c_str(), scene->load,
             (loading_.announced_at - loading_.requested_at).toSec());
  }

  void onSessionInfo(const vrm_msgs::SessionInfo::ConstPtr& info) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (status_.state != vrm_msgs::StationStatus::LOADING) return;
    if (status_.mode == "replay") {
      // A replay's session_info comes from the bag: it names the recorded scene.
      loading_.seen_info = true;
      status_.scene = info->scene;
      status_.difficulty = info->difficulty;
      status_.seed = info->seed;
      return;
    }
    // The new scene's (stamped when its graph started, or republished after the LOAD): the bag must begin with it.
    if (loading_.launched ? info->header.stamp < launched_stamp_ : !loading_.load_sent) return;
    if (info->scene != status_.scene || info->seed != status_.seed) return;
    if (!status_.difficulty.empty() && info->difficulty != status_.difficulty) return;
    loading_.seen_info = true;
  }

  void onScenarioStatus(const vrm_msgs::ScenarioStatus::ConstPtr& scenario) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!graph_) return;
    if (liveLoading() && loading_.load_sent && !loading_.announced &&
        scenario->message.find("LOAD '" + status_.scene + "'") != std::string::npos &&
        scenario->message.find("refused") != std::string::npos) {
      refuseLoad(scenario->message);
      return;
    }
    if (scenario->scenario != status_.scene) return;
    // Live: the new scene's status, not the previous session's (the same scene loaded again).
    if (status_.mode == "session" && (!loading_.announced || scenario->header.stamp < session_stamp_)) return;
    if (scenario->state == vrm_msgs::ScenarioStatus::RUNNING &&
        (status_.state == vrm_msgs::StationStatus::READY || status_.state == vrm_msgs::StationStatus::LOADING)) {
      status_.state = vrm_msgs::StationStatus::RUNNING;
      publishStatus("session running");
    }
  }

  // The scene owner refused the LOAD: the old scene runs on, so the station reports the old session again (its
  // recording, if any, ended with the request).
  void refuseLoad(const std::string& reason) {
    status_ = previous_.status;
    session_stamp_ = previous_.stamp;
    session_stem_ = previous_.stem;
    seen_result_ = previous_.seen_result;
    loading_ = Loading();
    loading_.announced = true;  // the old scene is the one that runs: its status and frames count again
    if (status_.state == vrm_msgs::StationStatus::LOADING) status_.state = vrm_msgs::StationStatus::IDLE;
    ROS_WARN("session_station: %s", reason.c_str());
    publishStatus(reason);
  }

  void onSimulationState(const vrm_msgs::SimulationState::ConstPtr& state) {
    std::lock_guard<std::mutex> lock(mutex_);
    newest_frame_ = std::max(newest_frame_, state->header.stamp);
    if (status_.state != vrm_msgs::StationStatus::LOADING || loading_.seen_frame) return;
    if (status_.mode == "session" && (!loading_.announced || state->header.stamp < session_stamp_)) return;
    loading_.seen_frame = true;
    loading_.first_frame_at = ros::WallTime::now();
  }

  void onSessionResult(const vrm_msgs::SessionResult::ConstPtr& result) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!graph_ || seen_result_) return;
    if (status_.mode == "replay") {
      seen_result_ = true;
      ended_at_ = ros::WallTime::now();
      return;
    }
    // The current session's: it ran (the previous session's result is latched too), in its scene, after its start.
    if (status_.state != vrm_msgs::StationStatus::READY && status_.state != vrm_msgs::StationStatus::RUNNING) return;
    if (result->header.stamp < session_stamp_) return;
    vrm_sim::result::SessionResult session_result;
    try {
      session_result = vrm_sim::result::resultFromJson(result->json, "session_result");
    } catch (const vrm_sim::result::ResultError& error) {
      ROS_ERROR("session_station: %s; no result file", error.what());
      return;
    }
    if (session_result.scene != status_.scene) return;
    seen_result_ = true;
    ended_at_ = ros::WallTime::now();
    ROS_INFO("session_station: session over (final state %s); its recording ends in %.1f s",
             result->final_state_hash.c_str(), end_tail_);
    writeResultFile(std::move(session_result));
  }

  // The result as scenario_manager reported it, with this session's bag and trainee (the graph was started without
  // them: it serves every session). Written by the simulator's one writer (temporary file + rename: a reader, the
  // console's import, never sees half a file).
  void writeResultFile(vrm_sim::result::SessionResult session_result) {
    session_result.bag = status_.bag.empty() ? std::nullopt : std::optional<std::string>(status_.bag);
    session_result.user = status_.user.empty() ? std::nullopt : std::optional<std::string>(status_.user);
    try {
      vrm_sim::result::writeResultFile(status_.result_file, session_result);
      ROS_INFO("session_station: result written to %s", status_.result_file.c_str());
    } catch (const vrm_sim::result::ResultError& error) {
      ROS_ERROR("session_station: %s", error.what());
    }
    saveState();
  }

  void onTimer(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (ghost_ && ghost_->poll()) ghost_.reset();
    closing_recorders_.erase(std::remove_if(closing_recorders_.begin(), closing_recorders_.end(),
                                            [](const auto& recorder) { return recorder->finishStopping(15.0); }),
                             closing_recorders_.end());
    if (recorder_) {
      if (const auto exit_status = recorder_->poll()) {
        recorder_.reset();
        if (!seen_result_ && status_.mode == "session" && status_.state != vrm_msgs::StationStatus::IDLE &&
            status_.state != vrm_msgs::StationStatus::ENDED) {
          status_.state = vrm_msgs::StationStatus::FAILED;
          status_.recording = false;
          publishStatus("the session's recorder ended (exit " + std::to_string(*exit_status) +
                        "): " + lastLines(session_stem_ + ".recorder.log", 3));
        }
      }
    }
    if (recovery_) stepRecovery();
    if (!graph_) return;
    if (const auto exit_status = graph_->poll()) {
      graph_.reset();
      closeRecorder();
      if (seen_result_ || (status_.mode == "replay" && *exit_status == 0)) {
        status_.state = vrm_msgs::StationStatus::ENDED;
        publishStatus(status_.mode == "replay" ? "replay finished" : "session over");
      } else {
        status_.state = vrm_msgs::StationStatus::FAILED;
        publishStatus("the session graph ended (" +
                      (*exit_status == ChildProcess::kUnknownExit ? std::string("taken over after a station restart")
                                                                  : "exit " + std::to_string(*exit_status)) +
                      "): " + lastLines(graph_log_, 3));
      }
      return;
    }
    if (seen_result_) {
      if (status_.state != vrm_msgs::StationStatus::ENDED && (ros::WallTime::now() - ended_at_).toSec() >= end_tail_) {
        if (status_.mode == "replay") {
          stopGraph();
        } else {
          closeRecorder();
        }
        status_.state = vrm_msgs::StationStatus::ENDED;
        publishStatus("session over");
      }
      return;
    }
    if (status_.state != vrm_msgs::StationStatus::LOADING) return;
    const bool replay = status_.mode == "replay";
    if (!replay && !loading_.launched && !loading_.load_sent) sendLoad();
    const bool scene_up = loading_.announced && loading_.seen_info && loading_.seen_frame;
    // The recorder starts once the new scene's session_info is out: the bag begins with it (latched).
    if (!replay && scene_up && status_.recording && !recorder_) startRecorder();
    const bool recorder_ready = !status_.recording || (recorder_ && recorderListens());
    const float progress = 0.05f + 0.3f * loading_.announced + 0.2f * loading_.seen_info + 0.2f * loading_.seen_frame +
                           0.2f * (scene_up && recorder_ready);
    const bool ready = replay ? loading_.seen_frame : scene_up && recorder_ready;
    const double waited = (ros::WallTime::now() - loading_.requested_at).toSec();
    if (ready) {
      status_.state = replay ? vrm_msgs::StationStatus::RUNNING : vrm_msgs::StationStatus::READY;
      status_.progress = 1.0f;
      if (!replay) {
        ROS_INFO(
            "session_station: '%s' ready %.2f s after the request (%s: scene announced after %.2f s, its first frame "
            "after %.2f s)",
            status_.scene.c_str(), waited, loading_.launched ? "graph launched" : "LOAD into the running graph",
            (loading_.announced_at - loading_.requested_at).toSec(),
            (loading_.first_frame_at - loading_.requested_at).toSec());
      }
      publishStatus(replay ? "replay playing" : "ready: " + status_.scene);
    } else if (waited > load_timeout_) {
      // A graph that neither runs the scene nor refuses it in time is not trusted with the next session either.
      const std::string log = lastLines(graph_log_, 3);
      stopGraph();
      status_.state = vrm_msgs::StationStatus::FAILED;
      publishStatus(std::string(loading_.launched ? "the session graph" : "the LOAD of " + status_.scene) +
                    " did not get ready within " + std::to_string(int(load_timeout_)) + " s: " + log);
    } else if ((ros::WallTime::now() - last_progress_).toSec() >= 0.5) {
      last_progress_ = ros::WallTime::now();
      status_.progress = progress;
      publishStatus(std::string(loading_.launched || replay ? "loading " : "switching to ") + status_.scene +
                    (scene_up && !recorder_ready ? ": waiting for the recorder" : ""));
    }
  }

  // The LOAD of the requested scene, once every subscriber of scenario_command the master knows of (the scene owner
  // among them) is connected to the station, so it cannot be lost; stamped ahead of the newest simulated frame like
  // the console's commands, so it applies to the next frame.
  void sendLoad() {
    XmlRpc::XmlRpcValue request, response, payload;
    request[0] = ros::this_node::getName();
    if (!ros::master::execute("getSystemState", request, response, payload, false)) return;
    int known = 0;
    const XmlRpc::XmlRpcValue& subscriptions = payload[1];
    for (int i = 0; i < subscriptions.size(); ++i)
      if (static_cast<std::string>(subscriptions[i][0]) == command_publisher_.getTopic())
        known = subscriptions[i][1].size();
    if (known == 0 || static_cast<int>(command_publisher_.getNumSubscribers()) < known) return;
    // The previous session's recorder must be gone from the inputs first (its bag then closes without the LOAD).
    if (!closing_recorders_.empty()) {
      for (int i = 0; i < subscriptions.size(); ++i) {
        const std::string topic = static_cast<std::string>(subscriptions[i][0]);
        if (topic != "/scenario_command" && topic != "/input_frame") continue;
        for (int j = 0; j < subscriptions[i][1].size(); ++j)
          if (static_cast<std::string>(subscriptions[i][1][j]).rfind(kRecorderNodePrefix, 0) == 0) return;
      }
    }
    auto command = boost::make_shared<vrm_msgs::ScenarioCommand>();
    command->header.stamp = (newest_frame_.isZero() ? ros::Time::now() : newest_frame_) + ros::Duration(0.2);
    command->command = vrm_msgs::ScenarioCommand::LOAD;
    command->scenario = status_.scene;
    command->argument = status_.difficulty;
    command->seed = status_.seed;
    loading_.load_sent = true;
    loading_.load_stamp = command->header.stamp;
    loading_.loads_before = loads_announced_;
    command_publisher_.publish(command);
    ROS_INFO("session_station: LOAD '%s'%s seed %u at input time %.3f", status_.scene.c_str(),
             status_.difficulty.empty() ? "" : (" (" + status_.difficulty + ")").c_str(), status_.seed,
             command->header.stamp.toSec());
  }

  void startRecorder() {
    const std::string log = session_stem_ + ".recorder.log";
    // A name of its own per session (station pid + count): scenario_manager resends the frames a recorder missed to
    // one that comes back under a name that left — a respawn — and must not take this one for the last session's.
    recorder_node_ =
        std::string(kRecorderNodePrefix) + "_" + std::to_string(getpid()) + "_" + std::to_string(++recorders_started_);
    std::vector<std::string> argv = {"roslaunch",           "--skip-log-check", recorder_launch_,
                                     "bag:=" + status_.bag, "start:=false",     "name:=" + recorder_node_.substr(1)};
    try {
      recorder_ = std::make_unique<ChildProcess>(argv, log);
      ROS_INFO("session_station: recording %s (log %s)", status_.bag.c_str(), log.c_str());
    } catch (const std::exception& error) {
      status_.state = vrm_msgs::StationStatus::FAILED;
      publishStatus(std::string("cannot start the recorder: ") + error.what());
    }
  }

  // This session's recorder (a process of its launch, not a stale registration of the previous one) subscribes to
  // every recorded input (else START could go unrecorded).
  bool recorderListens() const {
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
        if (static_cast<std::string>(subscriptions[i][1][j]) == recorder_node_) ++topics;
    }
    if (topics != 4) return false;
    const pid_t recorder = nodePid(recorder_node_);
    return recorder > 0 && descendsFrom(recorder, recorder_->pid());
  }

  // SIGINT: rosbag closes the bag and session_control writes its parts report while the station goes on (the timer
  // reaps it).
  void closeRecorder() {
    if (!recorder_) return;
    recorder_->interrupt();
    closing_recorders_.push_back(std::move(recorder_));
  }

  void stopGraph() {
    ghost_.reset();
    closeRecorder();
    if (!graph_) return;
    graph_->stop(15.0);
    graph_.reset();
  }

  void publishStatus(const std::string& message) {
    status_.message = message;
    status_.header.stamp = ros::Time::now();  // the station's own wall clock: not part of any session's inputs
    auto out = boost::make_shared<vrm_msgs::StationStatus>(status_);
    status_publisher_.publish(out);
    saveState();
  }

  // --- Taking over after a crash (issue 39 §2). The graph and the recorder run in process groups of their own and
  // outlive a station that crashes. The state file names them (leader pid + start time, so a reused pid is not
  // taken for them) and the session they serve; it is written on every status change (temporary file + rename) and
  // removed when no graph runs. A station started again (simulator.launch respawns it) reads it in takeOver().
  std::string statePath() const { return records_dir_ + "/station_state.json"; }

  void saveState() {
    if (!graph_) {
      // A recovery in progress keeps the file of the session it recovers: a crash meanwhile starts it again.
      if (!recovery_) std::remove(statePath().c_str());
      return;
    }
    const auto launch = [](const std::unique_ptr<ChildProcess>& process) {
      return process ? nlohmann::json{{"pid", process->pid()}, {"start", process->startTime()}} : nlohmann::json();
    };
    nlohmann::json graph = launch(graph_);
    graph["mode"] = graph_mode_;
    graph["script"] = graph_script_;
    graph["log"] = graph_log_;
    nlohmann::json recorder = launch(recorder_);
    if (recorder_) recorder["node"] = recorder_node_;
    const nlohmann::json state = {{"graph", graph},
                                  {"recorder", recorder},
                                  {"session",
                                   {{"state", status_.state},
                                    {"mode", status_.mode},
                                    {"user", status_.user},
                                    {"scene", status_.scene},
                                    {"difficulty", status_.difficulty},
                                    {"seed", status_.seed},
                                    {"bag", status_.bag},
                                    {"recording", static_cast<bool>(status_.recording)},
                                    {"result_file", status_.result_file},
                                    {"stem", session_stem_},
                                    {"stamp", {session_stamp_.sec, session_stamp_.nsec}},
                                    {"launched", {launched_stamp_.sec, launched_stamp_.nsec}},
                                    {"seen_result", seen_result_}}}};
    const std::string path = statePath(), temporary = path + ".tmp";
    {
      std::ofstream file(temporary, std::ios::trunc);
      file << state.dump(1) << "\n";
      if (!file.flush()) {
        ROS_WARN_THROTTLE(60, "session_station: cannot write %s: a station restart could not take over", path.c_str());
        return;
      }
    }
    if (std::rename(temporary.c_str(), path.c_str()) != 0)
      ROS_WARN_THROTTLE(60, "session_station: cannot write %s: %s", path.c_str(), std::strerror(errno));
  }

  // The launch a state file names, if it still runs: the same process (pid and start time), a roslaunch of
  // `launch_file`, leader of its process group. Anything else is left alone (adopting would let us stop it).
  static std::unique_ptr<ChildProcess> adoptLaunch(const nlohmann::json& entry, const std::string& launch_file) {
    if (!entry.is_object() || launch_file.empty()) return nullptr;
    const pid_t pid = entry.at("pid").get<pid_t>();
    const std::string command = processCommandLine(pid);
    if (command.find("roslaunch") == std::string::npos || command.find(launch_file) == std::string::npos)
      return nullptr;
    return ChildProcess::adopt(pid, entry.at("start").get<std::uint64_t>());
  }

  // What a crashed station left (its state file): a graph that still runs is taken over with its session — its
  // scene, frames and result count as if the station had never stopped, and a session that ended meanwhile has its
  // latched session_result, so its file is written now. A graph that ended meanwhile leaves the session's bag: the
  // result is replayed from it in the background (stepRecovery). Returns what happened ("" without a state file).
  std::string takeOver() {
    std::ifstream file(statePath());
    if (!file) return "";
    nlohmann::json state;
    std::unique_ptr<ChildProcess> graph, recorder;
    try {
      file >> state;
      const nlohmann::json& session = state.at("session");
      const nlohmann::json& graph_entry = state.at("graph");
      graph_mode_ = graph_entry.at("mode").get<std::string>();
      graph = adoptLaunch(graph_entry, graph_mode_ == "replay" ? replay_launch_ : simulator_launch_);
      recorder = adoptLaunch(state.at("recorder"), recorder_launch_);
      if (recorder) recorder_node_ = state.at("recorder").value("node", std::string(kRecorderNodePrefix));
      graph_script_ = graph_entry.at("script").get<std::string>();
      graph_log_ = graph_entry.at("log").get<std::string>();
      status_.state = session.at("state").get<std::uint8_t>();
      status_.mode = session.at("mode").get<std::string>();
      status_.user = session.at("user").get<std::string>();
      status_.scene = session.at("scene").get<std::string>();
      status_.difficulty = session.at("difficulty").get<std::string>();
      status_.seed = session.at("seed").get<std::uint32_t>();
      status_.bag = session.at("bag").get<std::string>();
      status_.recording = session.at("recording").get<bool>();
      status_.result_file = session.at("result_file").get<std::string>();
      session_stem_ = session.at("stem").get<std::string>();
      session_stamp_ =
          ros::Time(session.at("stamp").at(0).get<std::uint32_t>(), session.at("stamp").at(1).get<std::uint32_t>());
      launched_stamp_ = ros::Time(session.at("launched").at(0).get<std::uint32_t>(),
                                  session.at("launched").at(1).get<std::uint32_t>());
      seen_result_ = session.at("seen_result").get<bool>();
    } catch (const std::exception& error) {
      status_ = vrm_msgs::StationStatus();
      status_.station = hostName();
      std::remove(statePath().c_str());
      return "station restarted; its state file " + statePath() + " could not be read (" + error.what() +
             "): nothing taken over";
    }
    status_.station = hostName();
    const std::string session = "'" + status_.scene + "' of " + status_.user;
    const bool live = status_.mode == "session" && (status_.state == vrm_msgs::StationStatus::READY ||
                                                    status_.state == vrm_msgs::StationStatus::RUNNING);
    graph_ = std::move(graph);
    recorder_ = std::move(recorder);
    if (graph_) {
      if (status_.state == vrm_msgs::StationStatus::LOADING) {
        // Which of the load's conditions were met is gone with the station: the trainee loads again (a LOAD into
        // the running graph, a second or so).
        closeRecorder();
        status_.state = vrm_msgs::StationStatus::IDLE;
        status_.recording = false;
        return "station restarted while loading " + session + ": load it again (the session graph runs on)";
      }
      loading_.announced = true;                           // its scene runs: its status, frames and result count
      if (seen_result_) ended_at_ = ros::WallTime::now();  // its recording ends after the tail, as it would have
      return "station restarted: took over the session " + session + (seen_result_ ? " (ended)" : " (runs on)");
    }
    closeRecorder();  // an orphaned recorder of a graph that ended: its bag closes
    if (!live || seen_result_ || ::access(status_.result_file.c_str(), F_OK) == 0) {
      status_.state = vrm_msgs::StationStatus::IDLE;
      status_.recording = false;
      return "station restarted; the session graph had ended, and no session result was outstanding";
    }
    if (status_.bag.empty()) {
      status_.state = vrm_msgs::StationStatus::FAILED;
      status_.recording = false;
      return "station restarted: the session " + session +
             " was not recorded and its graph ended while no station ran: its result is lost";
    }
    recovery_ = Recovery{nullptr, session_stem_ + ".recovery.log", status_.result_file, status_.bag, status_.user};
    status_.state = vrm_msgs::StationStatus::IDLE;
    status_.recording = false;
    return "station restarted: the session graph of " + session +
           " ended while no station ran; replaying its bag for its result";
  }

  // (timer) The recovery's replay: started once the orphaned recorder has closed the bag; its result written when it
  // ends. A session that had not ended at the bag's end is kept as interrupted (vrm_sim::result::interrupted).
  void stepRecovery() {
    Recovery& recovery = *recovery_;
    if (!recovery.replay) {
      if (!closing_recorders_.empty()) return;
      try {
        recovery.replay = std::make_unique<ChildProcess>(
            std::vector<std::string>{"rosrun", "vrm_sim", "session_replay", "--bag", recovery.bag}, recovery.output);
      } catch (const std::exception& error) {
        finishRecovery(std::string("cannot start session_replay: ") + error.what());
      }
      return;
    }
    const auto exit_status = recovery.replay->poll();
    if (!exit_status) return;
    if (*exit_status != 0) {
      return finishRecovery("session_replay of " + recovery.bag + " failed (exit " + std::to_string(*exit_status) +
                            "): " + lastLines(recovery.output, 2));
    }
    try {
      // Its one JSON line (stdout) among the recovery notes (stderr) in the same log.
      std::ifstream log(recovery.output);
      nlohmann::json replayed;
      for (std::string line; std::getline(log, line);)
        if (!line.empty() && line.front() == '{') replayed = nlohmann::json::parse(line);
      if (!replayed.is_object() || !replayed.contains("result") || !replayed["result"].is_object())
        return finishRecovery("session_replay of " + recovery.bag + " printed no result");
      vrm_sim::result::SessionResult result =
          vrm_sim::result::resultFromJson(replayed["result"].dump(), "session_replay of " + recovery.bag);
      const bool ended = result.state && (*result.state == "finished" || *result.state == "failed");
      if (!ended) result = vrm_sim::result::interrupted(std::move(result));
      result.bag = recovery.bag;
      result.user = recovery.user.empty() ? std::nullopt : std::optional<std::string>(recovery.user);
      vrm_sim::result::writeResultFile(recovery.result_file, result);
      finishRecovery("", std::string(ended ? "result" : "interrupted result") + " replayed from " + recovery.bag +
                             " into " + recovery.result_file);
    } catch (const std::exception& error) {
      finishRecovery(std::string("the replayed result could not be written: ") + error.what());
    }
  }

  void finishRecovery(const std::string& error, const std::string& done = "") {
    const bool current = status_.result_file == recovery_->result_file && !graph_;
    recovery_.reset();
    if (!error.empty()) ROS_ERROR("session_station: recovery: %s", error.c_str());
    if (!done.empty()) ROS_INFO("session_station: %s", done.c_str());
    if (current) {
      status_.state = error.empty() ? vrm_msgs::StationStatus::ENDED : vrm_msgs::StationStatus::FAILED;
      publishStatus(error.empty() ? "session over: " + done : "no result: " + error);
    } else {
      saveState();
    }
  }

  ros::NodeHandle nh_, private_nh_;
  std::mutex mutex_;
  std::string simulator_launch_, replay_launch_, recorder_launch_, records_dir_, launch_args_, script_, scene_owner_;
  double load_timeout_ = 90.0, end_tail_ = 1.0;
  vrm_msgs::StationStatus status_;
  std::unique_ptr<ChildProcess> graph_, recorder_, ghost_;
  std::string recorder_node_;  // recorder_'s node name (per session, see startRecorder)
  unsigned recorders_started_ = 0;
  std::optional<Recovery> recovery_;
  std::vector<std::unique_ptr<ChildProcess>> closing_recorders_;  // interrupted, closing their bags
  std::string graph_mode_, graph_script_, graph_log_, session_stem_;
  Loading loading_;
  Session previous_;
  ros::WallTime ended_at_, last_progress_;
  ros::Time launched_stamp_, session_stamp_, newest_frame_;
  std::uint32_t loads_announced_ = 0;
  bool seen_result_ = false;
  ros::Publisher status_publisher_, command_publisher_;
  std::vector<ros::ServiceServer> services_;
  ros::Subscriber scene_subscriber_, info_subscriber_, status_subscriber_, state_subscriber_, result_subscriber_;
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
