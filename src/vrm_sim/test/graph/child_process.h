#pragma once
// A launch file or tool run as a child process by the graph tests, as a user would run it: started, waited for
// (never a fixed sleep), interrupted like Ctrl-C when it overstays.
#include <ros/ros.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <string>
#include <vector>

extern char** environ;

namespace vrm_sim {

class ChildProcess {
 public:
  explicit ChildProcess(const std::vector<std::string>& arguments) {
    std::vector<char*> argv;
    for (const auto& argument : arguments) argv.push_back(const_cast<char*>(argument.c_str()));
    argv.push_back(nullptr);
    if (posix_spawnp(&pid_, argv[0], nullptr, nullptr, argv.data(), environ) != 0) pid_ = -1;
  }
  ~ChildProcess() {
    if (running()) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }

  bool started() const { return pid_ > 0; }
  bool running() {
    if (pid_ <= 0 || exited_) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      exited_ = true;
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }
    return !exited_;
  }
  // Waits for the exit; on timeout interrupts (SIGINT, as Ctrl-C would), then kills. Returns the exit code or -1.
  int waitFor(double seconds) {
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(seconds);
    while (running() && ros::WallTime::now() < deadline) ros::WallDuration(0.05).sleep();
    if (!running()) return exit_code_;
    interrupt();
    const ros::WallTime grace = ros::WallTime::now() + ros::WallDuration(10.0);
    while (running() && ros::WallTime::now() < grace) ros::WallDuration(0.05).sleep();
    return -1;
  }
  void interrupt() {
    if (running()) kill(pid_, SIGINT);
  }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  int exit_code_ = -1;
};

}  // namespace vrm_sim
