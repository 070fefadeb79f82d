#!/usr/bin/env bash
# Runs a render on a real multi-process cluster on 127.0.0.1: F magg-fork processes,
# N magg-node processes and one magg-host, then stops them all (none is left behind,
# also on error or Ctrl-C).
#
#   deploy/local-cluster.sh SCENE OUT [--forks F] [--nodes N] [--base-port P] [-- HOST-FLAGS...]
#
# Example:
#   deploy/local-cluster.sh scenes/magg-paper.toml paper.png --forks 5 --nodes 8 -- --stats paper.json
#
# Binaries come from target/release (built first with cargo unless MAGG_BIN is set).
set -euo pipefail

usage() { sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
[ $# -ge 2 ] || usage
scene=$1; out=$2; shift 2
forks=5; nodes=4; base=17100
while [ $# -gt 0 ]; do
  case $1 in
    --forks) forks=$2; shift 2 ;;
    --nodes) nodes=$2; shift 2 ;;
    --base-port) base=$2; shift 2 ;;
    --) shift; break ;;
    *) echo "unknown option $1" >&2; usage ;;
  esac
done

root=$(cd "$(dirname "$0")/.." && pwd)
if [ -z "${MAGG_BIN:-}" ]; then
  (cd "$root" && cargo build --release -q -p magg-host -p magg-fork -p magg-node)
  MAGG_BIN=$root/target/release
fi

pids=()
cleanup() {
  for p in "${pids[@]:-}"; do [ -n "$p" ] && kill "$p" 2>/dev/null || true; done
  for p in "${pids[@]:-}"; do [ -n "$p" ] && wait "$p" 2>/dev/null || true; done
}
trap cleanup EXIT INT TERM

fork_addrs=()
for ((i = 0; i < forks; i++)); do
  addr=127.0.0.1:$((base + 1 + i))
  "$MAGG_BIN/magg-fork" --listen "$addr" &
  pids+=($!)
  fork_addrs+=("$addr")
done
host_addr=127.0.0.1:$base
for ((i = 0; i < nodes; i++)); do
  "$MAGG_BIN/magg-node" --host "$host_addr" --name "node-$i" &
  pids+=($!)
done
IFS=, ; forks_at="${fork_addrs[*]}"; unset IFS
"$MAGG_BIN/magg-host" render "$scene" --out "$out" --forks-at "$forks_at" \
  --listen "$host_addr" --external-nodes "$@"
