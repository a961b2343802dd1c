#!/usr/bin/env bash
# Set-up + build, then every unit test (plain gtest) and every rostest (nodelet graphs), with the real verdict:
# catkin's run_tests target exits 0 even when tests fail, so catkin_test_results decides.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$ROOT/scripts/setup.sh"
source "$ROOT/scripts/common.sh"

cmake --build "$ROOT/build" --target tests -j"$(nproc)"
rm -rf "$ROOT/build/test_results"
# One test at a time: rostests start their own masters and the machine has two cores.
cmake --build "$ROOT/build" --target run_tests -j1 || true

set +e
summary=$(catkin_test_results "$ROOT/build/test_results" --all 2>&1)
verdict=$?
set -e
echo "$summary" | grep -vE '^(Skipping|$)' | tail -n 40
if ! /usr/bin/python3 "$ROOT/scripts/test_summary.py" "$ROOT/build/test_results"; then
  echo "test.sh: no test results found" >&2
  exit 1
fi
exit $verdict
