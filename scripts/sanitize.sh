#!/usr/bin/env bash
# Builds flysfm with sanitizers and runs what each is there for
# (docs/testing.md):
#   scripts/sanitize.sh asan   AddressSanitizer + UndefinedBehaviorSanitizer
#                              in build-asan: every unit test, then
#                              `flysfm demo` in a temporary folder
#   scripts/sanitize.sh tsan   ThreadSanitizer in build-tsan: the tests
#                              where threads meet (label `threads`)
#   scripts/sanitize.sh [all]  both
# Exits non-zero when a build or a test fails or when a sanitizer reported
# anything, in a test or in a process a test started; the reports are printed.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
mode=${1:-all}
case "$mode" in
  asan|tsan|all) ;;
  *) echo "usage: scripts/sanitize.sh [asan|tsan|all]" >&2; exit 2 ;;
esac
jobs=$(nproc)

# Every report goes to a file, <dir>/sanitizer-reports/<tool>.<pid>, rather
# than to stderr: a test that runs `flysfm` as a child process deletes the
# child's output with its temporary folder, and a child's exit code is not
# always looked at. Any such file fails the run. Every report stops its
# process (halt_on_error); leaks count as reports (detect_leaks).
asan_reports=$root/build-asan/sanitizer-reports
tsan_reports=$root/build-tsan/sanitizer-reports
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:detect_stack_use_after_return=1:check_initialization_order=1:strict_init_order=1:log_path=$asan_reports/asan"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:log_path=$asan_reports/ubsan"
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$root/scripts/sanitizers/tsan.supp:log_path=$tsan_reports/tsan"

status=0

# phase NAME COMMAND...: runs COMMAND and says how long it took; a failure
# fails the run and is returned.
phase() {
  local name=$1 start=$SECONDS
  shift
  if "$@"; then
    echo "sanitize: $name passed in $((SECONDS - start)) s"
  else
    echo "sanitize: $name FAILED after $((SECONDS - start)) s" >&2
    status=1
    return 1
  fi
}

# build DIR SANITIZERS TARGET...
build() {
  local dir=$1 sanitizers=$2
  shift 2
  local generator=()
  [ -f "$dir/CMakeCache.txt" ] || { command -v ninja >/dev/null && generator=(-G Ninja); }
  cmake -S . -B "$dir" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release \
    -DFLYSFM_SANITIZE="$sanitizers" &&
    cmake --build "$dir" -j"$jobs" --target "$@"
}

# no_reports DIR: prints every report file in DIR; false when there is one.
no_reports() {
  local reports=("$1"/*)
  [ -e "${reports[0]}" ] || return 0
  for report in "${reports[@]}"; do
    echo "---- $report"
    cat "$report"
  done >&2
  return 1
}

# The demo writes flysfm_demo/ into the current folder: a temporary one here.
# 10 views instead of 24: every step of the pipeline runs, in 60 s instead of
# 150 s under the sanitizers (docs/testing.md).
demo() {
  local dir demo_status=0
  dir=$(mktemp -d)
  (cd "$dir" && "$root/build-asan/flysfm" demo --views 10) || demo_status=$?
  rm -rf "$dir"
  return $demo_status
}

run_asan() {
  rm -rf "$asan_reports" && mkdir -p "$asan_reports"
  phase "asan build" build build-asan address,undefined unit_tests flysfm || return 0
  phase "asan unit tests" ctest --test-dir build-asan -L unit --output-on-failure -j"$jobs" || true
  phase "asan demo" demo || true
  phase "asan reports" no_reports "$asan_reports" || true
}

run_tsan() {
  rm -rf "$tsan_reports" && mkdir -p "$tsan_reports"
  phase "tsan build" build build-tsan thread threads_tests || return 0
  phase "tsan threads tests" ctest --test-dir build-tsan -L threads --output-on-failure -j"$jobs" || true
  phase "tsan reports" no_reports "$tsan_reports" || true
}

if [ "$mode" != tsan ]; then run_asan; fi
if [ "$mode" != asan ]; then run_tsan; fi
if [ $status -ne 0 ]; then
  echo "sanitize: $mode FAILED" >&2
  exit 1
fi
echo "sanitize: $mode passed"
