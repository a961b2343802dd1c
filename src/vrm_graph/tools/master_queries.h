#pragma once
// Questions to the ROS master shared by the session tools (session_control, nodelet_keeper).
#include <ros/master.h>
#include <ros/this_node.h>

#include <map>
#include <string>
#include <vector>

namespace vrm_graph {
namespace tools {

// A node's XML-RPC URI according to the master ("" = not registered).
inline std::string lookupNode(const std::string& node) {
  XmlRpc::XmlRpcValue request, response, payload;
  request[0] = ros::this_node::getName();
  request[1] = node;
  if (!ros::master::execute("lookupNode", request, response, payload, false)) return "";
  return payload.getType() == XmlRpc::XmlRpcValue::TypeString ? static_cast<std::string>(payload) : "";
}

}  // namespace tools
}  // namespace vrm_graph
