#!/usr/bin/env bash
# issue 20: the README's ROS client commands work on a fresh set-up, against the graph as a user starts it
# (roslaunch launch/simulator.launch tracking:=true). Every type the graph publishes loads as a Python message class
# (what rostopic echo needs), and rostopic echo of /diagnostics, the latched /scene_markers (a late subscriber),
# camera_info and the inputs, rosnode list and tf_echo world -> eye answer within their time limits.
# Prints PASS/FAIL lines; exits 1 on any failure.
set -uo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/checks.sh"
PORT=${PORT:-11744}
export ROS_MASTER_URI=http://localhost:$PORT
setsid roslaunch -p "$PORT" "$ROOT/launch/simulator.launch" tracking:=true >"$TMP/launch.log" 2>&1 &
launch_pid=$!
cleanup() {
  kill -INT -- "-$launch_pid" 2>/dev/null
  for _ in $(seq 60); do kill -0 "$launch_pid" 2>/dev/null || break; sleep 0.5; done
  kill -KILL -- "-$launch_pid" 2>/dev/null
  rm -rf "$TMP"
}
trap cleanup EXIT

# The graph is up once the scene is published and the tracker delivers poses (conditions, not sleeps).
up=0
for _ in $(seq 120); do
  if rostopic list 2>/dev/null | grep -qx /scene_markers && timeout 5 rostopic echo -n1 /eye_state/valid >/dev/null 2>&1; then
    up=1; break
  fi
  sleep 0.5
done
((up)) || { fail "the graph did not come up within 60 s"; tail -n 20 "$TMP/launch.log"; exit 1; }

# Every published type loads in Python (a missing python3-*-msgs package fails here, as rostopic echo would).
types=$(rostopic list -v 2>/dev/null | sed -n '/Published topics/,/Subscribed topics/p' | grep -oE '\[[^]]+\]' | tr -d '[]' | sort -u)
missing=$(/usr/bin/python3 -c 'import sys, roslib.message
bad = [t for t in sys.argv[1:] if roslib.message.get_message_class(t) is None]
print(" ".join(bad))' $types 2>/dev/null)
if [[ -n $types && -z $missing ]]; then
  pass "every published type loads in Python ($(wc -w <<<"$types") types: $(tr '\n' ' ' <<<"$types"))"
else
  fail "Python message classes missing: ${missing:-no types listed}"
fi

run() {  # run NAME SECONDS EXPECTED_TEXT COMMAND...
  local name=$1 limit=$2 expected=$3 start output code
  shift 3
  start=$(date +%s.%N)
  output=$(timeout "$limit" "$@" 2>&1)
  code=$?
  local took
  took=$(awk "BEGIN{printf \"%.1f\", $(date +%s.%N) - $start}")
  if [[ $output == *"$expected"* ]]; then
    pass "$name in ${took} s"
  else
    fail "$name (exit $code after ${took} s): $(head -c 300 <<<"$output")"
  fi
}
run "rostopic echo -n1 /diagnostics" 20 "status:" rostopic echo -n1 /diagnostics
# Latched: a subscriber that comes late still gets it. It is large (every triangle of the scene as YAML, ~4 MB).
run "rostopic echo -n1 /scene_markers (latched, late subscriber)" 60 "markers:" rostopic echo -n1 /scene_markers
run "rostopic echo -n1 --noarr /scene_markers" 30 "markers:" rostopic echo -n1 --noarr /scene_markers
run "rostopic echo -n1 /stereo/left/camera_info" 30 "distortion_model" rostopic echo -n1 /stereo/left/camera_info
run "rostopic echo -n1 /simulation_state" 20 "header:" rostopic echo -n1 /simulation_state
run "rostopic echo -n1 /instrument_state" 20 "tip_pose:" rostopic echo -n1 /instrument_state
run "rosnode list" 20 "/vrm_manager" rosnode list
# tf_echo prints once a second until stopped: the limit ends it.
run "rosrun tf tf_echo world eye" 12 "Translation:" rosrun tf tf_echo world eye

# simulator.launch rviz:=true: the shipped view opens under a virtual display, stays up and draws the scene.
display=":$((PORT % 50 + 60))"
Xvfb "$display" -screen 0 1280x800x24 -nolisten tcp >"$TMP/xvfb.log" 2>&1 &
xvfb_pid=$!
DISPLAY=$display rviz -d "$ROOT/src/vrm_bringup/config/simulator.rviz" >"$TMP/rviz.log" 2>&1 &
rviz_pid=$!
sleep_until_drawn=0
for _ in $(seq 60); do  # until the 3D view shows the eye (orange) or 30 s
  sleep 0.5
  if DISPLAY=$display /usr/bin/python3 -c 'import sys
from PIL import ImageGrab
image = ImageGrab.grab(xdisplay=sys.argv[1]).convert("RGB")
w, h = image.size
view = image.crop((w // 3, h // 6, w - 20, h - 60)).resize((64, 40))
orange = sum(1 for r, g, b in view.getdata() if r > 120 and r > g + 40 and r > b + 60)
sys.exit(0 if orange > 40 else 1)' "$display" 2>/dev/null; then
    sleep_until_drawn=1; break
  fi
done
if ((sleep_until_drawn)) && kill -0 "$rviz_pid" 2>/dev/null; then
  pass "rviz -d vrm_bringup/config/simulator.rviz is up and draws the eye"
else
  fail "RViz with the shipped view: $(grep -v media_export "$TMP/rviz.log" | grep -iE 'error|fatal' | head -n 3)"
fi
kill "$rviz_pid" 2>/dev/null; wait "$rviz_pid" 2>/dev/null
kill "$xvfb_pid" 2>/dev/null; wait "$xvfb_pid" 2>/dev/null

((failures == 0)) || exit 1
