#pragma once
// A nodelet that cannot run (a scene that does not exist, a broken scene file) ends the whole graph instead of a
// simulator running on half a scene — and the graph must end as a failure: nodelet's manager exits 0 after
// ros::requestShutdown(), roslaunch then says "finished cleanly" and every script that wraps it would report success
// (issue 20). So the reason is left on the parameter server as <manager>/failure (the manager is this process's node)
// for supervised_manager, which exits non-zero with it, and the manager is asked to shut down.
#include <ros/ros.h>

#include <string>

namespace vrm_sim {

inline std::string graphFailureParameter() { return ros::this_node::getName() + "/failure"; }

inline void failGraph(const std::string& reason) {
  ros::param::set(graphFailureParameter(), reason);
  ros::requestShutdown();
}

}  // namespace vrm_sim
