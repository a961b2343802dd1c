#!/usr/bin/env bash
# issue 42: the layers hold at link time. ldd (what the loader really maps, transitive libraries included) of
#  - the scene floor (libvrm_scene's libraries and its import helper): no physics (FCL, Bullet), no GL, no ROS;
#  - every libvrm_tracking*.so: no libfcl, no rosbag, and no libOSMesa (the rig twin renders on the CPU);
#  - every libvrm_render*.so: no libfcl, no rosbag (OSMesa is the renderer's own);
#  - every eyesi_gui binary: no libfcl, no rosbag, except the two whose job is exactly that, named below.
# Prints PASS/FAIL lines; exits 1 on any failure.
set -uo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/checks.sh"
trap 'rm -rf "$TMP"' EXIT
LIB=${BUILD:-$ROOT/build}/devel/lib

physics='lib(fcl|BulletSoftBody|BulletDynamics|BulletCollision)\.so'
gl='lib(OSMesa|GL|GLX|EGL)\.so'
ros='lib(roscpp|rosbag|rosbag_storage|roslib|rostime|roscpp_serialization)\.so'
bags='lib(rosbag|rosbag_storage)\.so'

# check FILE FORBIDDEN_REGEX WHAT: one PASS or FAIL line.
check() {
  local file=$1 forbidden=$2 what=$3 found
  if [[ ! -e $file ]]; then
    fail "$(basename "$file"): not built (build the workspace first)"
    return
  fi
  found=$(ldd "$file" 2>/dev/null | grep -oE "$forbidden" | sort -u | tr '\n' ' ')
  if [[ -n $found ]]; then
    fail "$(basename "$file") loads $found($what)"
  else
    pass "$(basename "$file"): no $what"
  fi
}

for library in vrm_yaml vrm_cli vrm_meshes vrm_anatomy vrm_scene; do
  check "$LIB/lib$library.so" "$physics|$gl|$ros" "physics, GL or ROS"
done
check "$LIB/vrm_scene/vrm_mesh_import" "$physics|$gl|$ros" "physics, GL or ROS"

tracking=("$LIB"/libvrm_tracking*.so)
((${#tracking[@]} >= 4)) || fail "expected the four vrm_tracking libraries, found ${#tracking[@]}"
for library in "${tracking[@]}"; do
  check "$library" "$physics|$bags|libOSMesa\.so" "FCL, rosbag or OSMesa"
done

render=("$LIB"/libvrm_render*.so)
((${#render[@]} >= 4)) || fail "expected the four vrm_render libraries, found ${#render[@]}"
for library in "${render[@]}"; do
  check "$library" "$physics|$bags" "FCL or rosbag"
done

# The two eyesi_gui binaries allowed what the others are not, and why:
#  session_trajectory reads a session bag's trajectories for the records (issue 41): rosbag's reader is its job;
#  bench_validity simulates novice and expert sessions with the World to measure the scores' validity.
declare -A allowed=([session_trajectory]="$bags" [bench_validity]="$physics")
gui=0
for binary in "$LIB"/eyesi_gui/*; do
  [[ -f $binary && -x $binary ]] && file -bL "$binary" | grep -q ELF || continue
  gui=$((gui + 1))
  name=$(basename "$binary")
  forbidden="$physics|$bags"
  if [[ -n ${allowed[$name]:-} ]]; then
    forbidden=$(tr '|' '\n' <<<"$physics|$bags" | grep -vxF -f <(tr '|' '\n' <<<"${allowed[$name]}") | paste -sd'|')
  fi
  check "$binary" "$forbidden" "FCL or rosbag beyond its job"
done
((gui >= 4)) || fail "expected the eyesi_gui binaries (station, console, records tools), found $gui"

echo "library_layers: $failures failure(s)"
((failures == 0))
