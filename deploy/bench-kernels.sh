#!/usr/bin/env bash
# Rays per second of the LRT and VRT kernels on one core, as a markdown table.
#
#   deploy/bench-kernels.sh                                   # magg-paper and large
#   deploy/bench-kernels.sh --scenes scenes/cornell.toml --cache 20 --pairs 5000
#
# Builds and runs `core/examples/bench_kernels.rs` in release mode (flags are passed on;
# `--help` lists them). Each measurement runs on one thread from a cold block cache, over
# a deterministic sample of the pass (every k-th batch of 8 LRT pairs, every k-th 16x16
# VRT subscreen), repeated until it has taken at least a second. The machine, compiler
# and load average are printed above the table, as docs/PERFORMANCE.md records them.
# Progress goes to stderr, the report to stdout. Set CARGO_TARGET_DIR to build elsewhere.
set -euo pipefail
cd "$(dirname "$0")/.."

cargo build --release -p magg-core --example bench_kernels >&2

model=$(lscpu 2>/dev/null | sed -n 's/^Model name:[[:space:]]*//p' | head -n1)
cores=$(nproc 2>/dev/null || echo '?')
mem=$(awk '/^MemTotal:/ { printf "%.0f GiB", $2 / 1048576 }' /proc/meminfo 2>/dev/null || echo '?')
load_before=$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?')

echo "- machine: ${model:-unknown CPU}, ${cores} cores, ${mem} memory"
echo "- compiler: $(rustc --version)"
echo "- command: cargo run --release -p magg-core --example bench_kernels --${*:+ $*}"
echo "- load average before the run (1, 5, 15 min): ${load_before}"
echo
cargo run --quiet --release -p magg-core --example bench_kernels -- "$@"
echo
echo "- load average after the run: $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?')"
