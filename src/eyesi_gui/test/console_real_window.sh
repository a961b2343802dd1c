#!/usr/bin/env bash
# The console in a real window (Xvfb, the xcb platform) against the real simulator graph: roslaunch
# launch/simulator.launch headless:=false starts the station and the console; the console's autopilot logs in with
# its own buttons (an instructor created here with a PIN), loads the membrane-peeling scenario, presses START, the
# scripted expert peels the membrane, the result screen shows the score, every screen is saved as a PNG from the X
# server's framebuffer. Checks: the console exits 0 (its result reached the records store), the session row and its
# score items are in the database, the PNGs are not blank and the stereo view region of the session screen is not
# uniform, the station closed the bag, and the bag replays offline to the recorded final state.
# Usage: console_real_window.sh [OUT_DIR]   (default: a temporary folder; kept on failure)
set -uo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)
export PATH="/usr/bin:$PATH"
# shellcheck disable=SC1091
source "$ROOT/scripts/common.sh"
OUT=${1:-$(mktemp -d /tmp/eyesi_console.XXXXXX)}
mkdir -p "$OUT"
PORT=$((11800 + $$ % 80))
export ROS_MASTER_URI=http://localhost:$PORT ROS_LOG_DIR="$OUT/ros_log"
DB="$OUT/records.sqlite"
failures=0
check() {  # check NAME CONDITION-EXIT-STATUS DETAIL
  if [[ $2 -eq 0 ]]; then echo "PASS: $1"; else echo "FAIL: $1 ${3:-}"; failures=$((failures + 1)); fi
}

rosrun eyesi_gui records --db "$DB" add-user "Dr. Anna Weber" --role instructor --pin 2468 >/dev/null
timeout -k 10 300 xvfb-run -a -s "-screen 0 1280x800x24" \
  roslaunch -p "$PORT" "$ROOT/launch/simulator.launch" headless:=false database:="$DB" records_dir:="$OUT/sessions" \
  console_args:="--autopilot membrane_peeling --user 'Dr. Anna Weber' --pin 2468 --screenshots $OUT/shots --timeout 200" \
  >"$OUT/launch.log" 2>&1
grep -q "autopilot: session [1-9][0-9]* stored" "$OUT/launch.log"
check "the console ran the session by its own buttons and stored its result" $? "(see $OUT/launch.log)"
grep "console:" "$OUT/launch.log" | sed 's/^/  /'

rows=$(rosrun eyesi_gui records --db "$DB" export-csv --user "Dr. Anna Weber" --scene membrane_peeling | tail -n +2 | wc -l)
[[ $rows -ge 5 ]]
check "the session and its score items are in the database ($rows item rows)" $?

python3 - "$OUT/shots" <<'PY'
import sys, os
from PIL import Image, ImageStat
shots = sys.argv[1]
ok = True
for name in ["login", "scenarios", "session", "result", "history", "instructor"]:
    path = os.path.join(shots, name + ".png")
    if not os.path.exists(path):
        print(f"FAIL: screenshot {name}.png missing"); ok = False; continue
    image = Image.open(path).convert("RGB")
    spread = max(high - low for low, high in image.getextrema())
    print(f"{'PASS' if image.size[0] >= 1280 and spread > 50 else 'FAIL'}: {name}.png {image.size[0]}x{image.size[1]}, "
          f"value spread {spread}")
    ok &= image.size[0] >= 1280 and spread > 50
# The stereo view: the region left of the control column, below the title, above the state line.
session = Image.open(os.path.join(shots, "session.png")).convert("L").crop((20, 150, 940, 660))
stats = ImageStat.Stat(session)
colours = len(set(session.getdata()))
print(f"{'PASS' if stats.stddev[0] > 5 and colours > 32 else 'FAIL'}: stereo view region not uniform "
      f"(grey std {stats.stddev[0]:.1f}, {colours} grey levels)")
ok &= stats.stddev[0] > 5 and colours > 32
sys.exit(0 if ok else 1)
PY
check "screenshots" $?

bag=$(ls "$OUT"/sessions/*.bag 2>/dev/null | head -1)
[[ -n $bag && ! -e "$bag.active" ]]
check "the station closed the session's bag (${bag:-none})" $?
if [[ -n $bag ]]; then
  result="${bag%.bag}.result.json"
  recorded=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['final_state_hash'])" "$result")
  replayed=$(rosrun vrm_sim session_replay --bag "$bag" | python3 -c "import json,sys; print(json.loads(sys.stdin.readline())['final_state_hash'])")
  [[ -n $recorded && $recorded == "$replayed" ]]
  check "the console-recorded bag replays to the live final state ($recorded / $replayed)" $?
fi
leftovers=$(pgrep -f "__log:=$OUT/ros_log" | wc -l)
[[ $leftovers -eq 0 ]]
check "no process of the session graph is left" $? "($leftovers left)"
pkill -f "__log:=$OUT/ros_log" 2>/dev/null

if [[ $failures -eq 0 ]]; then
  echo "console_real_window: PASS ($OUT)"
  [[ $# -eq 0 ]] && rm -rf "$OUT"
  exit 0
fi
echo "console_real_window: $failures FAILED (kept $OUT)"
exit 1
