#!/usr/bin/env bash
# The defaults SECURITY.md claims, tested on this host:
#  1. Network: the product graph as shipped (launch/simulator.launch headless, recording, tracking, its own master
#     port, the scripts' ROS_HOSTNAME=localhost) — `ss` lists every listening socket of the launch's processes. The
#     master's XML-RPC, roslaunch's server, every TCPROS server and every UDP socket listen on loopback only; the
#     only sockets on a non-loopback address are the roscpp nodes' XML-RPC slave servers (each one a node URI the
#     master knows; xmlrpcpp binds INADDR_ANY whatever ROS_HOSTNAME says — SECURITY.md, "What does not hold"):
#     printed as KNOWN, and a FAIL with --strict. A non-loopback address of this host (if it has one) cannot reach
#     the master or a TCPROS port.
#  2. Records: the `records` tool (the console's store) creates the database 0600 in a 0700 folder, its -wal and
#     -shm files 0600 while a connection is open, the PIN is stored only as a salted PBKDF2 hash (no plain PIN in
#     the file or its WAL; 16-byte salt, 32-byte hash, >= 100000 iterations, different salts for equal PINs).
#  3. The session station creates its records folder (bags, results, logs) 0700.
# Usage: security_defaults.sh [--strict] [OUT_DIR]   (exit 0 = every check passed; OUT_DIR kept on failure)
set -uo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)
export PATH="/usr/bin:$PATH"
strict=0
[[ ${1:-} == --strict ]] && { strict=1; shift; }
# shellcheck disable=SC1091
source "$ROOT/scripts/common.sh"
OUT=${1:-$(mktemp -d /tmp/eyesi_security.XXXXXX)}
mkdir -p "$OUT"
PORT=$((11850 + $$ % 60))
export ROS_MASTER_URI=http://localhost:$PORT ROS_LOG_DIR="$OUT/ros_log"
failures=0
check() {  # check NAME CONDITION-EXIT-STATUS DETAIL
  if [[ $2 -eq 0 ]]; then echo "PASS: $1"; else echo "FAIL: $1 ${3:-}"; failures=$((failures + 1)); fi
}
mode() { stat -c %a "$1" 2>/dev/null || echo missing; }
echo "security_defaults: ROS_HOSTNAME=${ROS_HOSTNAME:-} ROS_IP=${ROS_IP:-} master port $PORT, output $OUT"

# --- 1. Network -------------------------------------------------------------------------------------------------
setsid roslaunch -p "$PORT" "$ROOT/launch/simulator.launch" headless:=true sim:=true tracking:=true record:=true \
  duration:=0 bag:="$OUT/session.bag" >"$OUT/launch.log" 2>&1 &
launch=$!
descendants() {  # every process under roslaunch (supervisors' children too)
  local pids=("$launch") i=0
  while ((i < ${#pids[@]})); do
    read -ra kids <<<"$(cat "/proc/${pids[i]}/task/${pids[i]}/children" 2>/dev/null)"
    pids+=("${kids[@]}")
    i=$((i + 1))
  done
  echo "${pids[@]}"
}
# Up = every node of the launch registered with the master (session_control comes last) and frames simulated.
up=1
for _ in $(seq 120); do
  if rostopic list 2>/dev/null | grep -q "^/simulation_state$" && rosnode list 2>/dev/null | grep -q "^/session_control$" &&
    timeout 5 rostopic echo -n 1 /simulation_state/frame >/dev/null 2>&1; then
    up=0
    break
  fi
  kill -0 "$launch" 2>/dev/null || break
  sleep 1
done
check "the product graph came up on its own master (port $PORT)" $up "(see $OUT/launch.log)"
sleep 2
read -ra pids <<<"$(descendants)"
pid_pattern=$(IFS='|'; echo "${pids[*]}")
ss -Hltnp | grep -E "pid=($pid_pattern)," >"$OUT/tcp_listen.txt"
ss -Hlunp | grep -E "pid=($pid_pattern)," >"$OUT/udp.txt"
# The XML-RPC URI (port) of every node, from the master.
python3 - "$ROS_MASTER_URI" >"$OUT/node_uris.txt" <<'PY'
import sys, xmlrpc.client
from urllib.parse import urlparse
master = xmlrpc.client.ServerProxy(sys.argv[1])
_, _, state = master.getSystemState("/security_defaults")
nodes = sorted({n for group in state for _, names in group for n in names})
for node in nodes:
    code, _, uri = master.lookupNode("/security_defaults", node)
    if code == 1:
        print(node, urlparse(uri).port)
PY
nodes=$(wc -l <"$OUT/node_uris.txt")
((nodes > 0))
check "the master lists the graph's nodes ($nodes nodes)" $?
address_of() { awk '{print $4}'; }
loopback() { grep -qE '^(127\.[0-9.]+|\[::1\]|\[::ffff:127\.[0-9.]+\]):[0-9]+$' <<<"$1"; }
master_lines=$(awk -v p=":$PORT" '$4 ~ p"$"' "$OUT/tcp_listen.txt")
where=$(address_of <<<"$master_lines" | paste -sd' ')
[[ -n $master_lines ]] && ! grep -vqE '^\S+\s+\S+\s+\S+\s+(127\.[0-9.]+|\[::1\]):' <<<"$master_lines"
check "the master's XML-RPC listens on loopback only: $where" $?
launch_lines=$(grep "pid=$launch," "$OUT/tcp_listen.txt")
where=$(address_of <<<"$launch_lines" | paste -sd' ')
[[ -n $launch_lines ]] && ! grep -vqE '^\S+\s+\S+\s+\S+\s+(127\.[0-9.]+|\[::1\]):' <<<"$launch_lines"
check "roslaunch's XML-RPC server listens on loopback only: $where" $?
node_ports=" $(awk '{print $2}' "$OUT/node_uris.txt" | paste -sd' ') "
tcpros=0 tcpros_sample="" tcpros_exposed=() xmlrpc_loopback=0 xmlrpc_exposed=()
while read -r line; do
  local_address=$(awk '{print $4}' <<<"$line")
  port=${local_address##*:}
  process=$(grep -oE 'users:\(\("[^"]+",pid=[0-9]+' <<<"$line" | sed -E 's/users:\(\("//; s/",pid=/ /')
  [[ $port == "$PORT" || $line == *"pid=$launch,"* ]] && continue
  if [[ $node_ports == *" $port "* ]]; then
    if loopback "$local_address"; then xmlrpc_loopback=$((xmlrpc_loopback + 1)); else xmlrpc_exposed+=("$process@$local_address"); fi
  else
    tcpros=$((tcpros + 1))
    loopback "$local_address" || tcpros_exposed+=("$process@$local_address")
    [[ -n $tcpros_sample ]] || tcpros_sample=$port
  fi
done <"$OUT/tcp_listen.txt"
((tcpros > 0 && ${#tcpros_exposed[@]} == 0))
check "every TCPROS server listens on loopback only ($tcpros sockets)" $? "(exposed: ${tcpros_exposed[*]:-})"
udp_exposed=$(awk '{print $4}' "$OUT/udp.txt" | grep -vcE '^(127\.[0-9.]+|\[::1\]):' || true)
udp=$(wc -l <"$OUT/udp.txt")
[[ $udp_exposed -eq 0 ]]
check "every UDP socket of the graph is bound to loopback ($udp sockets)" $?
if ((${#xmlrpc_exposed[@]})); then
  if ((strict)); then
    check "no node XML-RPC server listens on a non-loopback address" 1 "(${#xmlrpc_exposed[@]}: ${xmlrpc_exposed[*]})"
  else
    echo "KNOWN: ${#xmlrpc_exposed[@]} roscpp XML-RPC slave servers listen on a non-loopback address (xmlrpcpp binds" \
      "INADDR_ANY; SECURITY.md: firewall them): ${xmlrpc_exposed[*]}"
  fi
fi
echo "  node XML-RPC servers on loopback: $xmlrpc_loopback, on every address: ${#xmlrpc_exposed[@]}"
# From a non-loopback address of this host (what another host on that network would reach, firewall aside).
external=$(ip -4 -o addr show scope global 2>/dev/null | awk '{print $4}' | cut -d/ -f1 | head -1)
if [[ -n $external ]]; then
  python3 - "$external" "$PORT" "$tcpros_sample" <<'PY'
import socket, sys
host, master, tcpros = sys.argv[1], int(sys.argv[2]), int(sys.argv[3] or 0)
ok = True
for name, port in (("master", master), ("a TCPROS server", tcpros)):
    if not port:
        continue
    try:
        socket.create_connection((host, port), timeout=2).close()
        print(f"FAIL: {name} is reachable at {host}:{port}"); ok = False
    except OSError as error:
        print(f"PASS: {name} is not reachable at {host}:{port} ({error.strerror})")
sys.exit(0 if ok else 1)
PY
  (($? == 0)) || failures=$((failures + 1))
else
  echo "  (no non-loopback IPv4 address on this host: reachability not tried)"
fi
kill -INT "$launch" 2>/dev/null
for _ in $(seq 60); do kill -0 "$launch" 2>/dev/null || break; sleep 0.5; done
kill -0 "$launch" 2>/dev/null && kill -TERM "$launch"
wait "$launch" 2>/dev/null

# --- 2. Records ---------------------------------------------------------------------------------------------------
DB="$OUT/records/private/records.sqlite"
PIN=918273
RECORDS_TOOL=${RECORDS_TOOL:-$(catkin_find --first-only eyesi_gui records)}  # override: another build's tool
(umask 022 && "$RECORDS_TOOL" --db "$DB" add-user "Trainee One" --role trainee --pin "$PIN" >/dev/null &&
  "$RECORDS_TOOL" --db "$DB" add-user "Dr. Two" --role instructor --pin "$PIN" >/dev/null)
check "the records tool created a database with two users" $?
db_mode=$(mode "$DB") folder_modes="$(mode "$OUT/records") $(mode "$OUT/records/private")"
[[ $db_mode == 600 ]]
check "the records database is 0600 (umask 022): $db_mode" $?
[[ $folder_modes == "700 700" ]]
check "the folders the store created are 0700: $folder_modes" $?
# A connection held open (as the console holds one): SQLite creates the WAL and the shared-memory index.
python3 - "$DB" "$PIN" <<'PY'
import os, sqlite3, stat, sys
path, pin = sys.argv[1], sys.argv[2].encode()
os.umask(0o022)
db = sqlite3.connect(path)
db.execute("BEGIN IMMEDIATE"); db.execute("UPDATE users SET created_at = created_at"); db.commit()
ok = True
for suffix in ("-wal", "-shm"):
    mode = stat.S_IMODE(os.stat(path + suffix).st_mode) if os.path.exists(path + suffix) else None
    good = mode == 0o600
    print(f"{'PASS' if good else 'FAIL'}: the database's {suffix} file is 0600 while open: "
          f"{oct(mode) if mode is not None else 'missing'}")
    ok &= good
rows = db.execute("SELECT name, length(pin_salt), length(pin_hash), iterations, pin_salt FROM users "
                  "WHERE name != 'guest' ORDER BY name").fetchall()
good = len(rows) == 2 and all(r[1] == 16 and r[2] == 32 and r[3] >= 100000 for r in rows) and rows[0][4] != rows[1][4]
print(f"{'PASS' if good else 'FAIL'}: PINs stored as salted PBKDF2 hashes "
      f"({', '.join(f'{r[0]}: salt {r[1]} B, hash {r[2]} B, {r[3]} iterations' for r in rows)}; salts differ)")
ok &= good
found = [name for name in (path, path + "-wal") if os.path.exists(name) and pin in open(name, "rb").read()]
print(f"{'PASS' if not found else 'FAIL'}: the plain PIN is in neither the database nor its WAL"
      f"{' (found in ' + ', '.join(found) + ')' if found else ''}")
ok &= not found
db.close()
sys.exit(0 if ok else 1)
PY
(($? == 0)) || failures=$((failures + 1))

# --- 3. The session station's records folder ----------------------------------------------------------------------
STATION_DIR="$OUT/station/sessions"
setsid roslaunch -p "$PORT" --core >"$OUT/core.log" 2>&1 &
core=$!
for _ in $(seq 30); do rostopic list >/dev/null 2>&1 && break; sleep 0.5; done
(umask 022 && exec rosrun eyesi_gui session_station __name:=station_probe _records_dir:="$STATION_DIR" \
  _simulator_launch:="$ROOT/launch/simulator.launch" >"$OUT/station.log" 2>&1) &
station=$!
for _ in $(seq 40); do [[ -d $STATION_DIR ]] && break; sleep 0.25; done
folder_modes="$(mode "$OUT/station") $(mode "$STATION_DIR")"
[[ $folder_modes == "700 700" ]]
check "the session station creates its records folder 0700: $folder_modes" $?
kill -INT "$station" 2>/dev/null
wait "$station" 2>/dev/null
kill -INT "$core" 2>/dev/null
wait "$core" 2>/dev/null

if ((failures == 0)); then
  echo "security_defaults: PASS"
  [[ $# -eq 0 ]] && rm -rf "$OUT"
  exit 0
fi
echo "security_defaults: FAIL ($failures failed; kept $OUT)"
exit 1
