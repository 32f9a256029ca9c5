#!/usr/bin/env bash
# `flysfm batch` of an earlier revision and of this tree, run in turns on the
# same input on the same machine, as a user would run them: a virtual
# machine's speed drifts by tens of percent between days, so a figure from
# another day says little, a ratio from the same minutes says what changed.
#
#   scripts/bench_compare.sh [options] BASE_REV [-- more batch options]
#     --set fr1        TUM freiburg1_xyz with its calibration (default)
#     --set photos     bench_photos' rendered building, --photos N (100) at
#                      --megapixels 6|24 (6), with its K (--uncalibrated: without)
#     --frames N       fr1: the first N frames (default 330)
#     --rounds N       base, current, base, current, ... N times each (1)
#
# Builds BASE_REV's `flysfm` (Release) in a worktree kept under
# /tmp/flysfm-bench-base-<sha> and this tree's in build/ (FLYSFM_BUILD_DIR);
# renders the photos once with this tree's bench_photos (--render-only, kept
# in /tmp/flysfm-bench-photos-<set>). Per run it reads the batch's output
# lines as they come (the last image's result, the end), its log.jsonl
# (each image's all-stages time at arrival and each stage's), its peak
# resident memory (/usr/bin/time), its checkpoint folder's size, and the
# accuracy (`flysfm eval`: fr1's ATE, or the photos' centre error after
# Sim3). Prints the medians over rounds, base against current, and ends
# with one line of JSON. The data folder is FLYSFM_DATA_DIR (default
# ../shared/data). Run it on an idle machine.
set -euo pipefail

usage() { sed -n '2,24p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
set_name=fr1 frames=330 rounds=1 photos=100 megapixels=6 calibrated=1
while [[ $# -gt 0 && "$1" == --* && "$1" != -- ]]; do
  case "$1" in
    --set) set_name=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --rounds) rounds=$2; shift 2 ;;
    --photos) photos=$2; shift 2 ;;
    --megapixels) megapixels=$2; shift 2 ;;
    --uncalibrated) calibrated=0; shift ;;
    -h|--help) usage ;;
    *) echo "bench_compare: unknown option $1" >&2; usage ;;
  esac
done
[[ $# -ge 1 ]] || usage
base_rev=$1
shift
[[ $# -gt 0 && "$1" == -- ]] && shift
extra=("$@")
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "bench_compare: --rounds must be >= 1" >&2; exit 2; }

repo="$(cd "$(dirname "$0")/.." && pwd)"
build="${FLYSFM_BUILD_DIR:-$repo/build}"
data="${FLYSFM_DATA_DIR:-$repo/../shared/data}"
base_sha="$(git -C "$repo" rev-parse --verify "$base_rev^{commit}")" || {
  echo "bench_compare: '$base_rev' is not a revision of $repo" >&2
  exit 2
}
work="$(mktemp -d /tmp/flysfm-bench-compare.XXXXXX)"
base="/tmp/flysfm-bench-base-$base_sha"

echo "== building flysfm of ${base_sha:0:10} (base, in $base) and of this tree"
if [[ ! -d "$base" ]]; then
  git -C "$repo" worktree add --detach "$base" "$base_sha" >/dev/null
fi
cmake -S "$base" -B "$base/build" -DCMAKE_BUILD_TYPE=Release >"$work/base-cmake.log"
cmake --build "$base/build" -j2 --target flysfm >"$work/base-build.log" 2>&1 || {
  tail -20 "$work/base-build.log" >&2
  exit 1
}
[[ -f "$build/CMakeCache.txt" ]] || cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j2 --target flysfm bench_photos >"$work/current-build.log" 2>&1 || {
  tail -20 "$work/current-build.log" >&2
  exit 1
}

if [[ $set_name == fr1 ]]; then
  input="$data/tum/rgbd_dataset_freiburg1_xyz"
  truth="$input/groundtruth.txt"
  camera="FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,-0.0054,0.0026,1.1633,0,0,0"
  args=(--max-images "$frames")
elif [[ $set_name == photos ]]; then
  input="/tmp/flysfm-bench-photos-$photos-$megapixels"
  echo "== rendering $photos photos of $megapixels MP into $input (reused when there)"
  "$build/bench/bench_photos" --render-only --work "$input" --photos "$photos" \
    --megapixels "$megapixels" >"$work/render.log" 2>&1 || { tail -20 "$work/render.log" >&2; exit 1; }
  truth="$input/groundtruth.txt"
  camera="$(cat "$input/camera.txt")"
  args=()
else
  echo "bench_compare: unknown set $set_name" >&2
  exit 2
fi
[[ $calibrated == 1 ]] && args+=(--camera "$camera")

python3 - "$work" "$rounds" "$base_sha" "$base/build/flysfm" "$build/flysfm" "$input" "$truth" \
  "$set_name" -- "${args[@]}" "${extra[@]}" <<'PY'
import json, os, statistics, subprocess, sys, time
work, rounds, base_sha, base_bin, current_bin, input_dir, truth, set_name = sys.argv[1:9]
rounds = int(rounds)
batch_args = sys.argv[10:]
evaluator = current_bin

def folder_bytes(path):
    total = 0
    for root, _, files in os.walk(path):
        for name in files:
            total += os.path.getsize(os.path.join(root, name))
    return total

def run(side, binary, round_index):
    out = os.path.join(work, f"{side}-{round_index}")
    command = ["/usr/bin/time", "-f", "peak_rss_kb %M", binary, "batch", input_dir, "--out", out,
               *batch_args]
    print(f"== round {round_index}: {side}", flush=True)
    start = time.monotonic()
    last_image = None
    with open(out + ".txt", "w") as log:
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                   text=True)
        for line in process.stdout:
            log.write(line)
            if line.startswith("["):
                last_image = time.monotonic() - start
        process.wait()
    wall = time.monotonic() - start
    if process.returncode != 0:
        sys.exit(f"bench_compare: {side} failed, see {out}.txt")
    peak_kb = 0
    for line in open(out + ".txt"):
        if line.startswith("peak_rss_kb"):
            peak_kb = int(line.split()[1])
    arrivals, stages = {}, {}
    for line in open(os.path.join(out, "log.jsonl")):
        record = json.loads(line)
        if record["name"] in arrivals:
            continue
        arrivals[record["name"]] = record["ms"]["total"]
        for stage, ms in record["ms"].items():
            stages.setdefault(stage, []).append(ms)
    totals = list(arrivals.values())
    evaluation = subprocess.run([evaluator, "eval", "--groundtruth", truth, "--trajectory",
                                 os.path.join(out, "trajectory.txt")],
                                capture_output=True, text=True)
    error_m = float("nan")
    if evaluation.returncode == 0:
        error_m = json.loads(evaluation.stdout.strip().splitlines()[-1])["ate_rmse_m"]
    n = len(totals)
    state = os.path.join(out, "state")
    figures = {
        "images": n,
        "median_all_stages_ms": statistics.median(totals),
        "p95_all_stages_ms": sorted(totals)[int(0.95 * (n - 1))],
        "first10_median_ms": statistics.median(totals[:10]),
        "last10_median_ms": statistics.median(totals[-10:]),
        "wall_s": wall,
        "last_image_s": last_image,
        "end_s": wall - last_image,
        "end_share": (wall - last_image) / wall,
        "peak_rss_mb": peak_kb / 1024,
        "checkpoint_kb_per_image": folder_bytes(state) / 1024 / n if os.path.isdir(state) else float("nan"),
        "error_cm" if set_name == "fr1" else "error_mm": error_m * (100 if set_name == "fr1" else 1000),
    }
    for stage, values in stages.items():
        if stage != "total":
            figures[f"stage:{stage}"] = statistics.median(values)
    return figures

runs = {"base": [], "current": []}
for r in range(1, rounds + 1):
    runs["base"].append(run("base", base_bin, r))
    runs["current"].append(run("current", current_bin, r))
keys = [k for k in runs["current"][0] if k in runs["base"][0]]
print(f"\nbase {base_sha[:10]} against this tree, {set_name}, {rounds} round(s), medians over rounds")
print(f"{'':28}{'base':>12}{'current':>12}{'current/base':>14}")
summary = {}
for key in keys:
    b = statistics.median(run[key] for run in runs["base"])
    c = statistics.median(run[key] for run in runs["current"])
    ratio = c / b if b else float("nan")
    summary[key] = {"base": b, "current": c, "ratio": ratio}
    print(f"{key:28}{b:12.3f}{c:12.3f}{ratio:14.3f}")
print(f"each run's output: {work}")
print(json.dumps({"bench": "compare", "set": set_name, "base": base_sha, "rounds": rounds,
                  "figures": summary}))
PY
