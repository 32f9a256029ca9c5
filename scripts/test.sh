#!/usr/bin/env bash
# Every test of flysfm, as CI runs them, each phase timed:
#   release  builds build/ (Release) and runs every CTest case: label `unit`
#            and `regression` (real data; skipped where it is absent, failed
#            instead with FLYSFM_REQUIRE_DATA=1)
#   asan     AddressSanitizer + UndefinedBehaviorSanitizer on every unit test
#            and `flysfm demo` (scripts/sanitize.sh asan)
#   tsan     ThreadSanitizer on the tests where threads meet (label `threads`)
#   fuzz     every libFuzzer target on its seed corpus (scripts/fuzz.sh)
#
#   scripts/test.sh                 all four phases
#   scripts/test.sh release [ARGS]  one phase; for release, ARGS go to ctest
#                                   (e.g. scripts/test.sh release -L unit)
# Exits non-zero when any phase failed; every phase runs either way.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
phases=(release asan tsan fuzz)
ctest_args=()
if [ $# -gt 0 ]; then
  case "$1" in
    release|asan|tsan|fuzz) phases=("$1"); shift; ctest_args=("$@") ;;
    *) echo "usage: scripts/test.sh [release [ctest args] | asan | tsan | fuzz]" >&2; exit 2 ;;
  esac
fi

release() {
  if [ ! -f build/CMakeCache.txt ]; then
    local generator=()
    command -v ninja >/dev/null && generator=(-G Ninja)
    cmake -S . -B build "${generator[@]}" -DCMAKE_BUILD_TYPE=Release
  fi
  cmake --build build -j"$jobs"
  ctest --test-dir build --output-on-failure -j"$jobs" "${ctest_args[@]}"
}

status=0
total=$SECONDS
for phase in "${phases[@]}"; do
  start=$SECONDS
  case "$phase" in
    release) release || status=1 ;;
    asan|tsan) bash scripts/sanitize.sh "$phase" || status=1 ;;
    fuzz) bash scripts/fuzz.sh 20 || status=1 ;;
  esac
  echo "test: phase $phase took $((SECONDS - start)) s"
done
[ ${#phases[@]} -gt 1 ] && echo "test: all phases took $((SECONDS - total)) s"
exit $status
