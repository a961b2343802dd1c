#!/usr/bin/env bash
# Soak test (issue 14 §4): the whole product graph for N minutes — launch/simulator.launch headless with the
# simulated hardware, the optical tracking (tracking:=true), the membrane_peeling scene (tissue, collision, bleeding),
# the stereo renderer watched by a viewer in its own process, the session's inputs recorded into a bag — while the
# scenario is cycled STOP/LOAD/START every minute as the console does it. scripts/soak_monitor.py samples once a
# second and writes one row per minute: RSS and CPU of the nodelet manager and of the whole graph, message rates
# (/eye_state, /instrument_state, /simulation_state, both eyes' images, /tissue/*), the renderer's dropped frames,
# per-stage and end-to-end latency p99 (/diagnostics), crashes (a process of the graph that died or came back with
# another pid). Verdict (JSON and exit status): manager RSS growth <= 5 % from minute 5 to the end, no rate below
# 90 % of minute 5's, zero crashes, every scenario cycle acknowledged. Fewer than 6 minutes = smoke mode: minute 1 is
# the baseline, and the results go to soak.quick.json / soak.quick.png instead of soak.json / soak.png.
# Runs on its own ROS master port (default 11751), so it never meets another graph.
# Usage: scripts/soak.sh [--minutes N] [--port PORT] [--out DIR] [--results DIR] [roslaunch args...]
#   --out      the run's folder: bag, launch log, ROS logs (default build/soak/<UTC time>)
#   --results  where soak.json and soak.png go (default bench/results)
#   --no-cycle a control run: the scenario is never cycled
#   --minute-seconds S   rows (and cycles) every S s instead of 60 (development: many cycles in a short run)
#   --tree     another checkout's launch files and packages (ROS_PACKAGE_PATH=TREE/src) with this build, e.g. a
#              `git worktree` of the last commit while the working tree's launch files wait for a rebuild
#   --sanitize the graph of the ASan + UBSan build (build_asan/, as scripts/test.sh --sanitize builds it; VRM_ASAN_BUILD
#              names another): a memory error is reported where it happens, not minutes later as a corrupted heap.
#              Reports go to <out>/sanitizer_reports; any report fails the soak. Rates and latencies then measure the
#              sanitizer, so such a run's JSON goes to soak.sanitize[.quick].json, never over the plain one.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
minutes=30
port=11751
out=""
results="$ROOT/bench/results"
extra=()
monitor_args=()
tree=$ROOT
sanitize=0
while (($#)); do
  case $1 in
    --minutes) minutes=$2; shift 2 ;;
    --port) port=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --results) results=$2; shift 2 ;;
    --tree) tree=$(cd "$2" && pwd); shift 2 ;;
    --no-cycle) monitor_args+=(--no-cycle); shift ;;
    --sanitize) sanitize=1; shift ;;
    --minute-seconds) monitor_args+=(--minute "$2"); shift 2 ;;
    -h | --help) sed -n '2,20p' "$0"; exit 0 ;;
    *) extra+=("$1"); shift ;;
  esac
done
[[ $minutes =~ ^[1-9][0-9]*$ ]] || { echo "soak.sh: --minutes must be a positive whole number" >&2; exit 2; }
[[ $port =~ ^[0-9]+$ ]] || { echo "soak.sh: --port must be a number" >&2; exit 2; }

# shellcheck disable=SC1091
source "$ROOT/scripts/common.sh"
[[ $tree == "$ROOT" ]] || export ROS_PACKAGE_PATH="$tree/src"
[[ -n $out ]] || out="$ROOT/build/soak/$(date -u +%Y%m%d_%H%M%S)"
mkdir -p "$out" "$results"
# Absolute: the manager runs in this folder (its core dumps land there), so a relative bag or result path would
# resolve against it instead.
out=$(cd "$out" && pwd)
suffix=""
if ((sanitize)); then
  asan_build=${VRM_ASAN_BUILD:-$ROOT/build_asan}
  [[ -f $asan_build/devel/setup.bash ]] || {
    echo "soak.sh --sanitize: no ASan build in $asan_build (build it with scripts/test.sh --sanitize)" >&2
    exit 2
  }
  # The Debian nodelet binary with libasan preloaded (see the wrapper), found first by roslaunch in this devel space.
  install -D -m 755 "$ROOT/scripts/sanitizers/nodelet" "$asan_build/devel/lib/nodelet/nodelet"
  set +u
  # shellcheck disable=SC1091
  source "$asan_build/devel/setup.bash"
  set -u
  # shellcheck source=scripts/sanitizers/env.sh disable=SC1091
  source "$ROOT/scripts/sanitizers/env.sh" "$out"
  suffix=".sanitize"
fi
export ROS_MASTER_URI=http://localhost:$port ROS_LOG_DIR="$out/ros_log"
if ss -ltn "sport = :$port" | grep -q LISTEN; then
  echo "soak.sh: port $port is in use (another soak?); choose another with --port" >&2
  exit 2
fi
((minutes < 6)) && suffix="$suffix.quick"
json="$results/soak$suffix.json"
png="$results/soak$suffix.png"
bag="$out/soak.bag"

echo "soak.sh: ${minutes} min$([[ $suffix == *.quick ]] && echo " (smoke mode: baseline minute 1)")$( ((sanitize)) && echo " (ASan + UBSan build)"), master port $port," \
  "scene membrane_peeling, tracking, recording to $bag; run folder $out"
# duration:=0: session_control starts the session once the recorder listens and never stops it; the monitor's
# cycles are the session's STOP/LOAD/START (recorded inputs, like the console's).
# A manager that crashes leaves its core and every thread's stack in the run folder (vrm_graph/supervised_manager).
VRM_MANAGER_CORE_DIR="$out" setsid roslaunch -p "$port" "$tree/launch/simulator.launch" headless:=true sim:=true tracking:=true record:=true \
  duration:=0 "bag:=$bag" scene:=membrane_peeling "${extra[@]}" >"$out/launch.log" 2>&1 &
launch_pid=$!
stop_graph() {
  if kill -0 "$launch_pid" 2>/dev/null; then
    kill -INT "$launch_pid" 2>/dev/null || true
    for _ in $(seq 60); do kill -0 "$launch_pid" 2>/dev/null || break; sleep 0.5; done
    if kill -0 "$launch_pid" 2>/dev/null; then kill -TERM "$launch_pid" 2>/dev/null || true; fi
  fi
  wait "$launch_pid" 2>/dev/null || true
}
trap stop_graph EXIT
trap 'exit 130' INT TERM

set +e
/usr/bin/python3 "$ROOT/scripts/soak_monitor.py" --minutes "$minutes" --launch-pid "$launch_pid" --bag "$bag" \
  --out "$json" "${monitor_args[@]}" 2>&1 | tee "$out/monitor.log"
status=${PIPESTATUS[0]}
set -e
stop_graph
trap - EXIT

grep -hE "FATAL|ERROR|REQUIRED process|has died" "$out/launch.log" | sed -E 's/\x1b\[[0-9;]*m//g' | head -n 10 || true
echo "launch log: $out/launch.log"
for stacks in "$out"/core.*.backtrace.txt; do
  [[ -f $stacks ]] && echo "a manager crashed: its core ${stacks%.backtrace.txt}, every thread's stack in $stacks"
done
if ((sanitize)); then
  reports=("$SANITIZER_REPORTS"/*)
  if [[ -e ${reports[0]} ]]; then
    echo "soak.sh: ${#reports[@]} sanitizer report(s) in $SANITIZER_REPORTS:" >&2
    for report in "${reports[@]}"; do
      echo "== $report" >&2
      grep -E 'ERROR|SUMMARY|runtime error|^    #[0-9] ' "$report" | head -n 16 >&2 || true
    done
    status=1
  else
    echo "soak.sh: no sanitizer report"
  fi
fi
# roslaunch exits 0 when a required part failed: the soak fails then too (issue 20).
if ! failed=$(required_failures "$out/launch.log"); then
  echo "soak.sh: the simulator graph failed: $failed" >&2
  status=1
fi
if [[ -f $json ]]; then
  /usr/bin/python3 "$ROOT/scripts/soak_table.py" --png "$png" "$json" || true
  echo "results: $json, $png"
fi
ls "$out"/*.bag >/dev/null 2>&1 && echo "bag: $(du -ch "$out"/*.bag | tail -1 | cut -f1) in $(ls "$out"/*.bag | wc -l) file(s) under $out"
exit "$status"
