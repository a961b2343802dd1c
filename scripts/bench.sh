#!/usr/bin/env bash
# Runs benchmark suites and writes bench/results/<suite>.json (with --quick: <suite>.quick.json, a smoke run that
# leaves the committed full results alone). Usage: scripts/bench.sh [--quick] [suite ...]  (default: all suites)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
quick=()
suites=()
for arg in "$@"; do
  case $arg in
    --quick) quick=(--quick) ;;
    -h | --help) sed -n '2,3p' "$0"; exit 0 ;;
    *) suites+=("$arg") ;;
  esac
done
"$ROOT/scripts/setup.sh"
source "$ROOT/scripts/common.sh"

declare -A executables
while IFS= read -r path; do
  executables[$(basename "$path" | sed 's/^bench_//')]=$path
done < <(find "$ROOT/build/devel/lib" -maxdepth 2 -type f -name 'bench_*' -perm -u+x | sort)
((${#suites[@]})) || suites=($(printf '%s\n' "${!executables[@]}" | sort))
((${#suites[@]})) || { echo "bench.sh: no benchmarks built" >&2; exit 1; }

mkdir -p "$ROOT/bench/results"
status=0
for suite in "${suites[@]}"; do
  exe=${executables[$suite]:-}
  [[ -n $exe ]] || { echo "bench.sh: unknown suite '$suite' (have: ${!executables[*]})" >&2; status=1; continue; }
  out="$ROOT/bench/results/$suite${quick:+.quick}.json"
  echo "== $suite -> ${out#$ROOT/}"
  (cd "$ROOT" && "$exe" "${quick[@]}" --out "$out") || { echo "bench.sh: suite $suite failed" >&2; status=1; continue; }
  # A suite may ship a plot script (src/<pkg>/bench/plot_<suite>.py): PNGs beside the JSON; quick runs plot into
  # build/ so they test the script without touching the committed figures.
  for plot in "$ROOT"/src/*/bench/plot_"$suite".py; do
    [[ -f $plot ]] || continue
    plots="$ROOT/bench/results"
    ((${#quick[@]})) && plots="$ROOT/build/bench_quick_plots" && mkdir -p "$plots"
    /usr/bin/python3 "$plot" "$out" "$plots" || { echo "bench.sh: plot $plot failed" >&2; status=1; }
  done
done
exit $status
