#!/usr/bin/env bash
# Set-up + build, then the headless simulator with simulated hardware running a training scenario end to end: the
# scripted expert surgeon (the scene's scenario.scripts.expert) seen through the camera rig twin and the optical
# tracking, pedals, knobs; the scenario manager (simulation core: collision, tissue, bleeding, scenario and score);
# the renderer. It runs for a bounded time, records the session's inputs to a bag, saves three stereo frames and
# writes the session's result JSON, then prints a summary of what was recorded and of what the simulation did
# (outputs.bag: frame cost; the view's fps and end-to-end latency from the display twin, with a warning when the
# machine is too slow for real time) and the score table, and replays the bag offline (session_replay) to show the replay ends in the
# live session's final state, bit for bit.
# With --check the exit status says whether the session did its job: simulation frames were produced, in a scene
# with tissue the tissue was published deformed and grasped, the scenario finished, and the replay of the bag ended
# in the live final state hash (CI runs the short form).
# Usage: scripts/run.sh [--duration SECONDS] [--scenario NAME] [--difficulty LEVEL] [--script expert|novice]
#                       [--bag PATH] [--check] [--no-build] [roslaunch args...]
# (--scene is a synonym of --scenario; scenario_offline --list names the scenarios. --no-build skips the set-up and
# build, for a second run on a built tree or a build someone else is running.)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
duration=20
scene=membrane_peeling
difficulty=""
script=expert
bag=""
check=()
build=true
extra=()
while (($#)); do
  case $1 in
    --duration) duration=$2; shift 2 ;;
    --scene | --scenario) scene=$2; shift 2 ;;
    --difficulty) difficulty=$2; shift 2 ;;
    --script) script=$2; shift 2 ;;
    --bag) bag=$2; shift 2 ;;
    --check) check=(--check); shift ;;
    --no-build) build=false; shift ;;
    -h | --help) sed -n '2,16p' "$0"; exit 0 ;;
    *) extra+=("$1"); shift ;;
  esac
done
[[ $duration =~ ^[0-9]+([.][0-9]+)?$ ]] && [[ $duration != 0 ]] || { echo "run.sh: --duration must be a positive number" >&2; exit 2; }

if $build; then
  "$ROOT/scripts/setup.sh"
elif [[ ! -f $ROOT/build/devel/setup.bash ]]; then
  echo "run.sh: --no-build, but there is no build in $ROOT/build (run without --no-build once)" >&2
  exit 2
fi
source "$ROOT/scripts/common.sh"

out="$ROOT/build/sessions/$(date +%Y%m%d_%H%M%S)"
# Stereo frames while the expert works: approach, grasp, peel (seconds after the first input).
SNAPSHOT_TIMES=${SNAPSHOT_TIMES:-"2.5 4.3 5.9"}
mkdir -p "$out"
[[ -n $bag ]] || bag="$out/session.bag"
echo "run.sh: headless simulator, simulated hardware (scripted $script surgeon, pedals, knobs) seen through the camera" \
  "rig twin and the optical tracking (tracking:=true), scenario '$scene'${difficulty:+ ($difficulty)}, ${duration} s," \
  "recording to $bag"
# The recorder is a required node with --duration, so roslaunch ends by itself; timeout is only a safety net.
launch_status=0
timeout --signal=INT --kill-after=15 "$(awk "BEGIN{print int($duration) + 60}")" \
  roslaunch --screen "$ROOT/launch/simulator.launch" sim:=true headless:=true record:=true tracking:=true \
  "duration:=$duration" "bag:=$bag" "outputs_bag:=$out/outputs.bag" "scene:=$scene" "snapshot_dir:=$out" \
  "difficulty:=$difficulty" "script:=scenario:$script" "result_file:=$out/result.json" \
  snapshot_times:="$SNAPSHOT_TIMES" "${extra[@]}" \
  >"$out/launch.log" 2>&1 || launch_status=$?
log="$out/launch.log"
grep -ahE "scene '|FATAL|ERROR|the graph failed" "$log" | sed -E 's/\x1b\[[0-9;]*m//g' | head -n 10 || true
echo "launch log: $log"
# roslaunch exits 0 when a required part of the graph failed (e.g. a scene that does not exist): say so and stop.
if ! failed=$(required_failures "$log"); then
  echo "run.sh: the simulator graph failed: $failed" >&2
  exit 1
fi
if ((launch_status == 124)); then
  echo "run.sh: the graph did not end by itself within $(awk "BEGIN{print int($duration) + 60}") s; stopped it" >&2
elif ((launch_status != 0)); then
  echo "run.sh: roslaunch failed (exit status $launch_status)" >&2
  exit 1
fi
status=0
/usr/bin/python3 "$ROOT/scripts/bag_summary.py" "$bag" || status=1
echo "stereo frames: $(find "$out" -name '*.png' | wc -l) PNGs in $out"
# Issue 33: the saved frames re-rendered from their saved state (<prefix>.frame): the working instrument's shadow,
# the working area in focus, the fundus lit by the light pipe's cone (rosrun vrm_render frame_check --help).
if ! rosrun vrm_render frame_check "$out"; then
  echo "run.sh: frame_check: a saved frame failed its shadow / focus / light check (or could not be checked)" >&2
  ((${#check[@]} == 0)) || status=1
fi
result_args=()
[[ -f $out/result.json ]] && result_args=(--result "$out/result.json")
/usr/bin/python3 "$ROOT/scripts/session_summary.py" "${check[@]}" "${result_args[@]}" "$out/outputs.bag" || status=1
# (A result file is summarised by session_summary.py above.)
[[ -f $out/result.json ]] || echo "result: none (the scenario did not end within ${duration} s)"
# The session is its recorded inputs (thesis §2.4.2): the offline replay must end where the live session did.
live_result=${bag%.bag}.result.json
if [[ -f $live_result ]]; then
  # The result's one Python reader (scripts/session_result.py, schema doc/session_result.md): a malformed result fails.
  live_hash=$(/usr/bin/python3 "$ROOT/scripts/session_result.py" "$live_result" final_state_hash) || status=1
  if replay=$(rosrun vrm_sim session_replay --bag "$bag"); then
    replay_hash=$(/usr/bin/python3 -c 'import json,sys; d=json.loads(sys.argv[1]); print(d["final_state_hash"], "in %.2f s (%.0fx real time)" % (d["wall_seconds"], d["speedup"]))' "$replay")
    if [[ ${replay_hash%% *} == "$live_hash" ]]; then
      echo "replay: rosrun vrm_sim session_replay --bag $bag -> final state $replay_hash = live $live_hash (bit for bit)"
    else
      echo "replay: final state ${replay_hash%% *} DIFFERS from the live session's $live_hash" >&2
      status=1
    fi
  else
    echo "replay: session_replay could not replay $bag" >&2
    status=1
  fi
else
  echo "replay: no live result next to the bag ($live_result)" >&2
  status=1
fi
exit $status
