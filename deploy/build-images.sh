#!/usr/bin/env bash
# Builds the container images magg-fork, magg-node and magg-host FROM scratch: each holds
# one binary of the dist profile (release, symbols stripped, fat LTO, one codegen unit;
# the host's of the dist-host profile, which sizes all but the rendering core), linked
# statically (glibc's crt-static: no shared library, no loader; a binary given by
# --bin-dir brings the shared libraries `ldd` lists for it and the dynamic loader), and the
# host also the scenes (with
# their meshes) at /scenes; nothing else: no base image, no registry, no network needed (a
# Docker engine that has no images and can pull none builds them). Each runs as uid:gid
# 65532:65532, not root; /out (owned by that user) and /tmp are the writable folders.
#
#   deploy/build-images.sh                       # the static dist build, then the images
#   deploy/build-images.sh --bin-dir target/release --tag test
#
# Options:
#   --bin-dir DIR   take the binaries from DIR instead of running the static dist build
#                   (they are stripped on the way in)
#   --scenes DIR    the scenes the host image carries at /scenes (default: scenes/)
#   --tag TAG       image tag (default: latest, or $MAGG_TAG)
#   --save FILE     also write the three images to FILE (docker save), to load on other
#                   machines without a registry: docker load -i FILE, or
#                   ctr -n k8s.io images import FILE, or kind load image-archive FILE
#
# Each image has the usual flags set by environment (see docs/DEPLOY.md): forks listen on
# 0.0.0.0:7100, nodes serve health on 0.0.0.0:7200 and wait for render after render, the
# host serves nodes on 0.0.0.0:7000; and a HEALTHCHECK that runs the binary's own
# `probe ADDR` subcommand (there is no shell in the image).
#
# `docker images` shows each image's size (docs/DEPLOY.md records them).
set -euo pipefail
cd "$(dirname "$0")/.."

bin_dir=""
scenes="scenes"
tag="${MAGG_TAG:-latest}"
save=""
while [ $# -gt 0 ]; do
    case "$1" in
        --bin-dir) bin_dir="$2"; shift 2 ;;
        --scenes) scenes="$2"; shift 2 ;;
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
[ -d "$scenes" ] || { echo "build-images.sh: --scenes $scenes is not a folder" >&2; exit 1; }
host_bin_dir="$bin_dir"
if [ -z "$bin_dir" ]; then
    # With --target, RUSTFLAGS reach only the binaries, not build scripts or proc macros.
    triple="$(rustc -vV | sed -n 's/^host: //p')"
    RUSTFLAGS="${RUSTFLAGS:-} -C target-feature=+crt-static" \
        cargo build --profile dist --target "$triple" -p magg-fork -p magg-node
    # The host: the dist-host profile (sized, its rendering core still fast), linked at
    # fixed addresses (a static executable, not a static PIE: no run-time relocation
    # table, 0.36 MB). Sizes and times: docs/DEPLOY.md.
    RUSTFLAGS="${RUSTFLAGS:-} -C target-feature=+crt-static -C relocation-model=static" \
        cargo build --profile dist-host --target "$triple" -p magg-host
    bin_dir="${CARGO_TARGET_DIR:-target}/$triple/dist"
    host_bin_dir="${CARGO_TARGET_DIR:-target}/$triple/dist-host"
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

# The user every image runs as (the "nonroot" uid of distroless images).
user="65532:65532"

# image NAME ENV HEALTHCHECK-ADDR [SCENES]: the image magg-NAME:$tag.
image() {
    local name="magg-$1" env="$2" probe="$3" with_scenes="${4:-}"
    local ctx="$work/$name" bin="$bin_dir/magg-$1"
    [ "$1" != host ] || bin="$host_bin_dir/magg-host"
    [ -x "$bin" ] || { echo "build-images.sh: $bin is missing (build it, or pass --bin-dir)" >&2; exit 1; }
    mkdir -p "$ctx/rootfs" "$ctx/writable/out" "$ctx/writable/tmp"
    cp "$bin" "$ctx/rootfs/$name"
    if command -v strip >/dev/null; then strip "$ctx/rootfs/$name"; fi
    # Every library the loader resolves, and the loader itself, at the path ldd names
    # (symbolic links followed: the image has only the files); none for a static binary.
    local lib
    for lib in $(ldd "$bin" 2>/dev/null | grep -o '/[^ ]*' || true); do
        mkdir -p "$ctx/rootfs$(dirname "$lib")"
        cp -L "$lib" "$ctx/rootfs$lib"
    done
    if [ -n "$with_scenes" ]; then
        mkdir -p "$ctx/rootfs/scenes"
        cp -R "$with_scenes/." "$ctx/rootfs/scenes"
    fi
    # /out belongs to the image's user; /tmp is everyone's (sticky), as on any system.
    chmod 0755 "$ctx/writable/out"
    chmod 1777 "$ctx/writable/tmp"
    cat >"$ctx/Dockerfile" <<EOF
FROM scratch
COPY rootfs/ /
COPY --chown=$user writable/ /
ENV $env
USER $user
WORKDIR /out
HEALTHCHECK --interval=2s --timeout=4s --start-period=2s --retries=3 CMD ["/$name", "probe", "$probe"]
ENTRYPOINT ["/$name"]
EOF
    docker build --quiet --label org.opencontainers.image.title="$name" -t "$name:$tag" "$ctx" >/dev/null
    echo "$name:$tag ($(du -sh "$ctx/rootfs" | cut -f1) on disk)"
}

image fork "MAGG_FORK_LISTEN=0.0.0.0:7100" 127.0.0.1:7100
image node "MAGG_HEALTH_LISTEN=0.0.0.0:7200 MAGG_REPEAT=true" 127.0.0.1:7200
image host "MAGG_HOST_LISTEN=0.0.0.0:7000" 127.0.0.1:7000 "$scenes"

if [ -n "$save" ]; then
    docker save -o "$save" "magg-fork:$tag" "magg-node:$tag" "magg-host:$tag"
    echo "saved to $save"
fi
