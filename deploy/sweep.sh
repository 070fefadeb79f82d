#!/usr/bin/env bash
# Redoes the paper's experiments (Kawai et al. 1993, figures 4-11) on the magg cluster
# under the magg1993 hardware profile: nodes 5,10,20,40,60,80 x cache 20,40,60,80 blocks,
# 5 forks, the paper's schedule and ours, on scenes/magg-paper.toml at 400x400.
# Writes OUT/sweep.csv (one row per run), OUT/*.png (the figures) and prints a markdown
# table (docs/EXPERIMENTS.md holds ours).
#
#   deploy/sweep.sh [OUT] [-- magg-host sweep flags]
#
# Examples:
#   deploy/sweep.sh sweep                                   # the full grid, in-process
#   deploy/sweep.sh sweep-mp -- --multi-process deploy/local-cluster.sh   # separate processes
#   deploy/sweep.sh quick -- --nodes 5,20,80 --cache-blocks 20,40 -- --width 200 --height 200
#   deploy/sweep.sh both -- --schemes magg --accel grid,bvh          # the grid and the BVH
#
# The full grid takes about 6-10 minutes on a 2-core machine: every run lasts its modelled
# time times the dilation (grown with the node count so that the emulating machine stays
# under half busy; the table's last column shows its real CPU share).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-sweep}
[ $# -gt 0 ] && shift
[ "${1:-}" = "--" ] && shift
cd "$root"
cargo build --release -q -p magg-host -p magg-fork -p magg-node
exec target/release/magg-host sweep scenes/magg-paper.toml --out-dir "$out" --profile magg1993 "$@"
