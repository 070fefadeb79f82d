#!/usr/bin/env bash
# magg's ray kernel against Intel Embree 3 (Debian's libembree-dev), one thread, the same
# triangles and the same rays: primary rays (one per pixel centre, nearest hit, in tiles
# of 4 x 4 pixels) and occlusion rays (light to element centroids). Prints two markdown
# tables of Mrays/s and the ratio magg / Embree, the median over ROUNDS interleaved rounds
# (each the median of REPEATS timed runs): one ray at a time (trace::cast against
# rtcIntersect1 / rtcOccluded1), then packets of consecutive rays (trace::cast_all /
# occluded_all, 16 rays, against rtcIntersect8 / rtcOccluded8, Embree's native width on
# AVX2; EMBREE_WIDTH=16 for rtcIntersect16). docs/PERFORMANCE.md records it.
#
#   deploy/bench-embree.sh                      # the issue's table, and 50k random triangles
#   SIZE=200 ROUNDS=3 deploy/bench-embree.sh scenes/cornell.toml
#
# Installs libembree-dev with apt-get when missing (as root); where there is no apt, says
# so and exits 0 without measuring.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
size=${SIZE:-300}
rounds=${ROUNDS:-3}
repeats=${REPEATS:-3}
occ=${OCCLUSION:-100000}
targets=("$@")
# sphere-box and spheres:25 are generated (core/examples/embree_rays/scenes.rs): the box
# with a block and a sphere (3 988 triangles) and 25 spheres in a box (55 210).
[ ${#targets[@]} -gt 0 ] || targets=(sphere-box spheres:25 scenes/magg-paper.toml scenes/cornell.toml scenes/large.toml random:50000)

if [ ! -f /usr/include/embree3/rtcore.h ]; then
  if ! command -v apt-get >/dev/null; then
    echo "bench-embree: skipped: Embree 3 headers not found and no apt-get to install libembree-dev" >&2
    exit 0
  fi
  echo "bench-embree: installing libembree-dev" >&2
  sudo=""; [ "$(id -u)" -eq 0 ] || sudo=sudo
  $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq libembree-dev >/dev/null
fi
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
width=${EMBREE_WIDTH:-8}
cc -O2 -DW="$width" -o "$tmp/harness" "$root/deploy/embree/harness.c" -lembree3 -lm
(cd "$root" && cargo build --release -q -p magg-core --example embree_rays)
rays=${CARGO_TARGET_DIR:-$root/target}/release/examples/embree_rays

head="| scene | triangles | magg primary | Embree primary | ratio | magg occlusion | Embree occlusion | ratio |"
rule="|---|---:|---:|---:|---:|---:|---:|---:|"
printf '%s\n%s\n' "One ray at a time:" "" >"$tmp/single"
printf '%s\n%s\n' "Packets (magg 16 rays, Embree $width):" "" >"$tmp/packets"
for f in single packets; do printf '%s\n%s\n' "$head" "$rule" >>"$tmp/$f"; done
for t in "${targets[@]}"; do
  case $t in
    random:*) src=(--random "${t#random:}"); name="random ${t#random:}" ;;
    spheres:*) src=(--spheres "${t#spheres:}"); name="${t#spheres:} spheres" ;;
    sphere-box) src=(--sphere-box); name="box, block and sphere" ;;
    *) src=("$root/$t"); name=$(basename "$t" .toml) ;;
  esac
  : >"$tmp/runs"
  for r in $(seq "$rounds"); do
    "$rays" "${src[@]}" --out "$tmp/rays.bin" --size "$size" --occlusion "$occ" --repeats "$repeats" >>"$tmp/runs"
    "$tmp/harness" "$tmp/rays.bin" "$repeats" >>"$tmp/runs"
  done
  python3 - "$name" "$tmp/runs" >>"$tmp/single" 3>>"$tmp/packets" <<'PY'
import os, statistics, sys
name, path = sys.argv[1], sys.argv[2]
rows = {"magg": [], "embree": []}
for line in open(path):
    w = line.split()
    # "... primary P occlusion O ... packets P8 O8" on both sides.
    rows[w[0]].append((int(w[2]), float(w[4]), float(w[6]), float(w[-2]), float(w[-1])))
med = lambda who, k: statistics.median(r[k] for r in rows[who])
tri = rows["magg"][0][0]
for k, out in ((1, sys.stdout), (3, os.fdopen(3, "w"))):
    mp, ep, mo, eo = med("magg", k), med("embree", k), med("magg", k + 1), med("embree", k + 1)
    print(f"| {name} | {tri} | {mp:.2f} | {ep:.2f} | {mp / ep:.2f} | {mo:.2f} | {eo:.2f} | {mo / eo:.2f} |", file=out, flush=True)
PY
done
cat "$tmp/single"; echo; cat "$tmp/packets"
