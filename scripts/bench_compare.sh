#!/usr/bin/env bash
# bench_engine of an earlier revision and of this tree, run in turns on the
# same machine: a virtual machine's speed drifts by tens of percent between
# days, so a figure from another day says little, a ratio from the same
# minutes says what changed.
#
#   scripts/bench_compare.sh BASE_REV [ROUNDS] [-- bench_engine options]
#
# Builds BASE_REV's bench_engine (Release) in a worktree kept under
# /tmp/flysfm-bench-base-<sha> (a second comparison reuses it), and this
# tree's in build/ (FLYSFM_BUILD_DIR), then runs base, current, base,
# current, ... ROUNDS times each (default 1) and prints, as the median over
# rounds, the median engine time, the median of all stages, each stage's
# median, the ATE and the ratios current / base; each run's output stays in
# the printed folder. The data folder is FLYSFM_DATA_DIR (default
# ../shared/data). Run it on an idle machine.
set -euo pipefail

if [[ $# -lt 1 || "$1" == -h || "$1" == --help ]]; then
  sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
base_rev="$1"
shift
rounds=1
if [[ $# -gt 0 && "$1" != -- ]]; then
  rounds="$1"
  shift
fi
[[ $# -gt 0 && "$1" == -- ]] && shift
if ! [[ "$rounds" =~ ^[1-9][0-9]*$ ]]; then
  echo "bench_compare: ROUNDS must be a positive integer, got '$rounds'" >&2
  exit 2
fi

repo="$(cd "$(dirname "$0")/.." && pwd)"
build="${FLYSFM_BUILD_DIR:-$repo/build}"
data="${FLYSFM_DATA_DIR:-$repo/../shared/data}"
base_sha="$(git -C "$repo" rev-parse --verify "$base_rev^{commit}")" || {
  echo "bench_compare: '$base_rev' is not a revision of $repo" >&2
  exit 2
}
work="$(mktemp -d /tmp/flysfm-bench-compare.XXXXXX)"
base="/tmp/flysfm-bench-base-$base_sha"

echo "== building bench_engine of ${base_sha:0:10} (base, in $base) and of this tree"
if [[ ! -d "$base" ]]; then
  git -C "$repo" worktree add --detach "$base" "$base_sha" >/dev/null
fi
cmake -S "$base" -B "$base/build" -DCMAKE_BUILD_TYPE=Release >"$work/base-cmake.log"
cmake --build "$base/build" -j2 --target bench_engine >"$work/base-build.log" 2>&1 || {
  tail -20 "$work/base-build.log" >&2
  exit 1
}
[[ -f "$build/CMakeCache.txt" ]] || cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j2 --target bench_engine >"$work/current-build.log" 2>&1 || {
  tail -20 "$work/current-build.log" >&2
  exit 1
}

for ((round = 1; round <= rounds; ++round)); do
  for side in base current; do
    if [[ $side == base ]]; then binary="$base/build/bench/bench_engine"; else binary="$build/bench/bench_engine"; fi
    echo "== round $round: $side"
    "$binary" --data "$data" "$@" >"$work/$side-$round.txt" 2>&1 || {
      tail -20 "$work/$side-$round.txt" >&2
      exit 1
    }
    tail -n 1 "$work/$side-$round.txt" >"$work/$side-$round.json"
  done
done

python3 - "$work" "$rounds" "$base_sha" <<'EOF'
import json, statistics, sys
work, rounds, base_sha = sys.argv[1], int(sys.argv[2]), sys.argv[3]
keys = [("median_engine_ms", "engine median ms"), ("median_all_stages_ms", "all stages median ms"),
        ("p95_engine_ms", "engine p95 ms"), ("ate_rmse_m", "ATE RMSE cm"), ("registered", "registered")]
runs = {side: [json.load(open(f"{work}/{side}-{r}.json"))["full"] for r in range(1, rounds + 1)]
        for side in ("base", "current")}
stages = sorted(set.intersection(*(set(run["stage_ms"]) for side in runs.values() for run in side)))
keys += [(f"stage:{name}", f"  {name} median ms") for name in stages]
def value(run, key):
    if key.startswith("stage:"):
        return run["stage_ms"][key[6:]]["median"]
    v = run[key]
    return 100 * v if key == "ate_rmse_m" else v
print(f"\nbase {base_sha[:10]} against this tree, {rounds} round(s), medians over rounds")
print(f"{'':24}{'base':>10}{'current':>10}{'current/base':>14}")
summary = {}
for key, label in keys:
    b = statistics.median(value(run, key) for run in runs["base"])
    c = statistics.median(value(run, key) for run in runs["current"])
    ratio = c / b if b else float("nan")
    summary[key] = {"base": b, "current": c, "ratio": ratio}
    print(f"{label:24}{b:10.2f}{c:10.2f}{ratio:14.3f}")
print(f"each run's output: {work}")
print(json.dumps({"bench": "compare", "base": base_sha, "rounds": rounds, "figures": summary}))
EOF
