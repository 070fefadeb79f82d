#!/usr/bin/env bash
# Overhead of the cluster (forks, nodes and host over gRPC on 127.0.0.1, in one process)
# against the rendering core driven directly, same scene, same node count, unlimited
# cache. Prints a markdown table; every run is --release.
#
#   deploy/bench-cluster.sh [REPEATS] [SCENE...]
#
# Default: 3 repeats of scenes/magg-paper.toml and scenes/large.toml, 2 nodes.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
repeats=${1:-3}
shift || true
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(scenes/magg-paper.toml scenes/large.toml)
nodes=${NODES:-2}
cargo build --release -q -p magg-host
bin=target/release/magg-host
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

field() { # field FILE KEY -> first numeric value of "KEY": N
  sed -n "s/.*\"$2\": \([0-9.e+-]*\).*/\1/p" "$1" | head -n 1
}
best() { # best of N runs of the given mode: prints "total lrt vrt"
  local mode=$1 scene=$2 b=""
  for ((i = 0; i < repeats; i++)); do
    "$bin" render "$scene" --out "$tmp/o.png" --stats "$tmp/s.json" --nodes "$nodes" --quiet $mode
    local t; t=$(field "$tmp/s.json" total_s)
    if [ -z "$b" ] || awk "BEGIN{exit !($t < ${b%% *})}"; then
      b="$t $(field "$tmp/s.json" lrt_s) $(field "$tmp/s.json" vrt_s)"
    fi
  done
  echo "$b"
}

echo "machine: $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n 1), $(nproc) cores; load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "nodes: $nodes, cache unlimited, best of $repeats runs"
echo
echo "| scene | core total s | cluster total s | overhead | core LRT s | cluster LRT s | core VRT s | cluster VRT s |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for s in "${scenes[@]}"; do
  read -r ct cl cv < <(best --embedded "$s")
  read -r gt gl gv < <(best "" "$s")
  over=$(awk "BEGIN{printf \"%+.1f%%\", 100*($gt-$ct)/$ct}")
  echo "| $(basename "$s" .toml) | $ct | $gt | $over | $cl | $gl | $cv | $gv |"
done
