#!/usr/bin/env bash
# Builds the container images magg-fork, magg-node and magg-host FROM scratch: each holds
# one release binary (debug info stripped), the shared libraries `ldd` lists for it and
# the dynamic loader, nothing else: no base image, no registry, no network needed (a
# Docker engine that has no images and can pull none builds them).
#
#   deploy/build-images.sh                       # cargo build --release, then the images
#   deploy/build-images.sh --bin-dir target/release --tag test
#
# Options:
#   --bin-dir DIR   take the binaries from DIR instead of running cargo build --release
#   --tag TAG       image tag (default: latest, or $MAGG_TAG)
#   --save FILE     also write the three images to FILE (docker save), to load on other
#                   machines without a registry: docker load -i FILE, or
#                   ctr -n k8s.io images import FILE, or kind load image-archive FILE
#
# Each image has the usual flags set by environment (see docs/DEPLOY.md): forks listen on
# 0.0.0.0:7100, nodes serve health on 0.0.0.0:7200 and wait for render after render, the
# host serves nodes on 0.0.0.0:7000; and a HEALTHCHECK that runs the binary's own
# `probe ADDR` subcommand (there is no shell in the image).
set -euo pipefail
cd "$(dirname "$0")/.."

bin_dir=""
tag="${MAGG_TAG:-latest}"
save=""
while [ $# -gt 0 ]; do
    case "$1" in
        --bin-dir) bin_dir="$2"; shift 2 ;;
        --tag) tag="$2"; shift 2 ;;
        --save) save="$2"; shift 2 ;;
        -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
        *) echo "build-images.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done

if ! docker info >/dev/null 2>&1; then
    echo "build-images.sh: no Docker engine reachable (docker info failed)" >&2
    exit 1
fi
if [ -z "$bin_dir" ]; then
    cargo build --release -p magg-fork -p magg-node -p magg-host
    bin_dir="${CARGO_TARGET_DIR:-target}/release"
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

# image NAME ENV HEALTHCHECK-ADDR: the image magg-NAME:$tag.
image() {
    local name="magg-$1" env="$2" probe="$3"
    local ctx="$work/$name" bin="$bin_dir/magg-$1"
    [ -x "$bin" ] || { echo "build-images.sh: $bin is missing (build it, or pass --bin-dir)" >&2; exit 1; }
    mkdir -p "$ctx/rootfs"
    cp "$bin" "$ctx/rootfs/$name"
    if command -v strip >/dev/null; then strip --strip-debug "$ctx/rootfs/$name"; fi
    # Every library the loader resolves, and the loader itself, at the path ldd names
    # (symbolic links followed: the image has only the files).
    local lib
    for lib in $(ldd "$bin" | grep -o '/[^ ]*'); do
        mkdir -p "$ctx/rootfs$(dirname "$lib")"
        cp -L "$lib" "$ctx/rootfs$lib"
    done
    mkdir -p "$ctx/rootfs/out" "$ctx/rootfs/tmp"
    cat >"$ctx/Dockerfile" <<EOF
FROM scratch
COPY rootfs/ /
ENV $env
HEALTHCHECK --interval=2s --timeout=4s --start-period=2s --retries=3 CMD ["/$name", "probe", "$probe"]
ENTRYPOINT ["/$name"]
EOF
    docker build --quiet --label org.opencontainers.image.title="$name" -t "$name:$tag" "$ctx" >/dev/null
    echo "$name:$tag ($(du -sh "$ctx/rootfs" | cut -f1) on disk)"
}

image fork "MAGG_FORK_LISTEN=0.0.0.0:7100" 127.0.0.1:7100
image node "MAGG_HEALTH_LISTEN=0.0.0.0:7200 MAGG_REPEAT=true" 127.0.0.1:7200
image host "MAGG_HOST_LISTEN=0.0.0.0:7000" 127.0.0.1:7000

if [ -n "$save" ]; then
    docker save -o "$save" "magg-fork:$tag" "magg-node:$tag" "magg-host:$tag"
    echo "saved to $save"
fi
