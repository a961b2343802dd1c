#!/usr/bin/env bash
# issue 20: a graph whose required part failed must fail the scripts that wrap roslaunch (roslaunch itself exits 0).
#   1. required_failures (scripts/common.sh) on roslaunch's own wording: a required node that died with an exit code
#      is a failure, one that finished cleanly (session_control after `duration`) is not;
#   2. scripts/run.sh --scenario nonexistent exits non-zero and says why (the manager's supervisor turns the scene
#      manager's refusal into exit code 1 with the reason);
#   3. the same launch straight through roslaunch: the manager's exit code is 1 and the reason is printed.
# Prints PASS/FAIL lines; exits 1 on any failure.
set -uo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/checks.sh"
trap 'rm -rf "$TMP"' EXIT

printf '%s\n' '================================================================================REQUIRED process [session_control-13] has died!' \
  'process has finished cleanly' 'log file: x' 'Initiating shutdown!' >"$TMP/clean.log"
printf '%s\n' $'\e[31m================================================================================REQUIRED process [vrm_manager-2] has died!' \
  'process has died [pid 1, exit code 1, cmd supervised_manager __name:=vrm_manager].' 'Initiating shutdown!' >"$TMP/died.log"
printf '%s\n' '[scene_manager-3] process has died [pid 2, exit code 255, cmd nodelet_keeper].' >"$TMP/optional.log"
required_failures "$TMP/clean.log" >/dev/null && pass "a required node that finished cleanly is no failure" \
  || fail "required_failures flags a clean finish"
out=$(required_failures "$TMP/died.log") && fail "required_failures misses a required node that died" \
  || { [[ $out == *"vrm_manager-2"*"exit code 1"* ]] && pass "a required node that died is a failure: $out" || fail "wording: $out"; }
required_failures "$TMP/optional.log" >/dev/null && pass "a non-required node's death is left to the run's own checks" \
  || fail "required_failures flags a non-required node"

PORT=${PORT:-11733}
export ROS_MASTER_URI=http://localhost:$PORT
timeout -s INT -k 10 90 roslaunch -p "$PORT" "$ROOT/launch/simulator.launch" scene:=nonexistent tracking:=false \
  >"$TMP/launch.log" 2>&1
code=$?
reason=$(grep -a "supervised_manager: the graph failed" "$TMP/launch.log" | head -n 1)
if ! required_failures "$TMP/launch.log" >/dev/null && [[ $reason == *"nonexistent"* ]]; then
  pass "roslaunch scene:=nonexistent (exit $code): the manager failed with the reason: $reason"
else
  fail "roslaunch scene:=nonexistent: no failed required node or no reason"; tail -n 20 "$TMP/launch.log" | sed 's/^/    /'
fi
unset ROS_MASTER_URI

run_out=$("$ROOT/scripts/run.sh" --scenario nonexistent --duration 5 2>&1)
run_code=$?
if ((run_code != 0)) && [[ $run_out == *"the simulator graph failed"* ]]; then
  pass "scripts/run.sh --scenario nonexistent exits $run_code: $(grep -a 'the simulator graph failed' <<<"$run_out")"
else
  fail "scripts/run.sh --scenario nonexistent exited $run_code"; tail -n 15 <<<"$run_out" | sed 's/^/    /'
fi
((failures == 0)) || exit 1
