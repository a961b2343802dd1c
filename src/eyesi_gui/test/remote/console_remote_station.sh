#!/usr/bin/env bash
# The remote station: the console on a second ROS host against the simulator's master. Host A (the simulator) runs
# roscore and the session_station (which launches the session graph under A's master); host B (the console station)
# runs the console (eyesi_gui, Qt offscreen) in autopilot mode with its own training records. Hosts are network
# namespaces joined by a veth pair, or two loopback addresses (two_hosts.sh; VRM_REMOTE_MODE=loopback forces that).
# Checks: the console ran the session by its own buttons and stored the result in B's database (score items, user,
# bag path on A), A closed the bag and wrote the result file whose final state hash equals B's, the console's
# connections really ran between the two addresses (and, in netns mode, the stereo images crossed the veth), and
# nothing is left behind after teardown.
# Prints PASS/FAIL lines; exit 0 iff all pass. Bounded by VRM_TEST_TIMEOUT seconds (default 300).
# Output in a temporary folder: deleted on success, kept (and named) on failure.
set -u -o pipefail
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../../../.." && pwd)"
TH="$HERE/two_hosts.sh"

# Overall time bound: re-run this script under `timeout` (its EXIT trap still tears down).
if [[ -z "${VRM_TEST_INNER:-}" ]]; then
  VRM_TEST_INNER=1 exec timeout -k 15 "${VRM_TEST_TIMEOUT:-300}" "$0" "$@"
fi

START_S=$SECONDS
OUT=$(mktemp -d /tmp/eyesi_remote.XXXXXX)
mkdir -p "$OUT/A/sessions" "$OUT/A/ros_log" "$OUT/B/ros_log" "$OUT/B/shots" "$OUT/B/xdg"
chmod 700 "$OUT/B/xdg"
export VRM_STATE_ROOT="$OUT/state"
NAME="remote-$$"
SCENE=membrane_peeling
USER_NAME="Dr. Anna Weber"
PIN=2468
DB="$OUT/B/records.sqlite"
RECORDS="$OUT/A/sessions"
FAILS=0
CONSOLE_PID=""
pass() { echo "PASS: $*"; }
fail() { echo "FAIL: $*"; FAILS=$((FAILS + 1)); }
show_log() { echo "  ----- $1 (last ${2:-15} lines)"; tail -n "${2:-15}" "$1" 2>/dev/null | sed 's/^/  | /'; }

# shellcheck disable=SC2317  # invoked by trap
cleanup() {
  trap - EXIT
  [[ -n "$CONSOLE_PID" ]] && kill -TERM "$CONSOLE_PID" 2>/dev/null
  "$TH" down "$NAME" >/dev/null 2>&1
  if ((FAILS == 0)) && [[ "${DONE:-0}" == 1 ]]; then
    rm -rf "$OUT"
  else
    echo "console_remote_station: output kept in $OUT"
  fi
}
trap cleanup EXIT
trap 'echo "FAIL: interrupted or timed out after $((SECONDS - START_S)) s"; FAILS=$((FAILS + 1)); exit 124' TERM INT HUP

# A port nothing listens on here (matters in loopback mode; in netns mode A's stack is fresh).
port_free() { ! ss -Hltn "sport = :$1" 2>/dev/null | grep -q .; }
PORT=$((11900 + $$ % 50))
for ((i = 0; i < 50; i++)); do port_free "$PORT" && break; PORT=$((11900 + (PORT - 11900 + 1) % 100)); done

UP_OUT=$("$TH" up "$NAME" "$PORT") || { fail "two_hosts.sh up"; exit 1; }
eval "$UP_OUT"
echo "remote-host mode: $VRM_MODE"
echo "  A (simulator) = $VRM_A_IP, B (console) = $VRM_B_IP, ROS_MASTER_URI=$VRM_MASTER_URI, output in $OUT"

onA() { local t=$1; shift; timeout -k 5 "$t" "$TH" exec A "$NAME" -- env ROS_LOG_DIR="$OUT/A/ros_log" "$@"; }  # onA SECONDS CMD...
onB() { local t=$1; shift; timeout -k 5 "$t" "$TH" exec B "$NAME" -- env ROS_LOG_DIR="$OUT/B/ros_log" "$@"; }
veth_bytes() {  # rx tx of B's veth end
  local d="/sys/class/net/$VRM_B_VETH/statistics"
  timeout 5 ip netns exec "$VRM_B_NETNS" cat "$d/rx_bytes" "$d/tx_bytes" 2>/dev/null | tr '\n' ' '
}

# --- host A: master and station
"$TH" spawn A "$NAME" "$OUT/A/roscore.log" -- env ROS_LOG_DIR="$OUT/A/ros_log" roscore -p "$PORT" >/dev/null
"$TH" spawn A "$NAME" "$OUT/A/station.log" -- env ROS_LOG_DIR="$OUT/A/ros_log" \
  rosrun eyesi_gui session_station __name:=station _simulator_launch:="$ROOT/launch/simulator.launch" \
  _replay_launch:="$ROOT/launch/replay.launch" _records_dir:="$RECORDS" \
  _launch_args:="sim:=true tracking:=false" _script:=scenario:expert >/dev/null

# The station's scene library, asked from B (the console's way to it): polls, no fixed wait.
station_up=0
for ((i = 0; i < 120; i++)); do   # each call takes ~0.5 s; bound ~60 s
  if onB 10 rosservice call /station/list_scenes >"$OUT/B/list_scenes.out" 2>&1 &&
     grep -q "$SCENE" "$OUT/B/list_scenes.out"; then station_up=1; break; fi
  sleep 0.2
done
if ((station_up)); then
  pass "station on A answers /station/list_scenes from B ($SCENE offered) after $((SECONDS - START_S)) s"
else
  fail "station on A not reachable from B"
  show_log "$OUT/B/list_scenes.out" 5; show_log "$OUT/A/roscore.log"; show_log "$OUT/A/station.log"
  exit 1
fi

# --- host B: the console's own records with an instructor, then the console in autopilot mode
if ! onB 30 rosrun eyesi_gui records --db "$DB" add-user "$USER_NAME" --role instructor --pin "$PIN" \
     >"$OUT/B/add_user.log" 2>&1; then
  fail "records add-user on B"; show_log "$OUT/B/add_user.log"; exit 1
fi

[[ $VRM_MODE == netns ]] && read -r RX0 TX0 <<<"$(veth_bytes)"
timeout -k 10 240 "$TH" exec B "$NAME" -- env ROS_LOG_DIR="$OUT/B/ros_log" QT_QPA_PLATFORM=offscreen \
  XDG_RUNTIME_DIR="$OUT/B/xdg" \
  rosrun eyesi_gui eyesi_gui __name:=console _station:=/station \
  --database "$DB" --autopilot "$SCENE" --user "$USER_NAME" --pin "$PIN" --timeout 200 \
  --screenshots "$OUT/B/shots" >"$OUT/B/console.log" 2>&1 </dev/null &
CONSOLE_PID=$!

# While the console runs: A's view of it (its URI, its inbound stereo connection from A's session graph).
seen_info=0
while kill -0 "$CONSOLE_PID" 2>/dev/null; do
  if ((!seen_info)); then
    onA 10 rosnode info /console >"$OUT/A/rosnode_info.tmp" 2>&1
    if grep -q "contacting node http://$VRM_B_IP:" "$OUT/A/rosnode_info.tmp" &&
       sed -n '/^Connections:/,$p' "$OUT/A/rosnode_info.tmp" | grep -A3 'topic: /stereo/left/image_raw' |
         grep -q "direction: inbound (.* - $VRM_A_IP:"; then
      seen_info=1
    fi
    mv "$OUT/A/rosnode_info.tmp" "$OUT/A/rosnode_info.out"
  fi
  sleep 0.5
done
wait "$CONSOLE_PID"; console_rc=$?
CONSOLE_PID=""
[[ $VRM_MODE == netns ]] && read -r RX1 TX1 <<<"$(veth_bytes)"
echo "  console finished (exit $console_rc) after $((SECONDS - START_S)) s"

# --- checks
stored=$(grep -o "autopilot: session [1-9][0-9]* stored" "$OUT/B/console.log" | head -1)
if [[ $console_rc -eq 0 && -n $stored ]]; then
  pass "console on B exited 0: '$stored'"
else
  fail "console on B: exit $console_rc, '${stored:-no stored line}'"; show_log "$OUT/B/console.log" 25
fi
grep "console:" "$OUT/B/console.log" | sed 's/^/  /' | tail -n 12

if ((seen_info)); then
  pass "rosnode info /console on A: URI at B (http://$VRM_B_IP:...), /stereo/left/image_raw inbound from A ($VRM_A_IP)"
else
  fail "rosnode info /console on A never showed B's URI with an inbound stereo connection"
  show_log "$OUT/A/rosnode_info.out" 30
fi
{ grep 'contacting node' "$OUT/A/rosnode_info.out"
  sed -n '/^Connections:/,$p' "$OUT/A/rosnode_info.out" | grep -A3 'topic: /stereo/' | grep -E 'topic:|to:|direction:'
} 2>/dev/null | head -7 | sed 's/^ */  /'

rows=$(onB 30 rosrun eyesi_gui records --db "$DB" export-csv --user "$USER_NAME" --scene "$SCENE" 2>"$OUT/B/export.err" |
  tee "$OUT/B/export.csv" | tail -n +2 | wc -l)
if ((rows >= 5)); then
  pass "B's database: $rows score items of '$USER_NAME' / $SCENE (records export-csv)"
else
  fail "B's database: $rows score item rows"; show_log "$OUT/B/export.csv" 10; show_log "$OUT/B/export.err" 5
fi

# The session row (records list/export do not show the hash): sqlite3 CLI, else python3's sqlite3. '|'-separated:
# a tab is IFS whitespace for `read`, which would merge the empty result_path into its neighbours.
query="SELECT u.name, s.bag_path, s.result_path, s.final_state_hash, s.station FROM sessions s JOIN users u ON u.id = s.user_id WHERE s.scene = '$SCENE' ORDER BY s.id DESC LIMIT 1"
if command -v sqlite3 >/dev/null; then
  row=$(sqlite3 -separator '|' "file:$DB?mode=ro" "$query" 2>&1)
else
  row=$(/usr/bin/python3 - "$DB" "$query" <<'PY' 2>&1
import sqlite3, sys
con = sqlite3.connect("file:%s?mode=ro" % sys.argv[1], uri=True)
for r in con.execute(sys.argv[2]):
    print("|".join(str(v) for v in r))
PY
)
fi
IFS='|' read -r db_user db_bag db_result db_hash db_station <<<"$row"
echo "  B's session row: user '$db_user', station '$db_station', bag $db_bag, hash ${db_hash:-?}"
if [[ $db_user == "$USER_NAME" && $db_bag == "$RECORDS"/*.bag && -n $db_hash && -n $db_station ]]; then
  pass "B's session row: user as logged in, bag path in A's records dir, station '$db_station'"
else
  fail "B's session row: '$row'"
fi

bags=("$RECORDS"/*.bag)
active=("$RECORDS"/*.bag.active)
if [[ -f ${bags[0]} && ${#bags[@]} -eq 1 && ! -e ${active[0]} && ${bags[0]} == "$db_bag" ]]; then
  pass "A's records dir holds the closed bag $(basename "${bags[0]}") ($(stat -c %s "${bags[0]}") bytes, no .bag.active)"
else
  fail "A's bags: ${bags[*]} active: ${active[*]} (B's row names '$db_bag')"; ls -la "$RECORDS" | sed 's/^/  /'
fi
result_json="${db_bag%.bag}.result.json"
a_hash=$(/usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['final_state_hash'])" \
  "$result_json" 2>/dev/null)
if [[ -n $a_hash && $a_hash == "$db_hash" ]]; then
  pass "A's $(basename "$result_json") final_state_hash equals B's database ($a_hash)"
else
  fail "final state hash: A '${a_hash:-none}' ($result_json) vs B '${db_hash:-none}'"
fi

if [[ $VRM_MODE == netns ]]; then
  rx=$((${RX1:-0} - ${RX0:-0})); tx=$((${TX1:-0} - ${TX0:-0}))
  if ((rx > 100000 && tx > 0)); then
    pass "B's veth $VRM_B_VETH: received $rx bytes, sent $tx bytes during the console's session"
  else
    fail "B's veth counters: rx +$rx, tx +$tx (expected rx > 100000)"
  fi
fi

# --- teardown leaves nothing behind
"$TH" down "$NAME" >/dev/null 2>&1
left=""
if [[ $VRM_MODE == netns ]]; then
  left+=$(ip netns list 2>/dev/null | awk '{print $1}' | grep -xE "$VRM_A_NETNS|$VRM_B_NETNS" | tr '\n' ' ')
  left+=$(ip -o link show 2>/dev/null | grep -oE "$VRM_A_VETH|$VRM_B_VETH" | tr '\n' ' ')
fi
[[ -d "$VRM_STATE_DIR" ]] && left+=" state:$VRM_STATE_DIR"
procs=$(pgrep -f -- "$OUT" | tr '\n' ' ')
[[ -n $procs ]] && left+=" processes:$procs($(ps -o comm= -p "${procs// /,}" 2>/dev/null | tr '\n' ' '))"
pgrep -f "rosmaster --core -p $PORT( |\$)" >/dev/null && left+=" rosmaster on $PORT"
port_free "$PORT" || left+=" port $PORT listening"
if [[ -z "$left" ]]; then
  pass "down left nothing behind (namespaces, veths, processes, state)"
else
  fail "leftovers after down: $left"
fi

DONE=1
if ((FAILS)); then
  echo "console_remote_station: $FAILS FAILED ($VRM_MODE, $((SECONDS - START_S)) s)"
  exit 1
fi
echo "console_remote_station: PASS ($VRM_MODE, $((SECONDS - START_S)) s)"
exit 0
