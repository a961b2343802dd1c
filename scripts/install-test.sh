#!/usr/bin/env bash
# Install test (issue 18): the install space runs the simulator without the source tree, as a training centre deploys
# it. Installs the built workspace (build/, `cmake --install`, no second build) into a temporary directory, then, in a
# clean environment that sources only <prefix>/setup.bash and with a working directory outside the checkout:
#   1. the environment (ROS_PACKAGE_PATH, PATH, LD_LIBRARY_PATH, PYTHONPATH, CMAKE_PREFIX_PATH) names no path in the
#      checkout, every package resolves into the prefix, every nodelet plugin library exists there, the graph tools
#      the launch files start are in lib/vrm_graph, and no installed text file names the checkout;
#   2. rosrun vrm_sim tissue_offline --scene membrane_peeling --seconds 0.2 gives the devel space's state hash;
#   3. roslaunch vrm_bringup simulator.launch runs 10 s headless (simulated hardware, recording; the scripted expert), the
#      renderer saves a stereo frame, the session writes its result, the installed session_replay replays the bag to
#      the devel space's replay's final state; roslaunch vrm_bringup replay.launch resolves with that bag;
#   4. rosrun vrm_tracking tracking_eval runs on the installed trajectory, rig and layout files.
# Every installed process runs under `strace -f -e trace=%file`: no file path into the checkout may be touched (opened,
# stat'ed, executed). Everything is removed afterwards (the prefix, the ROS logs, the master and the graph).
# catkin writes the workspace's setup files to the configure-time CMAKE_INSTALL_PREFIX (an absolute install
# destination), so the test installs with DESTDIR into <tmp>/root and uses <tmp>/root<CMAKE_INSTALL_PREFIX>:
# catkin's setup.bash and _setup_util.py find their own directory, so the prefix may move.
# Usage: scripts/install-test.sh [--keep] (--keep: leave the temporary directory for inspection). Exit 0 = passed.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BUILD=${VRM_BUILD_DIR:-$ROOT/build}
keep=false
[[ ${1:-} == --keep ]] && keep=true
export PATH="/usr/bin:$PATH"
started=$(date +%s.%N)

[[ -f $BUILD/CMakeCache.txt ]] || { echo "install-test: no build in $BUILD (run scripts/setup.sh)" >&2; exit 1; }
command -v strace >/dev/null || { echo "install-test: strace is missing (scripts/setup.sh installs it)" >&2; exit 1; }
install_prefix=$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$BUILD/CMakeCache.txt")
TMP=$(mktemp -d /tmp/vrm_install_test.XXXXXX)
PREFIX=$TMP/root$install_prefix
OUT=$TMP/session
WORK=$TMP/work  # the working directory of every installed run
mkdir -p "$OUT" "$WORK" "$TMP/home"
# A port of our own for the graph's master (the other graph tests use 11311 and 11750-11990): the first free one.
PORT=$((12050 + $$ % 100))
while /usr/bin/python3 -c 'import socket,sys; socket.create_connection(("localhost", int(sys.argv[1])), 0.5)' "$PORT" 2>/dev/null; do
  PORT=$((PORT + 1))
done
launch_pid=""

cleanup() {
  if [[ -n $launch_pid ]] && kill -0 "$launch_pid" 2>/dev/null; then
    kill -INT -- "-$launch_pid" 2>/dev/null || true
    for _ in $(seq 1 30); do kill -0 "$launch_pid" 2>/dev/null || break; sleep 0.5; done
    kill -KILL -- "-$launch_pid" 2>/dev/null || true
  fi
  if $keep; then echo "install-test: kept $TMP"; else rm -rf "$TMP"; fi
}
trap cleanup EXIT

failures=0
pass() { echo "PASS $*"; }
fail() { echo "FAIL $*"; failures=$((failures + 1)); }

# --- install -------------------------------------------------------------------------------------------------------
t0=$(date +%s.%N)
if ! DESTDIR=$TMP/root cmake --install "$BUILD" >"$TMP/install.log" 2>&1; then
  tail -n 20 "$TMP/install.log"
  echo "FAIL cmake --install"
  exit 1
fi
echo "install-test: installed into $PREFIX ($(find "$PREFIX" -type f | wc -l) files, $(du -sh "$PREFIX" | cut -f1)," \
  "$(awk "BEGIN{printf \"%.1f\", $(date +%s.%N) - $t0}") s)"
[[ -f $PREFIX/setup.bash ]] || { echo "FAIL no $PREFIX/setup.bash"; exit 1; }
if [[ -e $install_prefix/setup.bash && $install_prefix/setup.bash -nt $TMP/install.log ]]; then
  fail "something was installed outside DESTDIR ($install_prefix/setup.bash)"
fi

# A clean environment with only the install space: nothing from the devel space or the caller's shell.
cat >"$TMP/installed.sh" <<EOF
set +u
source "$PREFIX/setup.bash"
set -u
cd "$WORK"
unset OLDPWD  # else every bash started here (rosrun, roslaunch's scripts) stats the caller's directory
exec "\$@"
EOF
installed() {  # installed COMMAND... : in the install space's environment, working directory outside the checkout
  cd "$WORK" && env -i HOME="$TMP/home" PATH=/usr/bin:/bin LANG=C.UTF-8 ROS_HOME="$TMP/home/.ros" ROS_HOSTNAME=localhost \
    ROS_MASTER_URI="http://localhost:$PORT" bash --noprofile --norc "$TMP/installed.sh" "$@"
}
# Every file system call (open, exec, stat, ...) of the offline tools; for the live graph only the calls that open or
# run a file: tracing its ~50,000 stats slows it enough to change the live session (its replay then differs).
FILE_CALLS=%file
OPEN_CALLS=open,openat,openat2,creat,execve,execveat,readlink,readlinkat,chdir
traced() {  # traced NAME COMMAND... : installed, the file calls of every process written to $TMP/NAME.trace
  installed strace -f -qq --seccomp-bpf -e trace="${TRACE_CALLS:-$FILE_CALLS}" -e signal=none -o "$TMP/$1.trace" "${@:2}"
}
# Files of the checkout a traced run touched (the prefix lives in /tmp, so any path under ROOT is the source tree
# or the devel space).
touched_checkout() { grep -hoE "\"$ROOT(/[^\"]*|\")" "$TMP/$1.trace" | sort -u | head -n 10 || true; }
check_trace() {  # check_trace NAME WHAT
  local touched
  touched=$(touched_checkout "$1")
  if [[ -z $touched ]]; then
    pass "$2: no path into the checkout opened ($(grep -c . "$TMP/$1.trace") file calls traced)"
  else
    fail "$2 touched the checkout:"
    echo "$touched" | sed 's/^/    /'
  fi
}

# --- 1. environment and contents -------------------------------------------------------------------------------------
env_dump=$(installed bash -c 'for v in ROS_PACKAGE_PATH PATH LD_LIBRARY_PATH PYTHONPATH CMAKE_PREFIX_PATH PKG_CONFIG_PATH; do echo "$v=${!v:-}"; done')
if grep -q "$ROOT" <<<"$env_dump"; then
  fail "the installed environment names the checkout:"
  grep "$ROOT" <<<"$env_dump" | sed 's/^/    /'
else
  pass "environment: $(grep ROS_PACKAGE_PATH <<<"$env_dump"), nothing in $ROOT"
fi
for package in vrm_msgs vrm_gl vrm_sim vrm_graph vrm_tracking vrm_render eyesi_gui vrm_bringup; do
  where=$(installed rospack find "$package" 2>/dev/null || true)
  [[ $where == "$PREFIX/share/$package" ]] || fail "rospack find $package -> '$where' (expected $PREFIX/share/$package)"
done
pass "rospack finds the packages in the prefix"
# Every nodelet plugin library the installed plugin descriptions name exists in the prefix.
missing_plugins=""
for xml in "$PREFIX"/share/*/nodelet_plugins.xml; do
  for library in $(sed -n 's/.*<library path="\([^"]*\)".*/\1/p' "$xml"); do
    [[ -f $PREFIX/$library.so ]] || missing_plugins+=" $library (from $xml)"
  done
done
if [[ -z $missing_plugins ]]; then pass "nodelet plugin libraries installed"; else fail "missing:$missing_plugins"; fi
# Every installed executable and library loads its libraries from the prefix or the system (no RPATH into build/).
unresolved=$(installed bash -c 'for f in $(find "$1/lib" -maxdepth 2 -type f \( -name "*.so" -o -perm -u+x \)); do
    file -b "$f" 2>/dev/null | grep -q ELF || head -c 4 "$f" | grep -q ELF || continue
    ldd "$f" 2>&1 | grep -E "not found|$2" | sed "s|^|$f: |"
  done' _ "$PREFIX" "$ROOT" || true)
if [[ -z $unresolved ]]; then pass "installed executables and libraries resolve their libraries outside the checkout"
else fail "unresolved or checkout libraries:"; echo "$unresolved" | head -n 10 | sed 's/^/    /'; fi
plugin_list=$(installed rospack plugins --attrib=plugin nodelet 2>/dev/null || true)
for package in vrm_sim vrm_graph vrm_tracking vrm_render; do
  grep -q "^$package $PREFIX/share/$package/nodelet_plugins.xml" <<<"$plugin_list" \
    || fail "rospack plugins: no installed nodelet plugins of $package"
done
# The graph infrastructure (vrm_graph, issue 42): the launch files start its tools by package name, so each must be
# where rosrun looks in the prefix, and its monitors' configuration in its share.
missing_graph=""
for tool in nodelet_keeper supervised_manager session_recorder session_control input_relay; do
  [[ -x $PREFIX/lib/vrm_graph/$tool ]] || missing_graph+=" lib/vrm_graph/$tool"
done
for file in share/vrm_graph/package.xml share/vrm_graph/nodelet_plugins.xml share/vrm_graph/config/input_monitor.yaml \
    lib/libvrm_graph_nodelets.so; do
  [[ -f $PREFIX/$file ]] || missing_graph+=" $file"
done
for tool in nodelet_keeper supervised_manager session_recorder session_control input_relay; do
  [[ ! -e $PREFIX/lib/vrm_sim/$tool ]] || missing_graph+=" (still installed: lib/vrm_sim/$tool)"
done
if [[ -z $missing_graph ]]; then pass "vrm_graph's tools, scripts, plugin library and config installed"
else fail "vrm_graph install:$missing_graph"; fi
# Installed text files (launch, config, scripts, setup files) must not name the checkout. CMake package configs may
# name it only in the devel-space variant, which is not installed.
named=$(grep -rIl "$ROOT" "$PREFIX" 2>/dev/null | head -n 10 || true)
if [[ -z $named ]]; then pass "no installed text file names $ROOT"; else fail "installed files name the checkout:"; echo "$named" | sed 's/^/    /'; fi

# --- 2. tissue_offline: the same state hash as the devel space -------------------------------------------------------
hash_of() { /usr/bin/python3 -c 'import json,sys; print(json.loads(sys.argv[1].strip().splitlines()[-1])["final_state_hash"])' "$1"; }
devel_json=$(env -i HOME="$TMP/home" PATH=/usr/bin:/bin ROS_HOME="$TMP/home/.ros" bash --noprofile --norc -c \
  "set +u; source '$BUILD/devel/setup.bash'; rosrun vrm_sim tissue_offline --scene membrane_peeling --seconds 0.2") \
  || fail "devel space's tissue_offline failed"
installed_json=$(traced tissue_offline rosrun vrm_sim tissue_offline --scene membrane_peeling --seconds 0.2) \
  || fail "installed tissue_offline failed"
devel_hash=$(hash_of "$devel_json" 2>/dev/null || echo "none (devel)")
installed_hash=$(hash_of "$installed_json" 2>/dev/null || echo none)
if [[ $installed_hash == "$devel_hash" ]]; then
  pass "tissue_offline --scene membrane_peeling --seconds 0.2: state hash $installed_hash = devel space"
else
  fail "tissue_offline: installed state hash $installed_hash, devel space $devel_hash"
fi
check_trace tissue_offline "tissue_offline"

# --- 3. the simulator graph from the install space -------------------------------------------------------------------
t1=$(date +%s.%N)
# roslaunch (with its own master on a port of this test) in its own process group, which cleanup ends as a whole; it
# ends by itself after `duration` s of input time (session_control is a required node).
cd "$WORK"
setsid bash -c 'exec "$@"' _ env -i HOME="$TMP/home" PATH=/usr/bin:/bin LANG=C.UTF-8 ROS_HOME="$TMP/home/.ros" \
  ROS_HOSTNAME=localhost ROS_MASTER_URI="http://localhost:$PORT" bash --noprofile --norc "$TMP/installed.sh" \
  timeout --signal=INT --kill-after=15 90 \
  strace -f -qq --seccomp-bpf -e trace="$OPEN_CALLS" -e signal=none -o "$TMP/simulator.trace" \
  roslaunch -p "$PORT" vrm_bringup simulator.launch headless:=true sim:=true tracking:=false record:=true \
  duration:=10 bag:="$OUT/session.bag" snapshot_dir:="$OUT" snapshot_times:="3 6" script:=scenario:expert \
  >"$TMP/launch.log" 2>&1 &
launch_pid=$!
launch_status=0
wait "$launch_pid" || launch_status=$?
launch_pid=""
echo "install-test: roslaunch vrm_bringup simulator.launch ended with status $launch_status after" \
  "$(awk "BEGIN{printf \"%.1f\", $(date +%s.%N) - $t1}") s"
frames=$(find "$OUT" -name '*.png' | wc -l)
if ((frames > 0)); then pass "the installed renderer saved $frames stereo frame PNGs"; else fail "no frame saved"; fi
result=$OUT/session.result.json
if [[ -f $result && -f $OUT/session.bag ]]; then
  pass "the session recorded its bag and wrote its result ($(/usr/bin/python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); print("scene %s, state %s" % (d["scene"], d["state"]))' "$result"))"
  if ! /usr/bin/python3 -c 'import json,sys; f=json.load(open(sys.argv[1])).get("scene_file",""); sys.exit(0 if f.startswith(sys.argv[2]) else 1)' "$result" "$PREFIX/share/vrm_sim/"; then
    fail "the session's scene file is not the installed one: $(grep -o '"scene_file": "[^"]*"' "$result")"
  fi
  # The installed offline replay of the installed session's bag ends where the devel space's replay of it does (the
  # live-vs-replay equality is run.sh --check's case: under load the live graph may take inputs late).
  final_hash() { /usr/bin/python3 -c 'import json,sys; print(json.loads(sys.argv[1].strip().splitlines()[-1])["final_state_hash"])' "$1" 2>/dev/null || echo none; }
  live_hash=$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["final_state_hash"])' "$result")
  replay_hash=$(final_hash "$(traced session_replay rosrun vrm_sim session_replay --bag "$OUT/session.bag" || true)")
  devel_replay_hash=$(final_hash "$(cd "$WORK" && env -i HOME="$TMP/home" PATH=/usr/bin:/bin ROS_HOME="$TMP/home/.ros" \
    bash --noprofile --norc -c "set +u; source '$BUILD/devel/setup.bash'; rosrun vrm_sim session_replay --bag '$OUT/session.bag'" || true)")
  if [[ $replay_hash != none && $replay_hash == "$devel_replay_hash" ]]; then
    pass "installed session_replay of the session: final state $replay_hash = devel space's replay (live: $live_hash$([[ $live_hash == "$replay_hash" ]] && echo ", equal" || echo ", differs"))"
  else
    fail "session_replay: installed $replay_hash, devel space $devel_replay_hash"
  fi
  check_trace session_replay "session_replay"
  if traced replay_launch roslaunch --nodes vrm_bringup replay.launch bag:="$OUT/session.bag" >"$TMP/replay_nodes.log" 2>&1 \
      && grep -q session_player "$TMP/replay_nodes.log"; then
    pass "roslaunch vrm_bringup replay.launch resolves ($(wc -l <"$TMP/replay_nodes.log") nodes)"
  else
    fail "roslaunch vrm_bringup replay.launch:"; tail -n 5 "$TMP/replay_nodes.log" | sed 's/^/    /'
  fi
  check_trace replay_launch "replay.launch"
else
  fail "no session bag or result in $OUT (launch status $launch_status)"
fi
if ((failures)); then grep -E "ERROR|FATAL|rror" "$TMP/launch.log" | head -n 15 | sed 's/^/    /' || true; fi
check_trace simulator "simulator.launch (every process of the graph; opens and execs)"

# --- 4. tracking_eval on the installed script, rig and layout ---------------------------------------------------------
share=$PREFIX/share/vrm_tracking/config
script=$PREFIX/share/vrm_sim/config/scripts/membrane_peeling_demo.yaml
if eval_json=$(traced tracking_eval rosrun vrm_tracking tracking_eval --trajectory "$script" \
    --rig "$share/rig_default.yaml" --layout "$share/markers_default.yaml" --frames 25); then
  pass "tracking_eval: $(/usr/bin/python3 -c 'import json,sys; d=json.loads(sys.argv[1]); print("%d frames, tip rms %.1f um" % (d["frames"], d["tip_rms_um"]))' "$eval_json")"
else
  fail "installed tracking_eval failed"
fi
check_trace tracking_eval "tracking_eval"

echo "install-test: $failures failure(s), $(awk "BEGIN{printf \"%.0f\", $(date +%s.%N) - $started}") s"
((failures == 0))
