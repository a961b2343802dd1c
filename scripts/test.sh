#!/usr/bin/env bash
# The test tiers, each with the real verdict as its exit code (catkin's run_tests target exits 0 even when tests fail).
#
#   scripts/test.sh              everything, what CI runs (.ci/run): set-up + build, every unit test, every graph test
#                                (rostest), the main job (run.sh --check) and the script tests; catkin_test_results
#                                decides.
#   scripts/test.sh --fast       the inner loop: every unit-test binary of every package (plain gtest, no master, no
#                                graph), two at a time, after building only what they need (on an up-to-date build
#                                that check is the only build step). Prints the list it ran.
#   scripts/test.sh PKG [PKG..]  one package's unit tests (two at a time), then its graph tests (one at a time).
#   scripts/test.sh --sanitize [--part K/N]   the unit and graph tests built with ASan + UBSan in build_asan/ (all,
#                                or the K-th of N parts: scripts/sanitizers/run_tests.sh).
#
# Every tier first checks that bench/results/latency.json is newer than the last commit that changed what it measures
# (scripts/check_bench_fresh.sh, milliseconds, before building). A stale result does not stop the tests — a developer
# sees both verdicts — but the tier then exits non-zero and repeats why at the end.
#
# The unit tests are catkin_add_gtest targets, the graph tests add_rostest_gtest targets; the top-level CMakeLists.txt
# groups them into the build targets unit_tests and tests_<package>, and CTest (which catkin registers them with) runs
# them, longest first from its recorded costs.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BUILD="$ROOT/build"
RESULTS="$BUILD/test_results"

usage() {
  sed -n '2,16p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  echo "packages: $(cd "$ROOT/src" && ls -d */ | tr -d / | tr '\n' ' ')"
}

# ctest_tier LABEL REGEX JOBS: the catkin tests whose CTest name matches REGEX (catkin names them
# _ctest_<package>_<gtest|rostest>_<name>), JOBS at a time; returns ctest's verdict.
ctest_tier() {
  local label=$1 regex=$2 jobs=$3 start status
  start=$(date +%s%N)
  set +e
  ctest --test-dir "$BUILD/src" --tests-regex "$regex" --parallel "$jobs" --output-on-failure --timeout 1500 \
    | sed -E '/^ +Start +[0-9]+: /d; s/_ctest_//; /^Internal ctest changing into directory/d'
  status=${PIPESTATUS[0]}
  set -e
  echo "test.sh: $label: $((($(date +%s%N) - start) / 1000000000)) s wall"
  return "$status"
}

# Builds the given targets, or everything through setup.sh on a machine without a configured build.
build_targets() {
  if [[ ! -f "$BUILD/CMakeCache.txt" ]]; then
    "$ROOT/scripts/setup.sh"
  fi
  # A pyenv python3 may come first on PATH and lacks catkin_pkg: catkin must use the system interpreter.
  # Only what was built is worth a line: the up-to-date targets are not listed.
  PATH="/usr/bin:$PATH" cmake --build "$BUILD" --target "$@" -j"$(nproc)" | sed -E '/^\[ *[0-9]+%\] Built target /d'
}

# The bench freshness check's verdict joins the tier's: finish VERDICT exits with VERDICT, or 1 when latency.json is
# stale (and says so again, after the tests' output).
fresh_status=0
fresh_report=""
check_bench_fresh() {
  fresh_report=$("$ROOT/scripts/check_bench_fresh.sh" 2>&1) || fresh_status=1
  echo "$fresh_report"
}
finish() {
  if ((fresh_status != 0)); then
    echo "$fresh_report" >&2
    echo "test.sh: FAILED: bench/results/latency.json is stale (above); the tests' own verdict: exit status $1" >&2
    exit 1
  fi
  exit "$1"
}

case ${1:-} in
  -h | --help)
    usage
    exit 0
    ;;
  --fast | --sanitize | '' | [!-]*) check_bench_fresh ;;
esac

case ${1:-} in
  --sanitize)
    status=0
    shift
    "$ROOT/scripts/sanitizers/run_tests.sh" "$@" || status=$?
    finish $status
    ;;
  --fast)
    start=$(date +%s)
    build_targets unit_tests
    source "$ROOT/scripts/common.sh"
    rm -rf "$RESULTS"
    status=0
    ctest_tier "unit tests of every package" '^_ctest_[a-z_]+_gtest_' 2 || status=$?
    /usr/bin/python3 "$ROOT/scripts/test_summary.py" "$RESULTS" || status=1
    echo "test.sh --fast: $(($(date +%s) - start)) s wall, build check included"
    finish $status
    ;;
  -*)
    usage >&2
    exit 2
    ;;
  ?*)
    targets=() unit_regex="" graph_regex=""
    for package in "$@"; do
      if [[ ! -f "$ROOT/src/$package/package.xml" ]]; then
        echo "test.sh: no package '$package' in src/" >&2
        usage >&2
        exit 2
      fi
      targets+=("tests_$package")
      unit_regex+="${unit_regex:+|}^_ctest_${package}_gtest_"
      graph_regex+="${graph_regex:+|}^_ctest_${package}_rostest_"
    done
    start=$(date +%s)
    # The graph tests launch nodelets and tools of other packages too: the product is checked with the tests.
    build_targets all "${targets[@]}"
    source "$ROOT/scripts/common.sh"
    rm -rf "$RESULTS"
    status=0
    ctest_tier "unit tests of $*" "$unit_regex" 2 || status=$?
    # Graph tests start their own master and nodelet manager each: one at a time on two cores.
    ctest_tier "graph tests of $*" "$graph_regex" 1 || status=$?
    /usr/bin/python3 "$ROOT/scripts/test_summary.py" "$RESULTS" || status=1
    echo "test.sh $*: $(($(date +%s) - start)) s wall, build check included"
    finish $status
    ;;
esac

# --- everything (CI) ---
"$ROOT/scripts/setup.sh"
source "$ROOT/scripts/common.sh"

cmake --build "$ROOT/build" --target tests -j"$(nproc)"
tests_start=$(date +%s)
rm -rf "$RESULTS"
# The unit tests two at a time, the graph tests one at a time (each starts its own master and manager; the machine has
# two cores). Their verdicts are the JUnit files catkin_test_results reads below.
ctest_tier "unit tests" '^_ctest_[a-z_]+_gtest_' 2 || true
ctest_tier "graph tests" '^_ctest_[a-z_]+_rostest_' 1 || true
# The bench freshness check (run first, above) as a JUnit case, so CI's report lists it beside the tests.
mkdir -p "$RESULTS/bench_fresh"
fresh_failure=""
((fresh_status == 0)) || fresh_failure="<failure message=\"bench/results/latency.json is stale (scripts/check_bench_fresh.sh)\"><![CDATA[$fresh_report]]></failure>"
printf '<?xml version="1.0"?>\n<testsuite name="bench_fresh" tests="1" failures="%s" errors="0"><testcase classname="check_bench_fresh" name="latency_json_newer_than_what_it_measures">%s</testcase></testsuite>\n' \
  "$fresh_status" "$fresh_failure" >"$RESULTS/bench_fresh/TEST-bench_fresh.xml"

# The main job as a user runs it (short form, through the first grasp and peel): the default session must grasp the
# membrane and publish it deformed (run.sh --check). Its verdict joins the others as a JUnit case.
echo "test.sh: ./scripts/run.sh --duration 12 --check"
mkdir -p "$RESULTS/main_job"
failures=0 failure=""
if ! main_job=$("$ROOT/scripts/run.sh" --duration 12 --check 2>&1); then
  failures=1 failure="<failure message=\"the default session did not do its job (scripts/run.sh --check: frames, tissue grasped, scenario finished, replay bit-identical)\"/>"
fi
echo "$main_job" | tail -n 4
printf '<?xml version="1.0"?>\n<testsuite name="main_job" tests="1" failures="%s" errors="0"><testcase classname="run_sh" name="default_session_grasps_and_peels">%s</testcase></testsuite>\n' \
  "$failures" "$failure" >"$RESULTS/main_job/TEST-main_job.xml"

# Script tests (a real X window under Xvfb, a console on a second ROS host): each a JUnit case.
script_test() {  # script_test SUITE CASE COMMAND...
  local suite=$1 name=$2 failure="" failed=0 output
  shift 2
  echo "test.sh: $*"
  mkdir -p "$RESULTS/$suite"
  if ! output=$("$@" 2>&1); then
    failed=1 failure="<failure message=\"$* failed\"><![CDATA[$(echo "$output" | tail -n 30)]]></failure>"
  fi
  # A test whose output has no such line (unittest prints "OK") must not end test.sh: grep's 1 under pipefail would.
  echo "$output" | { grep -E '^(PASS|FAIL|SKIP|remote-host)|: PASS|FAILED|^OK' || true; } | tail -n 30
  printf '<?xml version="1.0"?>\n<testsuite name="%s" tests="1" failures="%s" errors="0"><testcase classname="%s" name="%s">%s</testcase></testsuite>\n' \
    "$suite" "$failed" "$suite" "$name" "$failure" >"$RESULTS/$suite/TEST-$suite.xml"
}
# Live = replay under load (issue 31): run.sh's session recorded under two busy loops, a relay that delays and
# silences the instrument on its way to the simulation node only, and the eye at 100 Hz: live = offline replay =
# replay.launch, bit for bit; the perturbation bit; the frames have no gap (~1.5 min).
script_test determinism live_equals_replay_under_load /usr/bin/python3 "$ROOT/src/vrm_sim/test/graph/determinism.py" test
# One scene owner (issue 32): one running graph switches navigation -> membrane_peeling -> a scene with its own eye
# geometry -> vitrectomy by LOAD, every node follows, a refused LOAD changes nothing, the manager never restarts (~1.5 min).
script_test scene_switch one_graph_follows_every_load /usr/bin/python3 "$ROOT/src/vrm_sim/test/graph/scene_switch.py"
script_test console_real_window console_runs_a_session_in_a_real_window \
  "$ROOT/src/eyesi_gui/test/console_real_window.sh"
script_test console_remote_station console_on_a_second_host \
  "$ROOT/src/eyesi_gui/test/remote/console_remote_station.sh"
# One session graph for every live session (issue 32): two scenes switched by LOAD in the same manager process, a
# bag per session, a refused LOAD leaves the previous scene running (~1.5 min).
script_test station_one_graph two_sessions_one_graph /usr/bin/python3 "$ROOT/src/eyesi_gui/test/station_one_graph.py" test
# The security defaults SECURITY.md claims, and its firewall rules in a network-namespace pair (issue 14).
script_test security_defaults security_defaults_hold "$ROOT/src/eyesi_gui/test/security_defaults.sh"
script_test security_firewall firewall_rules_in_netns "$ROOT/src/eyesi_gui/test/security_firewall.sh"
# A training centre (issue 41): a throw-away PostgreSQL cluster and three sync clients in network namespaces; the
# server and a station killed mid-sync, one offline; every session on the server exactly once; roles checked against
# the server directly (~20 s).
script_test records_centre centre_sync_roles_and_kills /usr/bin/python3 "$ROOT/src/eyesi_gui/test/centre/centre_sync.py"
# The researcher's export (issue 41): the reference sessions with their bags' trajectories exported as tidy CSV and
# read back with Python (scores, trajectory lengths from the bags), and the pseudonymised export (~2 s).
script_test records_export export_round_trips_and_pseudonymises /usr/bin/python3 "$ROOT/src/eyesi_gui/test/records_export.py"
# Runtime faults of the product graph (issues 14, 39): crashes (crash = pause; no gap in the record), a hostile flood,
# a consumer that never reads, the recorder's disk full.
for fault in manager_crash recorder_crash hostile_flood slow_consumer disk_full; do
  script_test "fault_$fault" "$fault" /usr/bin/python3 "$ROOT/src/vrm_graph/test/faults/graph_faults.py" "$fault"
done
# The install space runs the simulator without the source tree (issue 18): a temporary prefix, strace for the checkout.
# A new user's first hour (issue 20): a failed graph fails the scripts that wrap roslaunch.
script_test failed_graph wrapper_fails_when_a_required_part_fails "$ROOT/scripts/tests/failed_graph.sh"
script_test readme_clients readme_ros_clients_answer "$ROOT/scripts/tests/readme_clients.sh"
# The layers at link time (issue 42): ldd of the scene floor, tracking, rendering and the console's binaries (~1 s).
script_test library_layers floor_tracking_render_and_console_link_no_physics_or_rosbag \
  "$ROOT/scripts/tests/library_layers.sh"
# The fuzz targets' seeds and dictionaries are what make_seeds.py writes from the shipped files today (issue 39 §3; a
# moved test folder once broke it unseen) (~1 s).
script_test fuzz_seeds seeds_and_dictionaries_match_the_shipped_files \
  /usr/bin/python3 "$ROOT/src/vrm_fuzz/scripts/make_seeds.py" --check
# The session result's Python reader against the reference results and the malformed corpus the C++ reader reads.
script_test session_result_py python_reader_keeps_the_schema /usr/bin/python3 "$ROOT/scripts/tests/test_session_result.py"
script_test install_space installed_simulator_runs_without_the_source_tree "$ROOT/scripts/install-test.sh"

set +e
summary=$(catkin_test_results "$RESULTS" --all 2>&1)
verdict=$?
set -e
echo "$summary" | grep -vE '^(Skipping|$)' | tail -n 40
echo "test.sh: $(($(date +%s) - tests_start)) s wall after the build"
if ! /usr/bin/python3 "$ROOT/scripts/test_summary.py" "$RESULTS"; then
  echo "test.sh: no test results found" >&2
  finish 1
fi
finish $verdict
