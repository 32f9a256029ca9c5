#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ with clang in build-fuzz and runs each
# for the given time on a copy of its seed corpus (fuzz/corpus/<target>/):
#   bash scripts/fuzz.sh [seconds-per-target]     (default 60)
# Exits non-zero when the build fails or a target reports anything (a crash,
# a sanitizer finding, a leak, a timeout); the input that did it is kept in
# build-fuzz/fuzz/artifacts/ and its path printed.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
build=build-fuzz
jobs=$(nproc)

if ! command -v clang++ >/dev/null; then
  echo "fuzz: needs clang and libFuzzer (Debian: apt-get install clang libclang-rt-14-dev)" >&2
  exit 1
fi
start=$SECONDS
generator=()
[ -f "$build/CMakeCache.txt" ] || { command -v ninja >/dev/null && generator=(-G Ninja); }
cmake -S . -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=clang++ \
  -DFLYSFM_FUZZ=ON >/dev/null
cmake --build "$build" -j"$jobs" --target fuzz_targets
echo "fuzz: built in $((SECONDS - start)) s"

artifacts=$PWD/$build/fuzz/artifacts
mkdir -p "$artifacts"
export UBSAN_OPTIONS=print_stacktrace=1

# fuzz_one TARGET: runs it on a copy of its corpus; its verdict goes to
# $build/fuzz/TARGET.verdict. A target is one process on one core: two run at
# once on a 2-core machine, each for the full time.
fuzz_one() {
  local target=$1 corpus target_start=$SECONDS
  corpus=$(mktemp -d)
  cp fuzz/corpus/"$target"/* "$corpus"/
  # -timeout: one input running this long is a hang; -rss_limit_mb: a
  # memory blow-up is a finding too.
  if "$build/fuzz/$target" "$corpus" -max_total_time="$seconds" -timeout=10 \
      -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$artifacts/$target-" \
      >"$build/fuzz/$target.log" 2>&1; then
    echo "fuzz: $target passed ($(grep -o 'stat::number_of_executed_units: *[0-9]*' \
      "$build/fuzz/$target.log" | grep -o '[0-9]*$') runs in $((SECONDS - target_start)) s)" \
      >"$build/fuzz/$target.verdict"
  else
    echo "FAILED" >"$build/fuzz/$target.verdict"
  fi
  rm -rf "$corpus"
}

targets=()
for seeds in fuzz/corpus/*/; do targets+=("$(basename "$seeds")"); done
for ((i = 0; i < ${#targets[@]}; i += jobs)); do
  for target in "${targets[@]:i:jobs}"; do fuzz_one "$target" & done
  wait
done
status=0
for target in "${targets[@]}"; do
  if grep -q '^FAILED' "$build/fuzz/$target.verdict"; then
    echo "fuzz: $target FAILED; log:" >&2
    tail -n 60 "$build/fuzz/$target.log" >&2
    status=1
  else
    cat "$build/fuzz/$target.verdict"
  fi
done
echo "fuzz: total $((SECONDS - start)) s"
exit $status
