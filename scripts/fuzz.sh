#!/usr/bin/env bash
# Builds the fuzz targets of src/vrm_fuzz (clang 14 + libFuzzer, ASan + UBSan, build folder build_fuzz/) and runs
# each for N seconds, one at a time at nice 10, from its seed corpus (src/vrm_fuzz/corpus/<target>/, regenerated
# from the shipped files by src/vrm_fuzz/scripts/make_seeds.py). Writes bench/results/fuzz.json (one row per
# target: executions, exec/s, coverage = libFuzzer's edges `cov:`, features `ft:`, crashes) and the table in
# BENCHMARKS.md's "Fuzzing" section; copies every crash input to src/vrm_fuzz/regressions/<target>/.
# The text formats (YAML, JSON) fuzz with a dictionary, src/vrm_fuzz/dict/<target>.dict (also make_seeds.py's).
# Executions count libFuzzer's mutated runs only (the seed corpus's first pass, `#N INITED`, is left out); each row
# also says where coverage last grew (`last_new_coverage_at`, in mutated executions), whether it stopped growing in
# the run's last third (`plateau`), and the previous row's coverage as the baseline it must reach.
# --resume starts from the corpus the target's last run left in build_fuzz/fuzz_runs/<target>/corpus instead of the
# seeds alone (libFuzzer's usual way to spread a slow target's fuzzing over sittings); the row then also gives the
# mutated executions of all sittings of that corpus (`executions_all_sittings`, `sittings`) beside this run's.
# --build-only builds the targets and stops: no run, so no work folder (grown corpus) is replaced and no row written.
# The grown corpus outlives the build folder: after a run without crashes its inputs that add coverage are merged
# (libFuzzer -merge=1) into src/vrm_fuzz/grown/<target>/, which is committed, and every run reads that folder beside
# the seeds. So a fresh checkout starts where the last committed sitting ended instead of from the seeds alone (a slow
# target needs hours to grow back). src/vrm_fuzz/grown/<target>.json lists the sittings merged into it.
# --save-only merges the work folders' corpora into src/vrm_fuzz/grown/ and stops (for a run that was interrupted or
# came before this step).
# Usage: scripts/fuzz.sh [--seconds N] [--runs N] [--jobs J] [--no-build | --build-only | --save-only] [--resume]
#        [target ...]
#        (default: 300 s;
#        --runs alone runs to N executions, with --seconds too whichever comes first,
#        all targets, one at a time; --jobs 2 runs two targets at once, one per core)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export PATH="/usr/bin:$PATH"
seconds="" runs="" build=1 build_only=0 save_only=0 jobs=1 resume=0 targets=()
command_line="scripts/fuzz.sh $*"
while (($#)); do
  case $1 in
    --seconds) seconds=$2; shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --no-build) build=0; shift ;;
    --build-only) build_only=1; shift ;;
    --resume) resume=1; shift ;;
    --save-only) save_only=1; build=0; shift ;;
    --jobs) jobs=$2; shift 2 ;;
    -h | --help) awk 'NR > 1 && /^#/ { print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    *) targets+=("$1"); shift ;;
  esac
done
[[ -z $seconds && -z $runs ]] && seconds=300
PKG="$ROOT/src/vrm_fuzz"
BUILD="$ROOT/build_fuzz"
all_targets=($(cd "$PKG/fuzz" && ls *.cpp | sed 's/\.cpp$//' | grep -v '^fuzz_support$' | sort))
((${#targets[@]})) || targets=("${all_targets[@]}")
for t in "${targets[@]}"; do
  [[ " ${all_targets[*]} " == *" $t "* ]] || { echo "fuzz.sh: unknown target '$t' (have: ${all_targets[*]})" >&2; exit 2; }
done

# Per-target input caps: images and bags are large inputs; a cap keeps one execution short (see BENCHMARKS.md).
declare -A max_len=([marker_detector]=8192 [calibrator_images]=32768 [mesh_upload]=16384 [session_bag]=32768 [sim_messages]=4096 [tracking_messages]=4096
                    [scene_yaml]=16384 [mesh_import]=8192 [surgeon_script]=8192)
# Targets that read one input format (sim_conversions runs sim_messages' messages without a World).
declare -A same_format=([sim_conversions]=sim_messages [sim_messages]=sim_conversions)

if ((build)); then
  mkdir -p "$BUILD"
  flags="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
  CC=clang CXX=clang++ nice -n 10 cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only" \
    -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS="$flags" \
    -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined" \
    -DCATKIN_ENABLE_TESTING=OFF -DVRM_FUZZ_LIBFUZZER=ON \
    -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 >"$BUILD/configure.log" 2>&1 ||
    { tail -n 30 "$BUILD/configure.log"; exit 1; }
  nice -n 10 cmake --build "$BUILD" -j2 --target $(printf 'fuzz_%s ' "${targets[@]}")
fi
# Merges the work folder's corpus into the committed one: only inputs that add coverage to what it holds already.
save_corpus() {
  local t=$1 work="$BUILD/fuzz_runs/$1" grown="$PKG/grown/$1"
  [[ -d $work/corpus ]] || { echo "   $t: no work corpus in $work to save" >&2; return 1; }
  mkdir -p "$grown"
  local before
  before=$(ls "$grown" | wc -l)
  local options=()
  [[ -n ${max_len[$t]:-} ]] && options=(-max_len="${max_len[$t]}")
  (cd "$work" && nice -n 10 "$BUILD/fuzz/fuzz_$t" -merge=1 "${options[@]}" -timeout=20 -rss_limit_mb=3072 \
    "$grown" "$work/corpus") >"$work/merge.log" 2>&1 || { tail -n 5 "$work/merge.log"; return 1; }
  echo "   $t: src/vrm_fuzz/grown/$t: $before -> $(ls "$grown" | wc -l) inputs ($(du -sk "$grown" | cut -f1) KB)"
  /usr/bin/python3 - "$work" "$grown" "$t" <<'PY'
import datetime, json, os, pathlib, re, sys
work, grown, target = map(pathlib.Path, sys.argv[1:4])
log = (work / "log").read_text(errors="replace") if (work / "log").exists() else ""
status = [l for l in log.splitlines() if re.match(r"^#\d+\s", l)]
cov = re.search(r"cov: (\d+)", status[-1]) if status else None
sittings = json.loads((work / "sittings.json").read_text()) if (work / "sittings.json").exists() else []
record = grown.parent / ("%s.json" % target.name)
doc = json.loads(record.read_text()) if record.exists() else {"target": target.name, "merged": []}
doc["merged"].append({
    "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
    "sitting": sittings[-1] if sittings else None, "coverage_at_end": int(cov.group(1)) if cov else None,
    "inputs_after_merge": len(os.listdir(grown)),
    "bytes_after_merge": sum(f.stat().st_size for f in grown.iterdir())})
record.write_text(json.dumps(doc, indent=1) + "\n")
PY
}

if ((build_only)); then
  ((build)) || { echo "fuzz.sh: --build-only and --no-build together do nothing" >&2; exit 2; }
  echo "fuzz.sh: built ${#targets[@]} target(s) in $BUILD/fuzz (--build-only: nothing run)"
  exit 0
fi

# A fuzzed array length may ask for gigabytes: an allocation over 128 MB fails (std::bad_alloc, handled like a message
# roscpp cannot read) instead of counting as an out-of-memory crash.
export ASAN_OPTIONS="max_allocation_size_mb=128:allocator_may_return_null=1:detect_odr_violation=0:${ASAN_OPTIONS:-}"
export LSAN_OPTIONS="suppressions=$PKG/lsan.supp:${LSAN_OPTIONS:-}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:${UBSAN_OPTIONS:-}"
export ROS_HOSTNAME=localhost

if ((save_only)); then
  for t in "${targets[@]}"; do
    [[ -x $BUILD/fuzz/fuzz_$t ]] || { echo "fuzz.sh: $BUILD/fuzz/fuzz_$t is not built" >&2; exit 2; }
    save_corpus "$t" || failed=1
  done
  exit "${failed:-0}"
fi

mkdir -p "$BUILD/fuzz_runs" "$ROOT/bench/results"
# One results file per invocation, and the merge into fuzz.json under a lock: two invocations may run at once.
results="$BUILD/fuzz_runs/results.$$.tsv"
: >"$results"
trap 'rm -f "$results"' EXIT
run_target() {
  local t=$1 work="$BUILD/fuzz_runs/$1"
  # sittings.json: the mutated executions of every earlier run that grew this corpus (written by the merge below).
  if ((resume)) && [[ -d $work/corpus ]]; then
    rm -rf "$work/artifacts" "$work/log" && mkdir -p "$work/artifacts"
    echo "   $t: resuming from $(ls "$work/corpus" | wc -l) corpus inputs of earlier runs"
  else
    rm -rf "$work" && mkdir -p "$work/corpus" "$work/artifacts"
  fi
  local limit=()
  [[ -n $seconds ]] && limit+=(-max_total_time="$seconds")
  [[ -n $runs ]] && limit+=(-runs="$runs")
  local target_options=()  # libFuzzer options of this target: its input cap, its dictionary
  [[ -n ${max_len[$t]:-} ]] && target_options=(-max_len="${max_len[$t]}")
  [[ -f $PKG/dict/$t.dict ]] && target_options+=(-dict="$PKG/dict/$t.dict")
  local corpora=("$work/corpus" "$PKG/corpus/$t")
  [[ -d $PKG/grown/$t ]] && corpora+=("$PKG/grown/$t")
  # A target that reads the same input format as another also starts from that one's grown corpus (libFuzzer keeps
  # only the inputs that add coverage to this target, so the other's are no dead weight).
  [[ -n ${same_format[$t]:-} && -d $PKG/grown/${same_format[$t]} ]] && corpora+=("$PKG/grown/${same_format[$t]}")
  echo "== fuzz_$t (${limit[*]}${target_options:+ ${target_options[*]}}; corpora: ${corpora[*]#$ROOT/})"
  local start end rc crashes=0
  start=$(date +%s.%N)
  set +e
  (cd "$work" && nice -n 10 "$BUILD/fuzz/fuzz_$t" "${limit[@]}" "${target_options[@]}" -timeout=20 -rss_limit_mb=3072 \
    -print_final_stats=1 -artifact_prefix="$work/artifacts/" "${corpora[@]}") >"$work/log" 2>&1
  rc=$?
  set -e
  end=$(date +%s.%N)
  local load_timeout=0
  for artifact in "$work"/artifacts/{crash,leak,timeout,oom}-*; do
    [[ -f $artifact ]] || continue
    # libFuzzer's -timeout is wall time: on a loaded machine the nice-10 fuzzer can be starved past it. A timeout
    # input is run again alone; one that then finishes in time is no finding (the run still ended there).
    if [[ $(basename "$artifact") == timeout-* ]] &&
      (cd "$work" && nice -n 10 "$BUILD/fuzz/fuzz_$t" -timeout=20 "$artifact") >"$artifact.rerun.log" 2>&1; then
      load_timeout=1
      echo "   $t: $(basename "$artifact") ended the run but runs in time alone ($(grep -o 'in [0-9]* ms' \
        "$artifact.rerun.log" | tail -n 1)): the machine's load, not a finding; not copied to regressions/"
      continue
    fi
    crashes=$((crashes + 1))
    mkdir -p "$PKG/regressions/$t"
    cp "$artifact" "$PKG/regressions/$t/"
    echo "   $t: crash input -> src/vrm_fuzz/regressions/$t/$(basename "$artifact")"
  done
  # 72: libFuzzer's exit after SIGINT (kill -INT the fuzzer to end a run early; its stats and corpus are kept).
  if ((rc == 72 && crashes == 0)) && grep -q 'libFuzzer: run interrupted' "$work/log"; then
    echo "   $t: interrupted (SIGINT), not a crash"
  elif ((load_timeout && crashes == 0)); then
    echo "   $t: ended early by a timeout that does not reproduce (see above)"
  elif ((rc != 0 && crashes == 0)); then
    crashes=1
    echo "   $t: fuzzer exited $rc without an artifact (see $work/log)"
  fi
  grep -E '^#[0-9]+' "$work/log" | tail -n 1 | sed "s/^/   $t: /" || true
  printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$t" "$(echo "$end - $start" | bc)" "$crashes" "${max_len[$t]:-}" "$work/log" \
    "$work/sittings.json" >>"$results"
}
for t in "${targets[@]}"; do
  [[ -x $BUILD/fuzz/fuzz_$t ]] || { echo "fuzz.sh: $BUILD/fuzz/fuzz_$t is not built (run without --no-build)" >&2; exit 2; }
done
for t in "${targets[@]}"; do
  while (($(jobs -rp | wc -l) >= jobs)); do wait -n || true; done
  run_target "$t" &
done
wait

flock "$ROOT/bench/results/.fuzz.lock" /usr/bin/python3 - "$results" "$ROOT" "$command_line" "$seconds" "${runs:-}" <<'PY'
import datetime, json, os, pathlib, platform, re, subprocess, sys
results, root, command, seconds, runs = sys.argv[1:6]
root = pathlib.Path(root)
out = root / "bench" / "results" / "fuzz.json"
doc = json.loads(out.read_text()) if out.exists() else {}
rows = {r["target"]: r for r in doc.get("rows", [])}
clang = subprocess.run(["clang", "--version"], capture_output=True, text=True).stdout.splitlines()[0]
cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), platform.machine())
machine = "%s, %d cores (%s)" % (cpu, os.cpu_count(), platform.machine())
date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
for line in open(results):
    target, wall, crashes, max_len, log, sittings_file = line.rstrip("\n").split("\t")
    text = open(log, errors="replace").read()
    stat = dict(re.findall(r"^stat::(\w+):\s+(\d+)", text, re.M))
    status = [l for l in text.splitlines() if re.match(r"^#\d+\s", l)]
    last = status[-1] if status else ""
    cov = re.search(r"cov: (\d+)", last)
    ft = re.search(r"ft: (\d+)", last)
    corp = re.search(r"corp: (\d+)", last)
    total = int(stat.get("number_of_executed_units", 0))
    inited = re.search(r"^#(\d+)\s+INITED", text, re.M)
    executions = total - (int(inited.group(1)) if inited else 0)  # mutated runs only
    # Where coverage (cov:) last grew, in mutated executions; a plateau = no growth in the last third of the run.
    last_growth, best = 0, None
    for line in status:
        n, c = re.match(r"^#(\d+)", line), re.search(r"cov: (\d+)", line)
        if not (n and c):
            continue
        if best is None or int(c.group(1)) > best:
            best, last_growth = int(c.group(1)), max(0, int(n.group(1)) - (int(inited.group(1)) if inited else 0))
    previous = rows.get(target, {})
    # The baseline is pinned by the first run in this format: the coverage of the row before it (an older format's
    # row); for a target that was new then, its first run's coverage. Later runs carry it on. A run that did not
    # start (no row values) is no baseline.
    if previous.get("coverage_baseline") is not None:
        baseline, baseline_date = previous["coverage_baseline"], previous.get("coverage_baseline_date")
    elif previous.get("coverage"):
        baseline, baseline_date = previous.get("coverage"), previous.get("date")
    else:
        baseline, baseline_date = None, None
    wall = float(wall)
    # Earlier sittings of this corpus (--resume): their mutated executions, then this run's appended.
    sittings = json.loads(pathlib.Path(sittings_file).read_text()) if os.path.exists(sittings_file) else []
    sittings.append({"date": date, "executions": executions, "seconds": round(wall, 1)})
    pathlib.Path(sittings_file).write_text(json.dumps(sittings) + "\n")
    all_sittings = sum(x["executions"] for x in sittings)
    # Issue 39 §3: 10^6 mutated executions for the parsers that run at >= 1000 exec/s on an idle machine (the script
    # reader at 1,540 and the result reader at 7,600 exec/s here), 10^5 for the slower targets; fixed per target, so
    # that a run on a busy machine keeps its target's goal.
    parsers = ("camera_yaml", "rig_yaml", "marker_layout_yaml", "surgeon_script", "session_result_json")
    goal = 1_000_000 if target in parsers else 100_000
    rows[target] = {
        "suite": "fuzz", "target": target, "executions": executions,
        "executions_per_s": round(executions / wall, 1) if wall > 0 else None,
        "libfuzzer_exec_per_s": int(stat.get("average_exec_per_sec", 0)),
        "coverage": int(cov.group(1)) if cov else 0, "coverage_measure": "edges (libFuzzer cov:)",
        "features": int(ft.group(1)) if ft else 0, "corpus": int(corp.group(1)) if corp else 0,
        "crashes": int(crashes), "seconds": round(wall, 1), "max_len": int(max_len) if max_len else None,
        "dictionary": ("src/vrm_fuzz/dict/%s.dict" % target
                       if (root / "src" / "vrm_fuzz" / "dict" / ("%s.dict" % target)).exists() else None),
        "peak_rss_mb": int(stat.get("peak_rss_mb", 0)), "reached_1M": executions >= 1_000_000,
        "executions_counted": "mutated runs only (number_of_executed_units minus the #INITED seed pass)",
        "goal_executions": goal, "reached_goal": executions >= goal,
        "sittings": len(sittings), "executions_all_sittings": all_sittings,
        "reached_goal_all_sittings": all_sittings >= goal,
        "last_new_coverage_at": last_growth, "plateau": executions > 0 and last_growth <= executions * 2 / 3,
        "coverage_baseline": baseline, "coverage_baseline_date": baseline_date,
        "coverage_at_least_baseline": baseline is None or (int(cov.group(1)) if cov else 0) >= baseline,
        "date": date, "clang": clang, "machine": machine, "command": command,
    }
doc = {"suite": "fuzz", "command": command, "quick": False, "date": date, "clang": clang, "machine": machine,
       "seconds_per_target": float(seconds) if seconds else None, "runs_per_target": int(runs) if runs else None,
       "coverage": "edges: libFuzzer's cov: of the last status line (ft: = features, also given)",
       "sanitizers": "address, undefined (-fsanitize=fuzzer-no-link,address,undefined on all workspace code)",
       "rows": [rows[k] for k in sorted(rows)]}
out.write_text(json.dumps(doc, indent=1) + "\n")

# The table in BENCHMARKS.md between the fuzz markers (appended as a section the first time).
table = ["| target | mutated executions | all sittings | goal | exec/s | coverage (edges) | before | last growth at | features | crashes | seconds | max_len | date |",
         "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
def mark(ok):
    return "" if ok is None else (" ✓" if ok else " ✗")
for r in doc["rows"]:
    table.append("| %s | %s | %s | %s%s | %s | %d%s | %s | %s | %d | %d | %.0f | %s | %s |" % (
        r["target"], f'{r["executions"]:,}',
        ("%s (%d)%s" % (f'{r["executions_all_sittings"]:,}', r["sittings"], mark(r.get("reached_goal_all_sittings"))))
        if r.get("sittings", 1) > 1 else "-",
        f'{r["goal_executions"]:,}' if r.get("goal_executions") else "-", mark(r.get("reached_goal")),
        f'{r["executions_per_s"]:,.0f}' if r["executions_per_s"] else "-",
        r["coverage"], mark(r.get("coverage_at_least_baseline")), r.get("coverage_baseline") or "-",
        ("%s (%s)" % (f'{r["last_new_coverage_at"]:,}', "plateau" if r.get("plateau") else "still growing"))
        if "last_new_coverage_at" in r else "-",
        r["features"], r["crashes"], r["seconds"], r["max_len"] or "default", r["date"]))
block = "<!-- fuzz:table:begin (scripts/fuzz.sh writes this table) -->\n%s\n\n%s; %s; command of the last run: `%s`.\n<!-- fuzz:table:end -->" % (
    "\n".join(table), clang, machine, command)
md = root / "BENCHMARKS.md"
text = md.read_text()
if "<!-- fuzz:table:begin" in text:
    text = re.sub(r"<!-- fuzz:table:begin.*?<!-- fuzz:table:end -->", lambda m: block, text, flags=re.S)
else:
    text = text.rstrip("\n") + "\n\n## Fuzzing (issue 14)\n\n" + block + "\n"
md.write_text(text)
print("fuzz.sh: %s and BENCHMARKS.md (Fuzzing) updated" % out.relative_to(root))
for r in doc["rows"]:
    print("  %-20s %12s execs %8s exec/s  cov %5d  ft %6d  crashes %d" % (
        r["target"], f'{r["executions"]:,}', f'{r["executions_per_s"]:,.0f}' if r["executions_per_s"] else "-",
        r["coverage"], r["features"], r["crashes"]))
PY
status=0
awk -F'\t' '$3 != 0 { bad = 1 } END { exit bad }' "$results" || status=1
# A run without crashes hands its grown corpus on (a crash's corpus waits until the crash is understood).
while IFS=$'\t' read -r t _ crashes _; do
  ((crashes == 0)) && { save_corpus "$t" || status=1; }
done <"$results"
exit $status
