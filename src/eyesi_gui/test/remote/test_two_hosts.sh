#!/usr/bin/env bash
# Self-test of two_hosts.sh: a ROS master on host A, a console on host B, traffic both ways,
# isolation (netns mode), and a clean teardown. Prints PASS/FAIL/SKIP lines; exit 0 iff no FAIL.
# Bounded by VRM_TEST_TIMEOUT seconds (default 60). VRM_REMOTE_MODE=loopback forces the fallback.
set -u -o pipefail
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
TH="$HERE/two_hosts.sh"

# Overall time bound: re-run this script under `timeout` (its EXIT trap still tears down).
if [[ -z "${VRM_TEST_INNER:-}" ]]; then
  VRM_TEST_INNER=1 exec timeout -k 10 "${VRM_TEST_TIMEOUT:-60}" "$0" "$@"
fi

NAME="selftest-$$"
FAILS=0
pass() { echo "PASS: $*"; }
fail() { echo "FAIL: $*"; FAILS=$((FAILS + 1)); }
skip() { echo "SKIP: $*"; }

# shellcheck disable=SC2317  # invoked by trap
cleanup() {
  trap - EXIT
  "$TH" down "$NAME" >/dev/null 2>&1
}
trap cleanup EXIT
trap 'echo "FAIL: interrupted or timed out"; exit 124' TERM INT HUP

# A port nothing listens on here (matters in loopback mode; in netns mode A's stack is fresh).
port_free() { ! ss -Hltn "sport = :$1" 2>/dev/null | grep -q .; }
PORT=$((11900 + $$ % 50))
for ((i = 0; i < 50; i++)); do port_free "$PORT" && break; PORT=$((11900 + (PORT - 11900 + 1) % 100)); done

UP_OUT=$("$TH" up "$NAME" "$PORT") || { fail "two_hosts.sh up"; exit 1; }
eval "$UP_OUT"
echo "remote-host mode: $VRM_MODE"
echo "  A=$VRM_A_IP B=$VRM_B_IP ROS_MASTER_URI=$VRM_MASTER_URI"
LOG="$VRM_STATE_DIR/log"

show_log() { echo "----- $1"; tail -n 20 "$1" 2>/dev/null | sed 's/^/  | /'; }

# --- environment seen by each side
envA=$(timeout 10 "$TH" exec A "$NAME" -- env)
envB=$(timeout 10 "$TH" exec B "$NAME" -- env)
if grep -qx "ROS_IP=$VRM_A_IP" <<<"$envA" && grep -qx "ROS_IP=$VRM_B_IP" <<<"$envB" &&
   grep -qx "ROS_MASTER_URI=$VRM_MASTER_URI" <<<"$envB" &&
   ! grep -q '^ROS_HOSTNAME=' <<<"$envA$envB"; then
  pass "side env: ROS_IP per side, ROS_MASTER_URI=$VRM_MASTER_URI, ROS_HOSTNAME unset"
else
  fail "side env"; grep '^ROS_' <<<"$envB"
fi
if timeout 10 "$TH" exec B "$NAME" -- bash -c 'command -v roscore && command -v rostopic && command -v rosservice' >/dev/null; then
  pass "roscore/rostopic/rosservice on PATH inside a side"
else
  fail "ROS tools not on PATH inside a side"
fi

# --- master on A
"$TH" spawn A "$NAME" "$LOG/roscore.out" -- roscore -p "$PORT" >/dev/null
master_up=0
for ((i = 0; i < 100; i++)); do   # <= ~30 s incl. rostopic start-up
  if timeout 5 "$TH" exec B "$NAME" -- rostopic list 2>/dev/null | grep -qx /rosout; then master_up=1; break; fi
  sleep 0.2
done
if ((master_up)); then
  pass "master on A reachable from B at $VRM_MASTER_URI (rostopic list shows /rosout)"
else
  fail "master on A not reachable from B"; show_log "$LOG/roscore.out"
fi

if ((master_up)); then
  # --- topic: latched publisher on B, subscriber on A (A's TCPROS connects to B's ROS_IP)
  MSG="hello-from-B-$$"
  "$TH" spawn B "$NAME" "$LOG/pub_B.out" -- rostopic pub -l /vrm_selftest std_msgs/String "data: '$MSG'" >/dev/null
  echo_out=$(timeout 20 "$TH" exec A "$NAME" -- rostopic echo -n 1 /vrm_selftest 2>&1)
  if grep -q "$MSG" <<<"$echo_out"; then
    pass "topic B->A: 'rostopic echo -n 1' on A received '$MSG' published on B"
  else
    fail "topic B->A: got: $echo_out"; show_log "$LOG/pub_B.out"
  fi
  info=$(timeout 10 "$TH" exec A "$NAME" -- rostopic info /vrm_selftest 2>&1)
  if grep -q "http://$VRM_B_IP:" <<<"$info"; then
    pass "publisher registered with B's address (http://$VRM_B_IP:...)"
  else
    fail "publisher URI is not on B's address: $info"
  fi

  # --- service: rosout's get_loggers (a roscpp service on A) called from B
  srv_out=$(timeout 15 "$TH" exec B "$NAME" -- rosservice call /rosout/get_loggers 2>&1)
  if grep -q 'ros.rosout' <<<"$srv_out" || grep -q 'loggers:' <<<"$srv_out"; then
    pass "service A<-B: 'rosservice call /rosout/get_loggers' from B answered by A"
  else
    fail "service call from B: $srv_out"
  fi
  srv_uri=$(timeout 10 "$TH" exec B "$NAME" -- rosservice uri /rosout/get_loggers 2>&1)
  if grep -q "rosrpc://$VRM_A_IP:" <<<"$srv_uri"; then
    pass "service served at A's address ($srv_uri)"
  else
    fail "service URI not on A's address: $srv_uri"
  fi

  # --- parameter server: set from B, read on A
  timeout 10 "$TH" exec B "$NAME" -- rosparam set /vrm_selftest_param "$MSG" >/dev/null 2>&1
  p=$(timeout 10 "$TH" exec A "$NAME" -- rosparam get /vrm_selftest_param 2>&1)
  if [[ "$p" == "$MSG" ]]; then pass "param set on B, read on A"; else fail "param: got '$p'"; fi
fi

# --- isolation (netns only)
if [[ $VRM_MODE == netns ]]; then
  routes=$(timeout 5 ip -n "$VRM_B_NETNS" -4 route show 2>&1)
  if [[ -n "$routes" ]] && ! grep -v "^10\.213\.0\.0/30 dev $VRM_B_VETH " <<<"$routes" | grep -q .; then
    pass "B's only route is the veth subnet: $routes"
  else
    fail "B's routes: $routes"
  fi
  # The master is not reachable through B's own loopback, nor is the host's usual master.
  if ! timeout 3 "$TH" exec B "$NAME" -- bash -c "exec 3<>/dev/tcp/127.0.0.1/$PORT" 2>/dev/null &&
     ! timeout 3 "$TH" exec B "$NAME" -- bash -c 'exec 3<>/dev/tcp/127.0.0.1/11311' 2>/dev/null; then
    pass "from B, 127.0.0.1:$PORT and 127.0.0.1:11311 are unreachable (B reaches A only via the veth)"
  else
    fail "B reaches something on its loopback"
  fi
  if ! timeout 10 "$TH" exec B "$NAME" -- bash -c 'ROS_MASTER_URI=http://127.0.0.1:11311 rostopic list' >/dev/null 2>&1; then
    pass "from B, no master at the host's default http://127.0.0.1:11311"
  else
    fail "from B, a master answers at 127.0.0.1:11311"
  fi
  # A host address outside the pair (e.g. eth0's) must be unroutable from B.
  hostip=$(ip -4 -o addr show scope global 2>/dev/null | awk '{sub("/.*","",$4); print $4; exit}')
  if [[ -n "$hostip" ]]; then
    err=$(timeout 3 "$TH" exec B "$NAME" -- bash -c "exec 3<>/dev/tcp/$hostip/22" 2>&1)
    if grep -qi 'unreachable' <<<"$err"; then
      pass "from B, host address $hostip is unreachable (network unreachable)"
    else
      fail "from B, host address $hostip: $err"
    fi
  fi
  tx=$(timeout 5 ip netns exec "$VRM_B_NETNS" cat "/sys/class/net/$VRM_B_VETH/statistics/tx_bytes" 2>/dev/null)
  if [[ "$tx" =~ ^[0-9]+$ ]] && ((tx > 0)); then
    pass "traffic crossed the veth ($tx bytes sent by B)"
  else
    fail "veth TX counter of B: '${tx:-?}'"
  fi
else
  skip "isolation checks (loopback mode: both sides share the host's network stack)"
fi

# --- teardown leaves nothing behind
"$TH" down "$NAME" >/dev/null 2>&1
"$TH" down "$NAME" >/dev/null 2>&1 || fail "second down not idempotent"
left=""
if [[ $VRM_MODE == netns ]]; then
  left=$(ip netns list 2>/dev/null | awk '{print $1}' | grep -xE "$VRM_A_NETNS|$VRM_B_NETNS")
  left+=$(ip -o link show 2>/dev/null | grep -E "$VRM_A_VETH|$VRM_B_VETH")
fi
[[ -d "$VRM_STATE_DIR" ]] && left+=" state:$VRM_STATE_DIR"
if ss -Hltn "sport = :$PORT" 2>/dev/null | grep -q .; then left+=" port $PORT still listening"; fi
if pgrep -f "rosmaster --core -p $PORT( |\$)" >/dev/null; then left+=" rosmaster still running"; fi
if [[ -z "$left" ]]; then
  pass "down removed everything (namespaces, veths, processes, state)"
else
  fail "leftovers after down: $left"
fi

if ((FAILS)); then echo "RESULT: FAIL ($FAILS)"; exit 1; fi
echo "RESULT: PASS"
exit 0
