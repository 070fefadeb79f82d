#!/usr/bin/env bash
# Start-up on a large mesh: how long `magg-host info` takes to read a scene (its TOML and
# its OBJ) and to prepare it (elements, blocks, BVH), triangles per second, and the
# process's peak memory, for (3, 7) torus knots of 1M and 2M triangles in a room
# (`gen_meshes --knot N`). Prints one markdown table; not a test.
#
#   deploy/bench-startup.sh                                # 1M and 2M triangles
#   SIZES="1000000 2000000 20000000" deploy/bench-startup.sh
#   BEFORE=/tmp/magg-host-old REPEATS=3 deploy/bench-startup.sh   # two builds, interleaved
#
# Environment: SIZES (triangle counts), REPEATS (1; the table gives medians), MAGG_HOST
# (the build to time; default target/release/magg-host), BEFORE (another magg-host, run
# interleaved with it, e.g. a copy of an older build), WORK (where the meshes are written
# and kept between runs; default /tmp/magg-bench-startup), GEN_MESHES (the generator;
# default target/release/examples/gen_meshes).
#
# "read" is the build's own `read_s` (`magg-host info --json`); a build without it is
# given wall minus prepare (process start and exit included). Triangles per second are
# the mesh's triangles over read + prepare. Peak RSS is `/usr/bin/time`'s maximum
# resident set of the whole process.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
host=${MAGG_HOST:-$root/target/release/magg-host}
gen=${GEN_MESHES:-$root/target/release/examples/gen_meshes}
sizes=(${SIZES:-1000000 2000000})
repeats=${REPEATS:-1}
work=${WORK:-/tmp/magg-bench-startup}
builds=("$host")
[ -n "${BEFORE:-}" ] && builds=("$BEFORE" "$host")
for b in "${builds[@]}" "$gen"; do
  [ -x "$b" ] || {
    echo "bench-startup: $b not built (cargo build --release -p magg-host; cargo build --release -p magg-scene --example gen_meshes)" >&2
    exit 1
  }
done
mkdir -p "$work"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

median() { sort -g | awk '{ a[NR] = $1 } END { print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2 }'; }

echo "| triangles | build | read s | prepare s | read triangles/s | read + prepare triangles/s | peak RSS MB | wall s |"
echo "|---:|---|---:|---:|---:|---:|---:|---:|"
for n in "${sizes[@]}"; do
  obj="$work/knot$n.obj"
  scene="$work/knot$n-room.toml"
  [ -s "$obj" ] && [ -s "$scene" ] || "$gen" --knot "$n" "$obj" > /dev/null
  tris=$(grep -c '^f ' "$obj")
  for r in $(seq "$repeats"); do
    for k in "${!builds[@]}"; do
      /usr/bin/time -f "%e %M" -o "$tmp/time-$k-$r" "${builds[$k]}" info "$scene" --json > "$tmp/info-$k-$r.json"
    done
  done
  for k in "${!builds[@]}"; do
    for r in $(seq "$repeats"); do
      read -r wall rss < "$tmp/time-$k-$r"
      python3 - "$tmp/info-$k-$r.json" "$wall" "$rss" <<'EOF' >> "$tmp/rows-$k"
import json, sys
info = json.load(open(sys.argv[1]))
wall, rss = float(sys.argv[2]), float(sys.argv[3])
prep = info["preprocess_s"]
read = info.get("read_s", wall - prep)
print(read, prep, rss / 1024, wall)
EOF
    done
    read_s=$(cut -d' ' -f1 "$tmp/rows-$k" | median)
    prep_s=$(cut -d' ' -f2 "$tmp/rows-$k" | median)
    rss_mb=$(cut -d' ' -f3 "$tmp/rows-$k" | median)
    wall_s=$(cut -d' ' -f4 "$tmp/rows-$k" | median)
    rm -f "$tmp/rows-$k"
    name=$(basename "${builds[$k]}")
    awk -v n="$tris" -v b="$name" -v r="$read_s" -v p="$prep_s" -v m="$rss_mb" -v w="$wall_s" 'BEGIN {
      printf "| %d | %s | %.2f | %.2f | %.0f | %.0f | %.0f | %.2f |\n", n, b, r, p, n / r, n / (r + p), m, w }'
  done
done
