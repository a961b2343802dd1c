#!/usr/bin/env bash
# two_hosts.sh — run a ROS 1 graph on two "hosts" for tests.
#
#   host A (simulator: roscore + nodes)   host B (operator console)
#
# Mode "netns" (preferred, needs root / CAP_SYS_ADMIN): two network namespaces
#   vrmA-NAME (10.213.0.1/30) and vrmB-NAME (10.213.0.2/30) joined by a veth pair
#   vrm<hash>A <-> vrm<hash>B, `lo` up in each. Both veth ends live inside the
#   namespaces, so the host's interfaces are untouched and the only route of each
#   side is the /30 to the other side.
# Mode "loopback" (fallback): A = 127.0.0.1, B = 127.0.0.2, separate ROS_IP only.
#   Chosen when namespaces cannot be created, or forced with VRM_REMOTE_MODE=loopback.
#
# Usage (CLI):
#   two_hosts.sh up NAME [PORT]            create the pair; prints VAR=value lines (eval-able)
#   two_hosts.sh env A|B NAME              print the side's ROS env (export/unset lines)
#   two_hosts.sh exec A|B NAME -- CMD...   run CMD on a side (foreground; wrap it in `timeout`)
#   two_hosts.sh spawn A|B NAME LOG -- CMD...
#                                          start CMD on a side in its own process group
#                                          (setsid), output to LOG; prints the PGID; `down`
#                                          kills it (and its descendants)
#   two_hosts.sh mode NAME                 print "netns" or "loopback"
#   two_hosts.sh down NAME                 kill spawned processes, delete namespaces/veths,
#                                          remove the state (idempotent)
#   two_hosts.sh leftovers                 list vrm* namespaces / links present on this machine
#
# Usage (library): `source two_hosts.sh` defines `two_hosts ARGS...` (runs this script).
#
# Environment: VRM_REMOTE_MODE=auto|netns|loopback (default auto),
#   VRM_STATE_ROOT (default ${TMPDIR:-/tmp}/vrm-two-hosts), VRM_KEEP_STATE=1 keeps the state
#   directory (logs) after down.
#
# Inside `exec`/`spawn` the command sees: the workspace's ROS setup (scripts/common.sh of this
# repository, located from this file's path), ROS_HOSTNAME unset, ROS_IP = the side's address,
# ROS_MASTER_URI = http://<A's address>:PORT, ROS_LOG_DIR = the state directory.

TWO_HOSTS_SH="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/$(basename "${BASH_SOURCE[0]}")"

if [[ "${BASH_SOURCE[0]}" != "$0" ]]; then
  # Sourced: library mode.
  two_hosts() { "$TWO_HOSTS_SH" "$@"; }
  return 0
fi

set -u -o pipefail
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"   # system python3 first (pyenv shadows it)

REPO_ROOT="$(cd "$(dirname "$TWO_HOSTS_SH")/../../../.." && pwd)"
STATE_ROOT="${VRM_STATE_ROOT:-${TMPDIR:-/tmp}/vrm-two-hosts}"
SUBNET_A=10.213.0.1
SUBNET_B=10.213.0.2
PREFIX_LEN=30
LOOP_A=127.0.0.1
LOOP_B=127.0.0.2

die()  { echo "two_hosts.sh: $*" >&2; exit 2; }
note() { echo "two_hosts.sh: $*" >&2; }

check_name() {
  [[ "${1:-}" =~ ^[A-Za-z0-9_.-]{1,40}$ ]] || die "bad NAME '${1:-}' (1-40 chars of [A-Za-z0-9_.-])"
}
check_side() {
  [[ "${1:-}" == A || "${1:-}" == B ]] || die "side must be A or B, got '${1:-}'"
}

# Names derived from NAME. Interface names are limited to 15 chars: vrm + 8 hex + A/B.
ns_name()   { echo "vrm$2-$1"; }                  # ns_name NAME A -> vrmA-NAME
veth_name() {
  local h; h=$(printf '%s' "$1" | cksum | awk '{printf "%08x", $1}')
  echo "vrm${h}$2"
}
state_dir() { echo "$STATE_ROOT/$1"; }

default_port() {
  local c; c=$(printf '%s' "$1" | cksum | awk '{print $1}')
  echo $((11900 + c % 50))
}

# ---------------------------------------------------------------------------------------------
netns_teardown() {  # NAME — remove namespaces and veths (never fails)
  local name=$1 side ns pids link
  for side in A B; do
    ns=$(ns_name "$name" "$side")
    if ip netns list 2>/dev/null | awk '{print $1}' | grep -qxF "$ns"; then
      pids=$(timeout 5 ip netns pids "$ns" 2>/dev/null | tr '\n' ' ')
      # shellcheck disable=SC2086
      [[ -n "${pids// /}" ]] && kill -KILL $pids 2>/dev/null
      timeout 10 ip netns del "$ns" 2>/dev/null || note "could not delete netns $ns"
    fi
  done
  for side in A B; do
    link=$(veth_name "$name" "$side")
    if ip link show "$link" >/dev/null 2>&1; then
      timeout 5 ip link del "$link" 2>/dev/null || note "could not delete link $link"
    fi
  done
}

netns_setup() {  # NAME — returns non-zero (and cleans up) on any failure
  local name=$1 nsA nsB vA vB
  nsA=$(ns_name "$name" A); nsB=$(ns_name "$name" B)
  vA=$(veth_name "$name" A); vB=$(veth_name "$name" B)
  [[ $(id -u) -eq 0 ]] || { note "not root: no network namespaces"; return 1; }
  {
    timeout 10 ip netns add "$nsA" &&
    timeout 10 ip netns add "$nsB" &&
    timeout 10 ip link add "$vA" type veth peer name "$vB" &&
    timeout 10 ip link set "$vA" netns "$nsA" &&
    timeout 10 ip link set "$vB" netns "$nsB" &&
    timeout 10 ip -n "$nsA" link set lo up &&
    timeout 10 ip -n "$nsB" link set lo up &&
    timeout 10 ip -n "$nsA" addr add "$SUBNET_A/$PREFIX_LEN" dev "$vA" &&
    timeout 10 ip -n "$nsB" addr add "$SUBNET_B/$PREFIX_LEN" dev "$vB" &&
    timeout 10 ip -n "$nsA" link set "$vA" up &&
    timeout 10 ip -n "$nsB" link set "$vB" up
  } 2>"$(state_dir "$name")/netns_setup.err" || {
    note "netns setup failed: $(tr '\n' ' ' <"$(state_dir "$name")/netns_setup.err")"
    netns_teardown "$name"
    return 1
  }
  # Wait for the link to be usable (veth carrier + DAD is off for IPv4; just poll operstate).
  local i
  for ((i = 0; i < 50; i++)); do
    if ip -n "$nsA" -o link show "$vA" 2>/dev/null | grep -q 'LOWER_UP' &&
       ip -n "$nsB" -o link show "$vB" 2>/dev/null | grep -q 'LOWER_UP'; then
      return 0
    fi
    sleep 0.1
  done
  note "veth did not come up"
  netns_teardown "$name"
  return 1
}

# ---------------------------------------------------------------------------------------------
load_state() {  # NAME — sets MODE, PORT, IP_A, IP_B, MASTER_URI
  local sd; sd=$(state_dir "$1")
  [[ -f "$sd/state" ]] || die "no pair '$1' (run: two_hosts.sh up $1)"
  # shellcheck disable=SC1091
  source "$sd/state"
}

side_ip() { if [[ $1 == A ]]; then echo "$IP_A"; else echo "$IP_B"; fi; }

cmd_up() {
  local name=${1:-} port=${2:-}
  check_name "$name"
  [[ -z "$port" ]] && port=$(default_port "$name")
  [[ "$port" =~ ^[0-9]+$ ]] || die "bad PORT '$port'"
  local want=${VRM_REMOTE_MODE:-auto}
  case "$want" in auto|netns|loopback) ;; *) die "VRM_REMOTE_MODE must be auto|netns|loopback";; esac

  cmd_down "$name" >/dev/null 2>&1   # stale pair of the same name
  local sd; sd=$(state_dir "$name")
  mkdir -p "$sd/log" || die "cannot create $sd"
  : >"$sd/pgids"

  local mode
  if [[ $want != loopback ]] && netns_setup "$name"; then
    mode=netns; IP_A=$SUBNET_A; IP_B=$SUBNET_B
  elif [[ $want == netns ]]; then
    rm -rf "$sd"; die "netns mode requested but namespaces could not be created"
  else
    mode=loopback; IP_A=$LOOP_A; IP_B=$LOOP_B
  fi
  MASTER_URI="http://$IP_A:$port"
  {
    echo "MODE=$mode"
    echo "NAME=$name"
    echo "PORT=$port"
    echo "IP_A=$IP_A"
    echo "IP_B=$IP_B"
    echo "MASTER_URI=$MASTER_URI"
    echo "OWNER_PID=$PPID"
  } >"$sd/state"
  local s
  for s in A B; do
    {
      echo "unset ROS_HOSTNAME"
      echo "export ROS_IP=$(side_ip $s)"
      echo "export ROS_MASTER_URI=$MASTER_URI"
      echo "export ROS_LOG_DIR=$sd/log"
    } >"$sd/env.$s"
  done
  echo "VRM_MODE=$mode"
  echo "VRM_NAME=$name"
  echo "VRM_STATE_DIR=$sd"
  echo "VRM_PORT=$port"
  echo "VRM_A_IP=$IP_A"
  echo "VRM_B_IP=$IP_B"
  echo "VRM_MASTER_URI=$MASTER_URI"
  if [[ $mode == netns ]]; then
    echo "VRM_A_NETNS=$(ns_name "$name" A)"
    echo "VRM_B_NETNS=$(ns_name "$name" B)"
    echo "VRM_A_VETH=$(veth_name "$name" A)"
    echo "VRM_B_VETH=$(veth_name "$name" B)"
  fi
  echo "VRM_A_ENV=$sd/env.A"
  echo "VRM_B_ENV=$sd/env.B"
}

cmd_env() {
  check_side "${1:-}"; check_name "${2:-}"
  cat "$(state_dir "$2")/env.$1"
}

cmd_mode() {
  check_name "${1:-}"; load_state "$1"; echo "${MODE:?}"
}

# The command line that runs "$@" on side $1 of pair $2 (array in RUN).
build_run() {
  local side=$1 name=$2; shift 2
  load_state "$name"
  local sd; sd=$(state_dir "$name")
  # shellcheck disable=SC2016
  local inner=(bash -c '
    root=$1 envfile=$2; shift 2
    if [[ -f "$root/scripts/common.sh" ]]; then
      source "$root/scripts/common.sh" >/dev/null
    elif [[ -f "$root/build/devel/setup.bash" ]]; then
      source "$root/build/devel/setup.bash" >/dev/null
    fi
    set +u
    export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"
    source "$envfile"
    exec "$@"' two_hosts_exec "$REPO_ROOT" "$sd/env.$side" "$@")
  if [[ $MODE == netns ]]; then
    RUN=(ip netns exec "$(ns_name "$name" "$side")" "${inner[@]}")
  else
    RUN=("${inner[@]}")
  fi
}

cmd_exec() {
  local side=${1:-} name=${2:-}
  check_side "$side"; check_name "$name"; shift 2
  [[ "${1:-}" == -- ]] && shift
  [[ $# -gt 0 ]] || die "exec: no command"
  build_run "$side" "$name" "$@"
  exec "${RUN[@]}"
}

cmd_spawn() {
  local side=${1:-} name=${2:-} log=${3:-}
  check_side "$side"; check_name "$name"; [[ -n "$log" ]] || die "spawn: no LOG"
  shift 3
  [[ "${1:-}" == -- ]] && shift
  [[ $# -gt 0 ]] || die "spawn: no command"
  build_run "$side" "$name" "$@"
  local sd; sd=$(state_dir "$name")
  # This script is not interactive (no job control), so the background child is not a group
  # leader and setsid does not fork: $! is the new session's and process group's id.
  setsid "${RUN[@]}" >"$log" 2>&1 </dev/null &
  local pg=$!
  echo "$pg" >>"$sd/pgids"
  echo "$pg"
}

# All descendants of the given pids (roslaunch setsid's its children, so a process-group kill
# alone would orphan rosmaster/rosout).
descendants() {
  local -a todo=("$@") out=()
  local p kids
  while ((${#todo[@]})); do
    p=${todo[0]}; todo=("${todo[@]:1}")
    out+=("$p")
    kids=$(ps -o pid= --ppid "$p" 2>/dev/null | tr -s ' \n' ' ')
    # shellcheck disable=SC2206
    [[ -n "${kids// /}" ]] && todo+=($kids)
  done
  echo "${out[@]}"
}

any_alive() { local p; for p in "$@"; do kill -0 "$p" 2>/dev/null && return 0; done; return 1; }

kill_spawned() {  # NAME
  local sd; sd=$(state_dir "$1")
  [[ -s "$sd/pgids" ]] || return 0
  local -a pgs=() all=()
  local pg i
  while read -r pg; do [[ -n "$pg" ]] && pgs+=("$pg"); done <"$sd/pgids"
  # shellcheck disable=SC2207
  all=($(descendants "${pgs[@]}"))
  for sig in INT TERM KILL; do
    for pg in "${pgs[@]}"; do kill "-$sig" -- "-$pg" 2>/dev/null; done
    kill "-$sig" "${all[@]}" 2>/dev/null
    [[ $sig == KILL ]] && break
    for ((i = 0; i < 30; i++)); do any_alive "${all[@]}" || break 2; sleep 0.1; done
  done
  : >"$sd/pgids"
}

cmd_down() {
  local name=${1:-}
  check_name "$name"
  local sd; sd=$(state_dir "$name")
  kill_spawned "$name"
  netns_teardown "$name"     # always (also removes leftovers of a lost state dir)
  if [[ -d "$sd" && "${VRM_KEEP_STATE:-0}" != 1 ]]; then rm -rf "$sd"; fi
  return 0
}

cmd_leftovers() {
  ip netns list 2>/dev/null | awk '{print $1}' | grep '^vrm' | sed 's/^/netns /'
  ip -o link show 2>/dev/null | awk -F': ' '{print $2}' | sed 's/@.*//' | grep '^vrm' | sed 's/^/link /'
  return 0
}

usage() { sed -n '2,/^$/p' "$TWO_HOSTS_SH" | sed 's/^# \{0,1\}//' >&2; exit 2; }

case "${1:-}" in
  up)        shift; cmd_up "$@" ;;
  env)       shift; cmd_env "$@" ;;
  mode)      shift; cmd_mode "$@" ;;
  exec)      shift; cmd_exec "$@" ;;
  spawn)     shift; cmd_spawn "$@" ;;
  down)      shift; cmd_down "$@" ;;
  leftovers) shift; cmd_leftovers ;;
  *)         usage ;;
esac
