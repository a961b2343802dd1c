#!/usr/bin/env bash
# The nftables rules of SECURITY.md, tested on two "hosts" (remote/two_hosts.sh: network namespaces A and B joined by
# a veth pair; the rules are loaded into A's namespace only, never into this machine's).
#  Standalone station (A with the defaults, ROS_HOSTNAME=localhost): without the rules B reaches the roscpp XML-RPC
#  server of A's rosout (the exposure SECURITY.md names) but not A's master; with the standalone rules B reaches
#  nothing of A, and A's own graph still works (rostopic list, the node's API over loopback).
#  Instructor segment (A with ROS_HOSTNAME = its segment address, the rules allowing the console host B): B lists
#  A's topics and receives a latched topic from A, A receives one from B; the same rules naming another console
#  address shut B out.
# Usage: security_firewall.sh   (root; SKIP when network namespaces or nft are not available; exit 0 = pass)
set -uo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)
export PATH="/usr/bin:/usr/sbin:/sbin:$PATH"
TWO="$ROOT/src/eyesi_gui/test/remote/two_hosts.sh"
NAME=fw$$
failures=0
check() {  # check NAME CONDITION-EXIT-STATUS DETAIL
  if [[ $2 -eq 0 ]]; then echo "PASS: $1"; else echo "FAIL: $1 ${3:-}"; failures=$((failures + 1)); fi
}
command -v nft >/dev/null || { echo "SKIP: nft not installed (apt install nftables)"; exit 0; }
eval "$(VRM_REMOTE_MODE=netns "$TWO" up "$NAME" 2>/dev/null)" || true
if [[ ${VRM_MODE:-} != netns ]]; then
  echo "SKIP: no network namespaces here (needs root / CAP_SYS_ADMIN)"
  "$TWO" down "$NAME" >/dev/null 2>&1
  exit 0
fi
trap '"$TWO" down "$NAME" >/dev/null 2>&1' EXIT
echo "remote-host mode: netns (A $VRM_A_IP $VRM_A_VETH, B $VRM_B_IP)"
A() { timeout 20 "$TWO" exec A "$NAME" -- "$@"; }
B() { timeout 20 "$TWO" exec B "$NAME" -- "$@"; }
in_A() { ip netns exec "$VRM_A_NETNS" "$@"; }
reach() {  # reach SIDE HOST PORT: exit 0 when a TCP connection opens within 2 s
  local side=$1
  shift
  "$side" python3 -c 'import socket, sys
try:
    socket.create_connection((sys.argv[1], int(sys.argv[2])), timeout=2).close()
except OSError:
    sys.exit(1)' "$@"
}
rules() {  # rules EXTRA-RULE: SECURITY.md's ruleset with the console line (or none)
  cat <<EOF
table inet vrm_station {
  chain input {
    type filter hook input priority filter; policy drop;
    iif "lo" accept
    ct state established,related accept
    ct state invalid drop
    meta l4proto { icmp, ipv6-icmp } accept
    $1
  }
}
EOF
}
wait_master() {  # wait_master SIDE URI
  for _ in $(seq 40); do "$1" env ROS_MASTER_URI="$2" rostopic list >/dev/null 2>&1 && return 0; sleep 0.25; done
  return 1
}
rosout_xmlrpc_port() {  # the roscpp XML-RPC port of A's rosout (from A's master)
  A env ROS_MASTER_URI="$1" python3 -c 'import sys, xmlrpc.client
from urllib.parse import urlparse
print(urlparse(xmlrpc.client.ServerProxy(sys.argv[1]).lookupNode("/fw", "/rosout")[2]).port)' "$1"
}

# --- Standalone station: the defaults (ROS_HOSTNAME=localhost) -------------------------------------------------------
LOCAL_URI=http://localhost:$VRM_PORT
"$TWO" spawn A "$NAME" "$VRM_STATE_DIR/core_local.log" -- env ROS_HOSTNAME=localhost ROS_MASTER_URI="$LOCAL_URI" \
  roscore -p "$VRM_PORT" >/dev/null
wait_master A "$LOCAL_URI"
check "A: master with ROS_HOSTNAME=localhost up" $?
port=$(rosout_xmlrpc_port "$LOCAL_URI")
! reach B "$VRM_A_IP" "$VRM_PORT"
check "no rules: B cannot reach A's master ($VRM_A_IP:$VRM_PORT, bound to loopback)" $?
reach B "$VRM_A_IP" "$port"
check "no rules: B reaches A's rosout XML-RPC ($VRM_A_IP:$port, xmlrpcpp on 0.0.0.0) — the exposure" $?
rules "" | in_A nft -f -
check "A: the standalone ruleset loads" $?
! reach B "$VRM_A_IP" "$port"
check "standalone rules: B no longer reaches A's rosout XML-RPC" $?
# Up to 10 s: rostopic is a Python start-up on a machine that may be busy (it once listed nothing in CI), and rules
# that broke loopback would fail every try.
listed=1
for _ in 1 2 3 4 5; do
  A env ROS_HOSTNAME=localhost ROS_MASTER_URI="$LOCAL_URI" timeout 5 rostopic list 2>/tmp/vrm_firewall_rostopic.err |
    grep -q "^/rosout$" && { listed=0; break; }
  sleep 1
done
check "standalone rules: A's graph still works over loopback (rostopic list)" $listed "$(tail -n 2 /tmp/vrm_firewall_rostopic.err)"
reach A 127.0.0.1 "$port"
check "standalone rules: A's own processes reach the node API over loopback" $?
in_A nft delete table inet vrm_station
"$TWO" down "$NAME" >/dev/null 2>&1
eval "$(VRM_REMOTE_MODE=netns "$TWO" up "$NAME")"

# --- Instructor console on a separate segment --------------------------------------------------------------------
"$TWO" spawn A "$NAME" "$VRM_STATE_DIR/core_segment.log" -- env ROS_HOSTNAME="$VRM_A_IP" roscore -p "$VRM_PORT" >/dev/null
wait_master A "$VRM_MASTER_URI"
check "A: master on the segment address $VRM_A_IP" $?
rules "iifname \"$VRM_A_VETH\" ip saddr $VRM_B_IP tcp dport 1024-65535 accept" | in_A nft -f -
check "A: the segment ruleset (console host $VRM_B_IP) loads" $?
"$TWO" spawn A "$NAME" "$VRM_STATE_DIR/pub_a.log" -- env ROS_HOSTNAME="$VRM_A_IP" \
  rostopic pub -l /from_station std_msgs/String "data: station" >/dev/null
"$TWO" spawn B "$NAME" "$VRM_STATE_DIR/pub_b.log" -- env ROS_HOSTNAME="$VRM_B_IP" \
  rostopic pub -l /from_console std_msgs/String "data: console" >/dev/null
listed=1
for _ in $(seq 30); do  # the publisher on A registers within a few seconds on a loaded machine
  if B env ROS_HOSTNAME="$VRM_B_IP" rostopic list 2>/dev/null | grep -q "^/from_station$"; then listed=0; break; fi
  sleep 0.5
done
((listed == 0))
check "segment rules: the console host B lists A's topics (master reachable)" $?
B env ROS_HOSTNAME="$VRM_B_IP" rostopic echo -n 1 /from_station 2>/dev/null | grep -q "station"
check "segment rules: B receives A's latched topic (TCPROS B -> A)" $?
A env ROS_HOSTNAME="$VRM_A_IP" rostopic echo -n 1 /from_console 2>/dev/null | grep -q "console"
check "segment rules: A receives B's topic (A -> B, replies as established)" $?
in_A nft delete table inet vrm_station
rules "iifname \"$VRM_A_VETH\" ip saddr 10.213.0.99 tcp dport 1024-65535 accept" | in_A nft -f -
! reach B "$VRM_A_IP" "$VRM_PORT"
check "segment rules naming another console address: B cannot reach A's master" $?

if ((failures == 0)); then echo "security_firewall: PASS"; exit 0; fi
echo "security_firewall: FAIL ($failures failed)"
exit 1
