#!/usr/bin/env bash
# Set-up + build, then the headless simulator with simulated hardware (scripted surgeon seen through the camera rig
# twin and the optical tracking, pedals, knobs; tissue simulation; renderer) for a bounded time, recording the
# session's inputs to a bag and saving three stereo frames, then a summary of what was recorded.
# Usage: scripts/run.sh [--duration SECONDS] [--scene NAME] [--bag PATH] [roslaunch args...]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
duration=20
scene=membrane_peeling
bag=""
extra=()
while (($#)); do
  case $1 in
    --duration) duration=$2; shift 2 ;;
    --scene) scene=$2; shift 2 ;;
    --bag) bag=$2; shift 2 ;;
    -h | --help) sed -n '2,4p' "$0"; exit 0 ;;
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
  "duration:=$duration" "bag:=$bag" "scene:=$scene" "snapshot_dir:=$out" snapshot_count:=3 "${extra[@]}" \
  >"$out/launch.log" 2>&1 || true
log="$out/launch.log"
grep -hE "scene '|FATAL|ERROR" "$log" | sed -E 's/\x1b\[[0-9;]*m//g' | head -n 10 || true
echo "launch log: $log"
/usr/bin/python3 "$ROOT/scripts/bag_summary.py" "$bag"
echo "stereo frames: $(find "$out" -name '*.png' | wc -l) PNGs in $out"
