# Sourced by the script tests in this folder: the workspace environment, PASS/FAIL lines and their count, a
# temporary folder ($TMP, removed by the caller's cleanup).
# shellcheck disable=SC2034
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
source "$ROOT/scripts/common.sh"
failures=0
pass() { echo "PASS: $*"; }
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
TMP=$(mktemp -d)
