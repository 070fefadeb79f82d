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
# scene, size, REF_SPP and FIRST_DIFFUSE), FIRST_DIFFUSE (1: every BSDF wrapped in
# `firstdiffuse`, deploy/mitsuba/first_diffuse.py, so that paths end at their first
# diffuse bounce: magg's `diffuse_bounces = 0`), MASKS (material names: after the table, the
# error of each row on the pixels where the camera sees that material's shape directly,
# e.g. "mirror glass").
#
# Like for like: the ambient term is set to 0 (a physically based renderer has none), and
# the arguments after `--` go to both the export and magg's renders (e.g. `--set
# render.lrt_depth=0 --set render.vrt_depth=0` with MAX_DEPTH=2 compares direct light only,
# which Mitsuba's path tracer and magg compute alike). Mitsuba's `path` integrator cannot
# carry a point light's light through mirrors or glass (caustics): compare scenes with
# specular surfaces only in a variant where magg carries none either (lrt_depth = 0), or
# read the difference as that light. With FIRST_DIFFUSE=1 and lrt_depth = 0, what the
# camera sees in mirrors and glass is compared too: eye, mirrors and glass, then a diffuse
# surface's direct light, in both renderers (`MASKS="mirror glass"` for those pixels
# alone). Both renderers use every core.
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
if [[ ${FIRST_DIFFUSE:-0} == 1 ]]; then
  python3 deploy/mitsuba/scene_xml.py first "$work/mitsuba/scene.xml"
fi
masks=(${MASKS:-})
for m in "${masks[@]}"; do
  python3 deploy/mitsuba/scene_xml.py mask "$work/mitsuba/scene.xml" "$m" "$work/mitsuba/mask-$m.xml"
done
depth=()
[[ -n ${MAX_DEPTH:-} ]] && depth=(--max-depth "$MAX_DEPTH")
mitsuba_at() { # spp out seed -> seconds
  python3 deploy/mitsuba/render.py "$work/mitsuba" --spp "$1" --out "$2" --seed "$3" --variant "$variant" "${depth[@]}" |
    python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"])'
}
relmse() { "$host" diff "$1" "$work/ref.exr" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["rel_mse"])'; }

kind="first=${FIRST_DIFFUSE:-0} $ref_spp $size"
if [[ ${REUSE_REF:-0} == 1 && -f $work/ref.exr && $(cat "$work/ref-kind" 2>/dev/null) == "$kind" ]]; then
  ref_s="reused"
  echo "reference: reusing $work/ref.exr" >&2
else
  echo "reference: Mitsuba $variant, $ref_spp spp, ${size}x${size}" >&2
  ref_s=$(mitsuba_at "$ref_spp" "$work/ref.exr" 7)
  echo "$kind" >"$work/ref-kind"
fi
for m in "${masks[@]}"; do
  python3 deploy/mitsuba/render.py "$work/mitsuba" --scene "mask-$m.xml" --max-depth 1 --spp 64 \
    --out "$work/mask-$m.exr" --variant "$variant" >/dev/null
done
first=""
[[ ${FIRST_DIFFUSE:-0} == 1 ]] && first=", paths end at the first diffuse bounce (firstdiffuse)"
compare "scene $scene, ${size}x${size}, extra args: ${extra[*]:-(none)}; reference Mitsuba $ref_spp spp ($ref_s s)$first" "path ($variant)"
# Each row's error on the pixels where each of MASKS is seen directly.
for m in "${masks[@]}"; do
  echo
  echo "On the pixels of material \"$m\" (relMSE, mean ratio to the reference):"
  for f in "${spps[@]/#/mitsuba-}" "${qualities[@]/#/magg-}"; do
    file=$work/$f.exr
    [[ $f == magg-* ]] && file=$work/$f.pfm
    "$host" diff "$file" "$work/ref.exr" --mask "$work/mask-$m.exr" --mask-above 0.999 --json |
      python3 -c 'import json,sys; d=json.load(sys.stdin); print("  %s: %d pixels, relMSE %.3g, mean ratio %.4f" % (sys.argv[1], d["pixels"], d["rel_mse"], d["mean_ratio"]))' "$f"
  done
done
