# Sourced by the scripts: the ROS environment of the built workspace.
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export PATH="/usr/bin:$PATH"
export ROS_HOSTNAME=${ROS_HOSTNAME:-localhost}
# shellcheck disable=SC1091
set +u
source "$ROOT/build/devel/setup.bash"
set -u
export ROS_HOSTNAME=${ROS_HOSTNAME:-localhost}
export ROS_LOG_DIR=${ROS_LOG_DIR:-$ROOT/build/ros_log}
