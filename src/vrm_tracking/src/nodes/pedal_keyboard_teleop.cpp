// Keyboard stand-in for the foot pedals (thesis §2.4.1: swapping the mediator's input device). Publishes the full
// pedal state on pedals_sim/command at ~rate Hz, which pedals_sim forwards instead of its script track.
//
//   w / s   travel +/- 0.1        r   reflux on/off        c   instrument switch on/off
//   + / -   zoom in / out         [ / ]   focus near / far  (held for ~button_hold s after each key press, since a
//                                                           terminal reports key presses, not key releases)
//   space   all released, travel 0                          q   quit

#include <poll.h>
#include <ros/ros.h>
#include <termios.h>
#include <unistd.h>
#include <vrm_msgs/PedalState.h>
#include <vrm_msgs/publish.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cstdio>

namespace {

// Puts stdin into non-canonical, no-echo mode for single key presses and restores it on every exit path.
class RawTerminal {
 public:
  RawTerminal() {
    active_ = isatty(STDIN_FILENO) && tcgetattr(STDIN_FILENO, &saved_) == 0;
    if (!active_) return;
    termios raw = saved_;
    raw.c_lflag &= ~(ICANON | ECHO);
    raw.c_cc[VMIN] = 0;
    raw.c_cc[VTIME] = 0;
    tcsetattr(STDIN_FILENO, TCSANOW, &raw);
  }
  ~RawTerminal() {
    if (active_) tcsetattr(STDIN_FILENO, TCSANOW, &saved_);
  }
  RawTerminal(const RawTerminal&) = delete;
  RawTerminal& operator=(const RawTerminal&) = delete;

 private:
  termios saved_{};
  bool active_ = false;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "pedal_keyboard_teleop");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  double rate = 20.0;
  double button_hold = 0.3;
  pnh.param("rate", rate, rate);
  pnh.param("button_hold", button_hold, button_hold);
  ros::Publisher pub = nh.advertise<vrm_msgs::PedalState>("pedals_sim/command", 1);

  std::puts("pedal teleop: w/s travel, r reflux, c switch, +/- zoom, [/] focus, space release, q quit");
  RawTerminal terminal;
  vrm_msgs::PedalState state;
  ros::WallTime zoom_in_until, zoom_out_until, near_until, far_until;
  ros::WallRate loop(rate);
  while (ros::ok()) {
    pollfd in{STDIN_FILENO, POLLIN, 0};
    const ros::WallTime now = ros::WallTime::now();
    const ros::WallDuration hold(button_hold);
    char key = 0;
    while (poll(&in, 1, 0) > 0 && read(STDIN_FILENO, &key, 1) == 1) {
      switch (key) {
        case 'w':
          state.travel = std::min(1.0, state.travel + 0.1);
          break;
        case 's':
          state.travel = std::max(0.0, state.travel - 0.1);
          break;
        case 'r':
          state.reflux = !state.reflux;
          break;
        case 'c':
          state.instrument_switch = !state.instrument_switch;
          break;
        case '+':
          zoom_in_until = now + hold;
          break;
        case '-':
          zoom_out_until = now + hold;
          break;
        case '[':
          near_until = now + hold;
          break;
        case ']':
          far_until = now + hold;
          break;
        case ' ':
          state = vrm_msgs::PedalState();
          zoom_in_until = zoom_out_until = near_until = far_until = ros::WallTime();
          break;
        case 'q':
          ros::shutdown();
          break;
        default:
          break;
      }
    }
    if (!ros::ok()) break;
    state.zoom_in = now < zoom_in_until;
    state.zoom_out = now < zoom_out_until;
    state.focus_near = now < near_until;
    state.focus_far = now < far_until;

    auto msg = boost::make_shared<vrm_msgs::PedalState>(state);
    msg->header.stamp = ros::Time::now();
    vrm_msgs::publishShared(pub, msg);
    ROS_DEBUG_THROTTLE(1.0, "travel %.1f reflux %d switch %d", state.travel, state.reflux, state.instrument_switch);
    ros::spinOnce();
    loop.sleep();
  }
  return 0;
}
