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
jobs=2

if ! command -v clang++ >/dev/null; then
  echo "fuzz: needs clang and libFuzzer (Debian: apt-get install clang libclang-rt-14-dev)" >&2
  exit 1
fi
start=$SECONDS
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=clang++ \
  -DFLYSFM_FUZZ=ON >/dev/null
cmake --build "$build" -j"$jobs" --target fuzz_targets
echo "fuzz: built in $((SECONDS - start)) s"

artifacts=$PWD/$build/fuzz/artifacts
mkdir -p "$artifacts"
export UBSAN_OPTIONS=print_stacktrace=1
status=0
for seeds in fuzz/corpus/*/; do
  target=$(basename "$seeds")
  corpus=$(mktemp -d)
  cp "$seeds"/* "$corpus"/
  target_start=$SECONDS
  # -timeout: one input running this long is a hang; -rss_limit_mb: a
  # memory blow-up is a finding too.
  if "$build/fuzz/$target" "$corpus" -max_total_time="$seconds" -timeout=10 \
      -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$artifacts/$target-" \
      >"$build/fuzz/$target.log" 2>&1; then
    echo "fuzz: $target passed ($(grep -o 'stat::number_of_executed_units: *[0-9]*' \
      "$build/fuzz/$target.log" | grep -o '[0-9]*$') runs in $((SECONDS - target_start)) s)"
  else
    echo "fuzz: $target FAILED; log:" >&2
    tail -n 60 "$build/fuzz/$target.log" >&2
    status=1
  fi
  rm -rf "$corpus"
done
echo "fuzz: total $((SECONDS - start)) s"
exit $status
