# shellcheck shell=bash
# Sourced by scripts/test.sh --sanitize (and by hand for one test: `source scripts/sanitizers/env.sh build_asan`):
# the runtime options of the ASan + UBSan build. Argument: the build folder; reports go to <build>/sanitizer_reports.
_san_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
SANITIZER_REPORTS="$(cd "${1:?usage: source env.sh BUILD_DIR}" && pwd)/sanitizer_reports"
export SANITIZER_REPORTS
mkdir -p "$SANITIZER_REPORTS"
# log_path: every report of every process lands in a file <kind>.<pid> here, including those of nodelet managers
# and helper nodes whose exit codes no test looks at; test.sh fails the run when any such file exists.
# detect_leaks: LSan runs at each process's normal exit (a process killed by SIGKILL is not checked).
# halt_on_error: the first memory error ends the process (ASan's default, stated): the test fails there.
# check_initialization_order: also catch static initialisers that read another file's not yet constructed globals.
# alloc_dealloc_mismatch stays on (ASan's default, stated): the one mismatch it found, FCL's BVHModel arrays allocated
# by libfcl (built as C++14, Eigen's malloc-based operator new[]) and freed by our C++17 instantiation of ~BVHModel
# (global operator delete[]), is fixed at its source: fcl_detector.cpp is compiled with EIGEN_HAS_CXX17_OVERALIGN=0
# (src/vrm_sim/CMakeLists.txt), so both sides use Eigen's operators (issue 39 §4).
export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:check_initialization_order=1:alloc_dealloc_mismatch=1:suppressions=$_san_dir/asan.supp:log_path=$SANITIZER_REPORTS/asan"
# print_suppressions=0: a clean process whose leaks were all suppressed writes no file.
export LSAN_OPTIONS="suppressions=$_san_dir/lsan.supp:print_suppressions=0"
# halt_on_error=1: undefined behaviour ends the process like a memory error does, so it fails its test.
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$_san_dir/ubsan.supp:log_path=$SANITIZER_REPORTS/ubsan"
# The nodelet wrapper (scripts/sanitizers/nodelet) preloads this runtime into the Debian nodelet binary.
VRM_LIBASAN=$(gcc -print-file-name=libasan.so)
export VRM_LIBASAN
unset _san_dir
