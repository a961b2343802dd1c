// The console's link to the simulator over ROS: the station's services (scene list, load/end session, ghost),
// ScenarioCommand and microscope_setpoint out, station_status / scenario_status / session_result / the stereo view
// in. Every callback runs on a ROS spinner thread and reaches the UI as a queued Qt signal; every service call runs
// on a worker thread, so neither a slow station nor a lost network freezes the console.
#pragma once

#include <ros/ros.h>
#include <sensor_msgs/Image.h>

#include <QFutureSynchronizer>
#include <mutex>

#include "eyesi_gui/console/simulator_link.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/SessionResult.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_msgs/StationStatus.h"

namespace eyesi_gui {

class RosLink : public SimulatorLink {
  Q_OBJECT

 public:
  // station: the station node's name (its services and station_status live under it).
  RosLink(ros::NodeHandle nh, const std::string& station, QObject* parent = nullptr);
  ~RosLink() override;

  QString stationName() const override;
  void requestScenes() override;
  void loadSession(const SessionRequest& request) override;
  void endSession() override;
  void playGhost(const QString& bag, double rate) override;
  void sendCommand(Command command, const QString& argument) override;
  void setMicroscope(const MicroscopeSetting& setting) override;

 private:
  void onStationStatus(const vrm_msgs::StationStatus::ConstPtr& status);
  void onScenarioStatus(const vrm_msgs::ScenarioStatus::ConstPtr& status);
  void onSessionResult(const vrm_msgs::SessionResult::ConstPtr& result);
  void onSimulationState(const vrm_msgs::SimulationState::ConstPtr& state);
  void onImage(int eye, const sensor_msgs::Image::ConstPtr& image);
  template <typename Service>
  bool call(const std::string& name, Service& service);

  ros::NodeHandle nh_;
  std::string station_;
  ros::Subscriber station_subscriber_, status_subscriber_, result_subscriber_, state_subscriber_, left_subscriber_,
      right_subscriber_;
  ros::Publisher command_publisher_, microscope_publisher_;
  std::mutex mutex_;
  ros::Time newest_input_;  // the graph's input clock (simulation_state stamps): commands are stamped on it
  QImage latest_[2];
  ros::Time latest_stamp_[2];
  ros::Time last_result_stamp_;
  QFutureSynchronizer<void> calls_;
};

}  // namespace eyesi_gui
