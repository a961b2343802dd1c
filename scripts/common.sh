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

# roslaunch exits 0 when a required node dies: it only shuts the graph down. required_failures LOG prints each required
# process that died with a non-zero exit code (a negative one: a signal) in a roslaunch log and returns 1 if there was
# one, so a script that wraps roslaunch can fail as it should (issue 20). A required node that finished cleanly (e.g.
# session_control after `duration`) is no failure.
required_failures() {
  sed -E 's/\x1b\[[0-9;]*m//g' "$1" | awk '
    /REQUIRED process \[/ { name = $0; sub(/.*REQUIRED process \[/, "", name); sub(/\].*/, "", name); want = 1; next }
    want && /process has died/ {
      if (match($0, /exit code -?[0-9]+/)) {
        code = substr($0, RSTART + 10, RLENGTH - 10)
        if (code != 0) { print "required node " name " failed (exit code " code ")"; bad = 1 }
      }
      want = 0; next
    }
    want && /finished cleanly/ { want = 0 }
    END { exit bad }'
}
