#!/usr/bin/env bash
# Overhead of the cluster (forks, nodes and host in one process, talking gRPC through
# the in-process transport) against the rendering core driven directly, same scene,
# same node count, unlimited cache; and of the same cluster with every call over
# 127.0.0.1 sockets (MAGG_TRANSPORT=tcp). Prints a markdown table; every run is --release.
#
#   deploy/bench-cluster.sh [REPEATS] [SCENE...]
#
# Default: 7 repeats of scenes/magg-paper.toml and scenes/large.toml, 2 nodes (NODES=n);
# MODES="core cluster" leaves the socket runs out.
#
# The three modes run interleaved (core, cluster, tcp, core, ...), so that a slow spell
# of a shared machine hits all of them alike; the overhead is the median over repeats of
# the ratio of each cluster run to the core run just before it. Best and median times
# are given too. "total" is the stats file's total_s (preprocessing plus the render,
# from before the cluster's forks and nodes start until its figures are in); "process"
# is the wall time of the whole magg-host process (reading the scene, writing the image
# and shutting the cluster down included).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
repeats=${1:-7}
shift || true
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(scenes/magg-paper.toml scenes/large.toml)
nodes=${NODES:-2}
read -r -a modes <<<"${MODES:-core cluster tcp}"
cargo build --release -q -p magg-host
bin=target/release/magg-host
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

field() { # field FILE KEY -> first numeric value of "KEY": N
  sed -n "s/.*\"$2\": \([0-9.e+-]*\).*/\1/p" "$1" | head -n 1
}
run() { # run MODE SCENE -> "total lrt vrt process" of one render
  local mode=$1 scene=$2 t0 t1
  t0=$(date +%s.%N)
  case $mode in
    core) "$bin" render "$scene" --out "$tmp/o.png" --stats "$tmp/s.json" --nodes "$nodes" --quiet --embedded ;;
    cluster) MAGG_TRANSPORT=in-process "$bin" render "$scene" --out "$tmp/o.png" --stats "$tmp/s.json" --nodes "$nodes" --quiet ;;
    tcp) MAGG_TRANSPORT=tcp "$bin" render "$scene" --out "$tmp/o.png" --stats "$tmp/s.json" --nodes "$nodes" --quiet ;;
  esac
  t1=$(date +%s.%N)
  echo "$(field "$tmp/s.json" total_s) $(field "$tmp/s.json" lrt_s) $(field "$tmp/s.json" vrt_s) $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.4f", b - a }')"
}
stats() { # stats < "x..." lines -> "best median"
  sort -g | awk '{v[NR]=$1} END {m = (NR % 2) ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2; printf "%.4f %.4f\n", v[1], m}'
}

echo "machine: $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n 1), $(nproc) cores; load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "nodes: $nodes, cache unlimited, $repeats interleaved repeats; times best / median (s)"
echo
echo "| scene | mode | total s | LRT s | VRT s | overhead (median ratio) | process s | process overhead |"
echo "|---|---|---:|---:|---:|---:|---:|---:|"
for s in "${scenes[@]}"; do
  : >"$tmp/core" ; : >"$tmp/cluster" ; : >"$tmp/tcp"
  for ((i = 0; i < repeats; i++)); do
    for mode in "${modes[@]}"; do run $mode "$s" >>"$tmp/$mode"; done
  done
  name=$(basename "$s" .toml)
  for mode in "${modes[@]}"; do
    read -r tb tm < <(cut -d' ' -f1 "$tmp/$mode" | stats)
    read -r lb lm < <(cut -d' ' -f2 "$tmp/$mode" | stats)
    read -r vb vm < <(cut -d' ' -f3 "$tmp/$mode" | stats)
    read -r pb pm < <(cut -d' ' -f4 "$tmp/$mode" | stats)
    if [ $mode = core ]; then
      over="-" pover="-"
    else
      ratio() { paste -d' ' "$tmp/$mode" "$tmp/core" | awk -v c="$1" '{print $c / $(c + 4)}' | stats | awk '{printf "%+.1f%%\n", 100 * ($2 - 1)}'; }
      over=$(ratio 1) pover=$(ratio 4)
    fi
    echo "| $name | $mode | $tb / $tm | $lb / $lm | $vb / $vm | $over | $pb / $pm | $pover |"
  done
done
