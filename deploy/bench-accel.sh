#!/usr/bin/env bash
# Grid versus BVH: stage times of `magg-host render` for each scene, both acceleration
# structures, an unlimited and a bounded cache, interleaved runs, median of REPEATS.
# Prints one markdown table (docs/PERFORMANCE.md, "Grid versus BVH", has the newer
# whole-render comparisons on a 100k-triangle model).
#
#   deploy/bench-accel.sh                       # large, cornell, magg-paper at 200 x 200
#   SIZE=100 REPEATS=5 CACHE=40 deploy/bench-accel.sh scenes/cornell.toml
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
host=${MAGG_HOST:-$root/target/release/magg-host}
size=${SIZE:-200}
repeats=${REPEATS:-3}
cache=${CACHE:-40}
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(scenes/large.toml scenes/cornell.toml scenes/magg-paper.toml)
[ -x "$host" ] || { echo "bench-accel: $host not built (cargo build --release -p magg-host)" >&2; exit 1; }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT

echo "| scene | cache | accel | LRT s | VRT s | total s | hit ratio | misses |"
echo "|---|---|---|---:|---:|---:|---:|---:|"
for scene in "${scenes[@]}"; do
  for c in unlimited "$cache"; do
    for r in $(seq "$repeats"); do
      for accel in grid bvh; do
        "$host" render "$root/$scene" --out "$tmp/x.png" --width "$size" --height "$size" \
          --accel "$accel" --cache-blocks "$c" --stats "$tmp/$accel-$r.json" -q
      done
    done
    for accel in grid bvh; do
      python3 - "$scene" "$c" "$accel" "$tmp"/"$accel"-*.json <<'PY'
import json, statistics, sys
scene, cache, accel, files = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
runs = [json.load(open(f)) for f in files]
med = lambda k: statistics.median(r["stages"][k] for r in runs)
c = runs[0]["cache"]
print(f"| {scene.split('/')[-1]} | {cache} | {accel} | {med('lrt_s'):.3f} | {med('vrt_s'):.3f} | "
      f"{med('total_s'):.3f} | {c.get('hit_ratio', 0):.4f} | {c.get('misses', 0)} |")
PY
    done
  done
done
