#!/usr/bin/env bash
# Set-up + build, then the headless simulator with simulated hardware (scripted surgeon seen through the camera rig
# twin and the optical tracking, pedals, knobs; tissue simulation; renderer) for a bounded time, recording the
# session's inputs to a bag and saving three stereo frames (4.5 s: forceps over the membrane, 6.5 s: grasped, 9.5 s:
# peeled), then a summary of what was recorded and of what the simulation did (outputs.bag).
# With --check the exit status says whether the session did its job: simulation frames were produced and, in a scene
# with tissue, the membrane was published deformed and grasped (CI runs the short form).
# Usage: scripts/run.sh [--duration SECONDS] [--scene NAME] [--bag PATH] [--check] [roslaunch args...]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
duration=20
scene=membrane_peeling
bag=""
check=()
extra=()
while (($#)); do
  case $1 in
    --duration) duration=$2; shift 2 ;;
    --scene) scene=$2; shift 2 ;;
    --bag) bag=$2; shift 2 ;;
    --check) check=(--check); shift ;;
    -h | --help) sed -n '2,7p' "$0"; exit 0 ;;
    *) extra+=("$1"); shift ;;
  esac
done
[[ $duration =~ ^[0-9]+([.][0-9]+)?$ ]] && [[ $duration != 0 ]] || { echo "run.sh: --duration must be a positive number" >&2; exit 2; }

"$ROOT/scripts/setup.sh"
source "$ROOT/scripts/common.sh"

out="$ROOT/build/sessions/$(date +%Y%m%d_%H%M%S)"
mkdir -p "$out"
[[ -n $bag ]] || bag="$out/session.bag"
echo "run.sh: headless simulator, simulated hardware, scene '$scene', ${duration} s, recording to $bag"
# The recorder is a required node with --duration, so roslaunch ends by itself; timeout is only a safety net.
timeout --signal=INT --kill-after=15 "$(awk "BEGIN{print int($duration) + 60}")" \
  roslaunch --screen "$ROOT/launch/simulator.launch" sim:=true headless:=true record:=true tracking:=true \
  "duration:=$duration" "bag:=$bag" "outputs_bag:=$out/outputs.bag" "scene:=$scene" "snapshot_dir:=$out" \
  snapshot_times:="4.5 6.5 9.5" "${extra[@]}" \
  >"$out/launch.log" 2>&1 || true
log="$out/launch.log"
grep -hE "scene '|FATAL|ERROR" "$log" | sed -E 's/\x1b\[[0-9;]*m//g' | head -n 10 || true
echo "launch log: $log"
status=0
/usr/bin/python3 "$ROOT/scripts/bag_summary.py" "$bag" || status=1
echo "stereo frames: $(find "$out" -name '*.png' | wc -l) PNGs in $out"
/usr/bin/python3 "$ROOT/scripts/session_summary.py" "${check[@]}" "$out/outputs.bag" || status=1
exit $status
