#!/usr/bin/env bash
# magg against an independent reference: Mitsuba 3 (PyPI `mitsuba`) renders the same scene
# (written by `magg-host export --mitsuba`), a converged Mitsuba image is the reference, and
# both renderers' error (relMSE, `magg-host diff`) is printed against their time.
#
#   deploy/accuracy-vs-mitsuba.sh SCENE [-- MAGG/EXPORT ARGS...]
#
# Environment: SIZE (128: width = height), REF_SPP (4096), SPPS ("4 16 64 256": Mitsuba's
# points), QUALITIES ("draft good final": magg's points), REPEATS (3: medians of times,
# runs interleaved), MAX_DEPTH (Mitsuba's path depth; default the export's: vrt_depth + 2 +
# diffuse_bounces), VARIANT (default llvm_ad_rgb where it works, with Debian libllvm19,
# else scalar_rgb), WORK (a temporary directory), MAGG_HOST (a built magg-host; default:
# cargo build --release), REUSE_REF (1: keep WORK/ref.exr from an earlier run of the same
# scene and size).
#
# Like for like: the ambient term is set to 0 (a physically based renderer has none), and
# the arguments after `--` go to both the export and magg's renders (e.g. `--set
# render.lrt_depth=0 --set render.vrt_depth=0` with MAX_DEPTH=2 compares direct light only,
# which Mitsuba's path tracer and magg compute alike). Mitsuba's `path` integrator cannot
# carry a point light's light through mirrors or glass (caustics): compare scenes with
# specular surfaces only in a variant where magg carries none either (lrt_depth = 0), or
# read the difference as that light. Both renderers use every core.
set -euo pipefail
cd "$(dirname "$0")/.."
source deploy/mitsuba/common.sh
scene=${1:?usage: deploy/accuracy-vs-mitsuba.sh SCENE [-- ARGS...]}
shift
[[ ${1:-} == -- ]] && shift
extra=("$@")
size=${SIZE:-128}
ref_spp=${REF_SPP:-4096}
spps=(${SPPS:-4 16 64 256})
qualities=(${QUALITIES:-draft good final})
repeats=${REPEATS:-3}
work=${WORK:-$(mktemp -d)}
tools accuracy-vs-mitsuba
choose_variant accuracy-vs-mitsuba
common=(--width "$size" --height "$size" --set 'render.ambient=[0,0,0]' "${extra[@]}")
"$host" export --mitsuba "$scene" --out "$work/mitsuba" "${common[@]}" >&2
depth=()
[[ -n ${MAX_DEPTH:-} ]] && depth=(--max-depth "$MAX_DEPTH")
mitsuba_at() { # spp out seed -> seconds
  python3 deploy/mitsuba/render.py "$work/mitsuba" --spp "$1" --out "$2" --seed "$3" --variant "$variant" "${depth[@]}" |
    python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"])'
}
relmse() { "$host" diff "$1" "$work/ref.exr" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["rel_mse"])'; }

if [[ ${REUSE_REF:-0} == 1 && -f $work/ref.exr ]]; then
  ref_s="reused"
  echo "reference: reusing $work/ref.exr" >&2
else
  echo "reference: Mitsuba $variant, $ref_spp spp, ${size}x${size}" >&2
  ref_s=$(mitsuba_at "$ref_spp" "$work/ref.exr" 7)
fi
compare "scene $scene, ${size}x${size}, extra args: ${extra[*]:-(none)}; reference Mitsuba $ref_spp spp ($ref_s s)" "path ($variant)"
