#!/usr/bin/env bash
# Regenerates the expected replay results of the committed reference bags (src/vrm_sim/test/bags/<name>.bag ->
# <name>.expected.json: final_state_hash, score_total, state, frames, simulated_frames), which scripts/test.sh
# compares every replay with (test_reference_bags). Run it when a change is meant to change what a session does,
# and say why in the commit. Usage: scripts/update_reference_bags.sh
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$ROOT/scripts/setup.sh" >/dev/null
source "$ROOT/scripts/common.sh"
for bag in "$ROOT"/src/vrm_sim/test/bags/*.bag; do
  expected=${bag%.bag}.expected.json
  rosrun vrm_sim session_replay --bag "$bag" | /usr/bin/python3 -c '
import json, sys
line = json.load(sys.stdin)
keep = ["final_state_hash", "score_total", "state", "frames", "simulated_frames"]
json.dump({key: line[key] for key in keep}, sys.stdout, indent=2)
print()' >"$expected"
  echo "$(basename "$expected"): $(tr -d '\n ' <"$expected")"
done
