#!/usr/bin/env bash
# scripts/test.sh --sanitize: every unit test and rostest of the workspace, built with AddressSanitizer (+ LeakSanitizer)
# and UndefinedBehaviorSanitizer in build_asan/ — the same `tests` and `run_tests` targets as the plain run, judged by
# catkin_test_results, plus one JUnit case that fails when any process wrote a sanitizer report.
#
# Not run here: the main job (scripts/run.sh --check) and the script tests (console under Xvfb, remote station). They
# start the Release build in build/ through scripts/common.sh, and the nodelets they exercise are the ones the
# rostests load here; under ASan their wall-clock checks (frames in N seconds) would measure the sanitizer.
#
# Usage: scripts/test.sh --sanitize [--part K/N]   (run it with `nice -n 10` on a shared machine)
#   --part K/N  the K-th of N parts of the tests (CTest's stride selection: tests K, K+N, K+2N, ... of the workspace's
#               catkin tests in CTest order), so that a full run fits in sittings; every part builds what is missing
#               first (the first part the whole workspace), then prints its totals and the test names it ran. The
#               sanitizer-report case counts the reports of that part only.
# Environment: VRM_ASAN_BUILD (default <ws>/build_asan), VRM_SANITIZE_JOBS (default nproc).
set -euo pipefail
part="" parts=""
while (($#)); do
  case $1 in
    --part)
      [[ ${2:-} =~ ^([0-9]+)/([0-9]+)$ ]] && ((BASH_REMATCH[1] >= 1 && BASH_REMATCH[1] <= BASH_REMATCH[2])) || {
        echo "test.sh --sanitize: --part needs K/N with 1 <= K <= N (got '${2:-}')" >&2
        exit 2
      }
      part=${BASH_REMATCH[1]} parts=${BASH_REMATCH[2]}
      shift 2
      ;;
    *)
      echo "test.sh --sanitize: unknown argument '$1' (usage: test.sh --sanitize [--part K/N])" >&2
      exit 2
      ;;
  esac
done
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BUILD=${VRM_ASAN_BUILD:-$ROOT/build_asan}
JOBS=${VRM_SANITIZE_JOBS:-$(nproc)}
"$ROOT/scripts/setup.sh" --no-build
# A pyenv python3 may come first on PATH and lacks catkin_pkg: catkin must use the system interpreter.
export PATH="/usr/bin:$PATH"

# RelWithDebInfo with -O1: fast enough for the graph tests, still precise stacks; -fno-omit-frame-pointer for ASan's
# fast unwinder. NDEBUG as in the Release build, so the tests check the code that ships.
SAN="-fsanitize=address,undefined -fno-omit-frame-pointer"
# --as-needed as Debian's gcc adds it to every link but a -fsanitize one (gcc -dumpspecs: %{!fsanitize=*:--as-needed}).
# Without it a nodelet library pulls every library its dependencies export into the manager's global scope (the
# tracking nodelets: cv_bridge's OpenCV, highgui, glvnd's libOpenGL/libGL), and GL calls bound to glvnd's stubs instead
# of OSMesa. With it the ASan managers load what the Release ones load. (Preloading OSMesa into every manager, the first
# fix, cost the Release view about a fifth of its frame rate: bench_latency A/B, 2026-12-02.)
LINK_SAN="-fsanitize=address,undefined -Wl,--as-needed"
# Configured every run with the same values (a no-op then): a build directory configured before a flag changed here
# takes the change (new linker flags relink, they recompile nothing).
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_FLAGS="$SAN" -DCMAKE_CXX_FLAGS="$SAN" \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g -DNDEBUG" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g -DNDEBUG" \
  -DCMAKE_EXE_LINKER_FLAGS="$LINK_SAN" -DCMAKE_SHARED_LINKER_FLAGS="$LINK_SAN" -DCMAKE_MODULE_LINKER_FLAGS="$LINK_SAN" \
  -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 >"$ROOT/build_asan.configure.log" 2>&1 \
  || { cat "$ROOT/build_asan.configure.log"; echo "test.sh --sanitize: cmake configure failed" >&2; exit 1; }
mv "$ROOT/build_asan.configure.log" "$BUILD/configure.log"
start=$(date +%s)
cmake --build "$BUILD" -j"$JOBS"
cmake --build "$BUILD" --target tests -j"$JOBS"
echo "test.sh --sanitize: build $(($(date +%s) - start)) s"

# The Debian nodelet binary hosts our ASan-built nodelet libraries: it needs the ASan runtime preloaded (see the
# wrapper's comment). catkin_find looks in this devel space before /usr, so roslaunch starts the wrapper.
install -D -m 755 "$ROOT/scripts/sanitizers/nodelet" "$BUILD/devel/lib/nodelet/nodelet"

set +u
# shellcheck disable=SC1091
source "$BUILD/devel/setup.bash"
set -u
export ROS_HOSTNAME=${ROS_HOSTNAME:-localhost}
export ROS_LOG_DIR="$BUILD/ros_log"
# shellcheck source=scripts/sanitizers/env.sh disable=SC1091
source "$ROOT/scripts/sanitizers/env.sh" "$BUILD"
rm -rf "$SANITIZER_REPORTS" "$BUILD/test_results"
mkdir -p "$SANITIZER_REPORTS"

start=$(date +%s)
# The tests' console, kept: a report that bypassed log_path is counted from it below.
CONSOLE="$BUILD/test_console.log"
# One test at a time: rostests start their own masters and the machine has two cores.
if [[ -n $part ]]; then
  # CTest runs catkin's run_tests_* commands, which write the same JUnit files into test_results/.
  ctest --test-dir "$BUILD/src" -I "$part,,$parts" --output-on-failure --timeout 4800 2>&1 | tee "$CONSOLE" \
    | sed -E '/^ +Start +[0-9]+: /d; s/_ctest_//; /^Internal ctest changing into directory/d' || true
  echo "test.sh --sanitize: part $part/$parts: tests $(($(date +%s) - start)) s"
else
  cmake --build "$BUILD" --target run_tests -j1 2>&1 | tee "$CONSOLE" || true
  echo "test.sh --sanitize: tests $(($(date +%s) - start)) s"
fi

# Sanitizer reports as one JUnit case: a report from a process no test checks (a nodelet manager at its exit, a helper
# node) still fails the run. Each file is named <asan|ubsan>.<pid>.
mkdir -p "$BUILD/test_results/sanitizers"
reports=()
for report in "$SANITIZER_REPORTS"/*; do
  [[ -e $report ]] || continue
  # test_fuzz_regressions runs with allocator_may_return_null (fuzz_support.cpp): ASan then refuses a fuzzed gigabyte
  # allocation with one WARNING line and returns null (std::bad_alloc), which is the behaviour under test. A file
  # holding nothing else is no report.
  if ! grep -qvE '^(==[0-9]+==WARNING: AddressSanitizer failed to allocate 0x[0-9a-f]+ bytes)?$' "$report"; then
    echo "test.sh --sanitize: $(basename "$report"): allocations refused as configured (allocator_may_return_null), not a report"
    continue
  fi
  reports+=("$report")
done
# A report can bypass log_path: UBSan's runtime in a nodelet manager (the Debian nodelet binary preloads libasan only,
# and libubsan, loaded with our libraries, printed to stderr: the stereo renderer's null glGetString, 2026-12-02, went
# uncounted). What the tests printed is in the console: its reports are counted too, and kept beside the files.
report_start='^[^ ]*: runtime error: |^==[0-9]+==ERROR: (AddressSanitizer|LeakSanitizer)'
printed_reports=$(grep -cE "$report_start" "$CONSOLE" || true)
if ((printed_reports > 0)); then
  grep -E -A 12 "$report_start" "$CONSOLE" >"$SANITIZER_REPORTS/console.printed" || true
  reports+=("$SANITIZER_REPORTS/console.printed")
fi
count=$((${#reports[@]} + (printed_reports > 1 ? printed_reports - 1 : 0)))
failure=""
if ((count)); then
  echo "test.sh --sanitize: $count sanitizer report(s) in $SANITIZER_REPORTS ($printed_reports of them printed to the console):"
  for report in "${reports[@]}"; do
    echo "== $report"
    grep -E 'ERROR|WARNING|SUMMARY|runtime error|^    #[0-9] ' "$report" | head -n 12 || true
  done
  failure="<failure message=\"$count sanitizer report(s) in $SANITIZER_REPORTS\"><![CDATA[$(
    for report in "${reports[@]}"; do echo "== $report"; grep -E 'ERROR|WARNING|SUMMARY|runtime error' "$report" | head -n 5 || true; done
  )]]></failure>"
fi
printf '<?xml version="1.0"?>\n<testsuite name="sanitizers" tests="1" failures="%s" errors="0"><testcase classname="sanitizers" name="no_asan_lsan_ubsan_reports">%s</testcase></testsuite>\n' \
  "$((count > 0))" "$failure" >"$BUILD/test_results/sanitizers/TEST-sanitizers.xml"

set +e
summary=$(catkin_test_results "$BUILD/test_results" --all 2>&1)
verdict=$?
set -e
echo "$summary" | grep -vE '^(Skipping|$)' | tail -n 40
if ! /usr/bin/python3 "$ROOT/scripts/test_summary.py" "$BUILD/test_results"; then
  echo "test.sh --sanitize: no test results found" >&2
  exit 1
fi
exit $verdict
