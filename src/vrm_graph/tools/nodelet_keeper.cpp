// nodelet_keeper: `nodelet load` that survives a crash of its manager (issue 14). The stock loader loads a nodelet
// once; with --no-bond it never notices that the manager died and came back empty, and with a bond it exits and
// needs a respawn (and bonds break spuriously on a loaded two-core machine and abort at teardown under rostest
// with boost::lock_error). This loader asks the master for the manager's URI twice a second and loads the nodelet
// again into every new manager process (a new URI), with the same name, type, remappings and arguments, and unloads it
// when the launch stops it. Drop-in for the stock loader:
//   <node pkg="vrm_graph" type="nodelet_keeper" name="scene_manager" args="load vrm_sim/scene_manager MANAGER"/>
// A nodelet loaded again gets the extra argument --reloaded (getMyArgv()): a simulation node resumes its session
// from its journal then, and a device twin holds its script until it hears where the session was (issue 39).
// Parameters: none (the nodelet's own parameters live under its name, which it keeps across reloads).
#include <nodelet/NodeletList.h>
#include <nodelet/NodeletLoad.h>
#include <nodelet/NodeletUnload.h>
#include <ros/master.h>
#include <ros/ros.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <string>
#include <vector>

#include "master_queries.h"

namespace {

using vrm_graph::tools::lookupNode;

class Keeper {
 public:
  Keeper(std::string type, std::string manager, std::vector<std::string> argv)
      : type_(std::move(type)), manager_(ros::names::resolve(std::move(manager))), argv_(std::move(argv)) {
    timer_ = nh_.createWallTimer(ros::WallDuration(0.5), &Keeper::check, this);
  }

  // Called once ROS shuts down (SIGINT from roslaunch): the nodelet leaves the manager with its loader.
  void unload() {
    if (loaded_uri_.empty() || lookupNode(manager_) != loaded_uri_) return;
    nodelet::NodeletUnload unload;
    unload.request.name = ros::this_node::getName();
    ros::service::call(manager_ + "/unload_nodelet", unload);
  }

 private:
  void check(const ros::WallTimerEvent&) {
    const std::string uri = lookupNode(manager_);
    if (uri.empty() || uri == loaded_uri_) return;
    if (!loaded_uri_.empty()) {
      ROS_WARN("nodelet_keeper: manager %s restarted (%s); loading %s again", manager_.c_str(), uri.c_str(),
               ros::this_node::getName().c_str());
    }
    if (!ros::service::exists(manager_ + "/load_nodelet", false)) return;  // the new manager is still starting
    if (alreadyLoaded()) {
      loaded_uri_ = uri;
      return;
    }
    nodelet::NodeletLoad load;
    load.request.name = ros::this_node::getName();
    load.request.type = type_;
    for (const auto& [from, to] : ros::names::getRemappings()) {
      load.request.remap_source_args.push_back(from);
      load.request.remap_target_args.push_back(to);
    }
    load.request.my_argv = argv_;
    // Loaded again after a crash of the manager: the nodelet may resume what the crashed one did (issue 39).
    if (!loaded_uri_.empty()) load.request.my_argv.push_back("--reloaded");
    if (ros::service::call(manager_ + "/load_nodelet", load) && load.response.success) {
      loaded_uri_ = uri;
      ++loads_;
      ROS_INFO("nodelet_keeper: %s (%s) loaded into %s%s", load.request.name.c_str(), type_.c_str(), manager_.c_str(),
               loads_ > 1 ? " again" : "");
    } else if (++failures_ % 10 == 1) {
      // A nodelet whose onInit fails (a broken scene) is not retried in a tight loop.
      ROS_ERROR("nodelet_keeper: loading %s (%s) into %s failed; retrying", load.request.name.c_str(), type_.c_str(),
                manager_.c_str());
    }
  }

  // A manager that still holds the nodelet (this loader restarted, not the manager) needs no second load.
  bool alreadyLoaded() {
    nodelet::NodeletList list;
    if (!ros::service::call(manager_ + "/list", list)) return false;
    return std::find(list.response.nodelets.begin(), list.response.nodelets.end(), ros::this_node::getName()) !=
           list.response.nodelets.end();
  }

  ros::NodeHandle nh_;
  std::string type_, manager_;
  std::vector<std::string> argv_;
  ros::WallTimer timer_;
  std::string loaded_uri_;
  unsigned loads_ = 0, failures_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "nodelet_keeper", ros::init_options::NoSigintHandler);
  std::vector<std::string> args;
  ros::removeROSArgs(argc, argv, args);
  // args: program, "load", TYPE, MANAGER, [nodelet arguments...]; the stock loader's --no-bond is accepted.
  args.erase(std::remove(args.begin(), args.end(), std::string("--no-bond")), args.end());
  if (args.size() < 4 || args[1] != "load") {
    std::fprintf(stderr, "usage: nodelet_keeper load pkg/Type MANAGER [args...]\n");
    return 2;
  }
  Keeper keeper(args[2], args[3], std::vector<std::string>(args.begin() + 4, args.end()));
  // Unload before the node leaves the graph, so the manager does not keep an orphan.
  static volatile sig_atomic_t stop = 0;
  std::signal(SIGINT, [](int) { stop = 1; });
  std::signal(SIGTERM, [](int) { stop = 1; });
  ros::AsyncSpinner spinner(1);
  spinner.start();
  while (!stop && ros::ok()) ros::WallDuration(0.05).sleep();
  spinner.stop();
  keeper.unload();
  ros::shutdown();
  return 0;
}
