#!/usr/bin/env bash
# Is bench/results/latency.json still a measurement of the code it describes? It fails (exit 1) when a commit changed
# a source file of what the latency suite measures — the renderer core, the camera rig twin, the simulation frame —
# after the last commit of latency.json, i.e. when such a commit is reachable from HEAD but not from latency.json's
# last commit (so the last one is not an ancestor of, or equal to, the result's commit). It names the offending
# commits and the command that refreshes the file. Committed history only: uncommitted edits do not count (the result
# is committed with the code it measured). Outside a git checkout, or in a shallow clone that lacks the history, it
# prints a note and passes. Milliseconds; scripts/test.sh runs it first in every tier.
# Usage: scripts/check_bench_fresh.sh
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
RESULT=bench/results/latency.json
# What latency.json measures (issue 30): a directory ends in / and counts with its source files (below), a file counts
# as itself.
MEASURED=(
  src/vrm_render/src/core/                                # renderer core
  src/vrm_render/include/
  src/vrm_render/src/nodelets/stereo_renderer_nodelet.cpp
  src/vrm_tracking/src/core/rig_renderer.cpp              # camera rig twin
  src/vrm_tracking/include/vrm_tracking/rig_renderer.h
  src/vrm_tracking/src/nodelets/camera_rig_sim.cpp
  src/vrm_tracking/src/core/marker_detector.cpp          # tracking:=true: detection and reconstruction
  src/vrm_tracking/src/core/pose_tracker.cpp
  src/vrm_tracking/src/core/triangulation.cpp
  src/vrm_tracking/src/nodelets/marker_detector.cpp
  src/vrm_tracking/src/nodelets/tracker.cpp
  src/vrm_sim/src/core/world/                             # simulation frame
  src/vrm_sim/include/vrm_sim/world/
)
# Source files (not documentation): C/C++ sources and headers, shaders.
SOURCE_EXTENSIONS=(c cc cpp cxx h hh hpp hxx inl ipp glsl vert frag geom comp)

pathspecs=()
for path in "${MEASURED[@]}"; do
  if [[ $path == */ ]]; then
    for extension in "${SOURCE_EXTENSIONS[@]}"; do pathspecs+=(":(glob)$path**/*.$extension"); done
  else
    pathspecs+=(":(literal)$path")
  fi
done

git=(git -C "$ROOT")
if ! "${git[@]}" rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  echo "check_bench_fresh: $ROOT is not a git checkout: cannot tell whether $RESULT is current (skipped)"
  exit 0
fi
if [[ $("${git[@]}" rev-parse --is-shallow-repository) == true ]]; then
  echo "check_bench_fresh: shallow clone: the history that dates $RESULT is missing (skipped; git fetch --unshallow)"
  exit 0
fi
result_commit=$("${git[@]}" log -1 --format=%H -- "$RESULT")
if [[ -z $result_commit ]]; then
  echo "check_bench_fresh: FAILED: $RESULT was never committed; measure it: ./scripts/bench.sh latency" >&2
  exit 1
fi
# Newest first: commits that changed what is measured and that the measurement's commit does not contain.
mapfile -t stale < <("${git[@]}" rev-list HEAD "^$result_commit" -- "${pathspecs[@]}")
describe() { "${git[@]}" log -1 --format='%h (%cs) %s' "$1" | cut -c1-150; }
if ((${#stale[@]} == 0)); then
  echo "check_bench_fresh: $RESULT ($(describe "$result_commit" | cut -c1-60)...) is newer than the last change" \
    "of the renderer core, the rig twin, the tracking path and the simulation frame"
  exit 0
fi
{
  echo "check_bench_fresh: FAILED: $RESULT is stale: ${#stale[@]} commit(s) changed what it measures after it was"
  echo "  measured in $(describe "$result_commit")"
  echo "  last offending commit: $(describe "${stale[0]}")"
  for commit in "${stale[@]:1:4}"; do echo "  also: $(describe "$commit")"; done
  ((${#stale[@]} <= 5)) || echo "  ... and $((${#stale[@]} - 5)) more since ${result_commit:0:9} (the paths: MEASURED in scripts/check_bench_fresh.sh)"
  echo "  refresh it on an otherwise idle machine (run.sh's session, tracking off and on, 5 runs x 60 s each, every run"
  echo "  after the load average fell below 0.3; ~35 min):"
  echo "    rosrun vrm_sim bench_latency --only sequential --out $RESULT"
  echo "    src/vrm_sim/bench/plot_latency.py $RESULT"
  echo "  (./scripts/bench.sh latency runs all six synchronisation patterns: ~100 min), then commit $RESULT and"
  echo "  bench/results/latency_histogram.png"
} >&2
exit 1
