#!/usr/bin/env bash
# magg against an independent reference that carries a point light's light through mirrors
# and glass: Mitsuba 3's particle tracer (`ptracer`). A particle tracer sees only what it
# can connect to the camera, the diffuse surfaces the camera sees directly, and it carries
# light between diffuse surfaces, which magg leaves out at `diffuse_bounces = 0`. So the
# scene is split into one scene per receiver (a shape with a diffuse part;
# deploy/mitsuba/receivers.py): receiver k keeps its material and every other receiver's
# diffuse part turns black. Receiver k's ptracer image, on the pixels wholly covered by
# receiver k, holds the light that reaches it from the lights directly or through mirrors
# and glass: together, the reference for every pixel where the camera sees a diffuse
# surface directly. magg renders the scene itself (ambient 0) and is compared on those
# pixels (`magg-host diff --mask`, one mask per receiver, relMSE weighted by pixels).
#
#   deploy/ptracer-vs-mitsuba.sh SCENE [-- MAGG/EXPORT ARGS...]
#
# e.g. scenes/cornell.toml (five walls) or scenes/caustics.toml (the floor alone, with
# one diffuse bounce: the floor's light returned to it by the mirror and the glass, which
# a receiver's image keeps). Prints both renderers' relMSE against a converged reference
# and their times, and for each magg row the time Mitsuba needs for the same error
# (deploy/mitsuba/table.py). Mitsuba's time at a sample count is the mean over the
# receivers' renders: each emits as many particles as one ptracer render of the scene.
#
# What the reference holds (REFERENCE): with `first` (the default when the scene, after
# ARGS, has `diffuse_bounces = 0`), receiver k's BSDF is wrapped in `firstdiffuse`
# (deploy/mitsuba/first_diffuse.py), so that a path ends at its diffuse bounce on the
# receiver: like for like with magg's transport. With `receiver` (the default otherwise)
# the receiver keeps reflecting, and its image also holds the light it sends back onto
# itself through mirrors and glass, which magg carries only with a diffuse bounce.
# Mitsuba runs as VARIANT, by default llvm_ad_rgb where it works (Debian libllvm19), else
# scalar_rgb (`first` is slow there: its BSDF is Python, called at every scattering).
#
# Environment: PER_RECEIVER (0; 1: magg renders each receiver's scene too, see below),
# SIZE (128), REF_SPP (4096: particles per pixel of the reference), SPPS
# ("16 64 256"), QUALITIES ("draft good final"), REPEATS (3), WORK (a temporary
# directory), REUSE_REF (1: keep the references and masks in WORK from an earlier run of
# the same scene, size, REF_SPP and REFERENCE), REFERENCE and VARIANT (above), MAGG_HOST
# (a built magg-host; default: cargo build --release).
#
# A receiver's mask: its exported scene with the receiver made an area light of radiance 1
# and the point lights removed, rendered by Mitsuba's path tracer at depth 1 (what the
# camera sees directly), so a pixel's value is the share of it covered by the receiver;
# pixels wholly covered are compared (`--mask-above 0.999`): at a pixel shared with another
# surface, the reference holds only the receiver's part.
set -euo pipefail
cd "$(dirname "$0")/.."
source deploy/mitsuba/common.sh
scene=${1:?usage: deploy/ptracer-vs-mitsuba.sh SCENE [-- ARGS...]}
shift
[[ ${1:-} == -- ]] && shift
extra=("$@")
size=${SIZE:-128}
ref_spp=${REF_SPP:-4096}
spps=(${SPPS:-16 64 256})
qualities=(${QUALITIES:-draft good final})
repeats=${REPEATS:-3}
work=${WORK:-$(mktemp -d)}
tools ptracer-vs-mitsuba
# The diffuse bounces magg carries: the scene's, or the last `--set render.diffuse_bounces=N`.
bounces=$(python3 - "$scene" "${extra[@]}" <<'PY'
import sys, tomllib
n = tomllib.load(open(sys.argv[1], "rb")).get("render", {}).get("diffuse_bounces", 0)
for a in sys.argv[2:]:
    if a.startswith("render.diffuse_bounces="):
        n = int(a.split("=", 1)[1])
print(n)
PY
)
reference=${REFERENCE:-$([[ $bounces == 0 ]] && echo first || echo receiver)}
[[ $reference == first || $reference == receiver ]] ||
  { echo "ptracer-vs-mitsuba: REFERENCE is first or receiver, not $reference" >&2; exit 2; }
choose_variant ptracer-vs-mitsuba
[[ $reference == first && $variant == scalar_* ]] &&
  echo "ptracer-vs-mitsuba: REFERENCE=first in $variant calls into Python at every scattering: slow" >&2
common=(--width "$size" --height "$size" --set 'render.ambient=[0,0,0]' "${extra[@]}")
export MAGG_ALLOW_PATH=$(cd "$(dirname "$scene")" && pwd)
python3 deploy/mitsuba/receivers.py "$scene" "$work/receivers" >"$work/receivers.json"
# Each receiver's material (which its export names) and shape (for the tables).
materials=() shapes=()
while IFS=$'\t' read -r material shape; do
  materials+=("$material")
  shapes+=("$shape")
done < <(python3 -c 'import json,sys; [print(r["material"], r["shape"], sep="\t") for r in json.load(open(sys.argv[1]))]' "$work/receivers.json")
count=${#materials[@]}
for ((k = 0; k < count; k++)); do
  "$host" export --mitsuba "$work/receivers/receiver-$k.toml" --out "$work/r$k" "${common[@]}" >&2
  # The mask scene, beside the exported one (same meshes); with REFERENCE=first, the
  # receiver's BSDF wrapped in `firstdiffuse`.
  if [[ $reference == first ]]; then
    python3 deploy/mitsuba/scene_xml.py first "$work/r$k/scene.xml" "${materials[k]}"
  fi
  python3 deploy/mitsuba/scene_xml.py mask "$work/r$k/scene.xml" "${materials[k]}" "$work/r$k/mask.xml"
done
# With PER_RECEIVER=1, magg renders each receiver's scene as Mitsuba does, OUT-r0.pfm ...,
# and its time is their mean (add `-- --set render.diffuse_bounces=1` for the light a
# receiver sends back onto itself through mirrors and glass, which the reference holds).
if [[ ${PER_RECEIVER:-0} == 1 ]]; then
  magg() { # quality out -> seconds
    local k s=()
    for ((k = 0; k < count; k++)); do s+=("$(magg_on "$work/receivers/receiver-$k.toml" "$1" "${2%.*}-r$k.${2##*.}")"); done
    mean "${s[@]}"
  }
fi
mitsuba() { # dir xml integrator depth spp out seed -> seconds
  python3 deploy/mitsuba/render.py "$1" --scene "$2" --integrator "$3" --max-depth "$4" --spp "$5" \
    --out "$6" --seed "$7" --variant "$variant" | python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"])'
}
# One ptracer render per receiver, OUT-r0.exr ...; prints the mean of their seconds.
mitsuba_at() { # spp out seed -> seconds
  local k s=()
  for ((k = 0; k < count; k++)); do s+=("$(mitsuba "$work/r$k" scene.xml ptracer -1 "$1" "${2%.exr}-r$k.exr" "$3")"); done
  mean "${s[@]}"
}
# FILE's relMSE over every receiver's pixels (Mitsuba's per-receiver images, or one magg
# image), and, with a second argument, a line per receiver: shape, pixels, relMSE, mean
# ratio to the reference.
relmse() { # file [detail]
  local k f lines=()
  for ((k = 0; k < count; k++)); do
    f=$1
    [[ $1 == */mitsuba-* || ${PER_RECEIVER:-0} == 1 ]] && f=${1%.*}-r$k.${1##*.}
    lines+=("$("$host" diff "$f" "$work/ref-r$k.exr" --mask "$work/mask-r$k.exr" --mask-above 0.999 --json)")
  done
  printf '%s\n' "${lines[@]}" | python3 deploy/mitsuba/weighted.py "$work/receivers.json" ${2:+--detail}
}

kind="$reference $ref_spp $size"
if [[ ${REUSE_REF:-0} == 1 && -f $work/ref-r$((count - 1)).exr && -f $work/mask-r$((count - 1)).exr &&
  $(cat "$work/ref-kind" 2>/dev/null) == "$kind" ]]; then
  ref_s="reused"
  echo "reference: reusing $work/ref-r*.exr and $work/mask-r*.exr" >&2
else
  for ((k = 0; k < count; k++)); do mitsuba "$work/r$k" mask.xml path 1 256 "$work/mask-r$k.exr" 0 >/dev/null; done
  echo "reference: Mitsuba ptracer ($variant), $ref_spp spp, ${size}x${size}, $count receivers, REFERENCE=$reference" >&2
  ref_s=$(mitsuba_at "$ref_spp" "$work/ref.exr" 7)
  echo "$kind" >"$work/ref-kind"
fi
pixels=$(for ((k = 0; k < count; k++)); do "$host" diff "$work/ref-r$k.exr" "$work/ref-r$k.exr" --mask "$work/mask-r$k.exr" --mask-above 0.999 --json |
  python3 -c 'import json,sys; print(json.load(sys.stdin)["pixels"])'; done | python3 -c 'import sys; print(sum(int(x) for x in sys.stdin))')
how="magg renders the scene"
[[ ${PER_RECEIVER:-0} == 1 ]] && how="magg renders each receiver's scene, time per receiver"
compare "scene $scene, $how, ${size}x${size} ($pixels pixels of $count receivers compared), extra args: ${extra[*]:-(none)}; reference Mitsuba ptracer $ref_spp spp ($ref_s s per receiver), REFERENCE=$reference" "ptracer ($variant)"
for q in "${qualities[@]}"; do
  echo "magg $q, per receiver (relMSE; light of the brightest and darkest pixels, deploy/mitsuba/regions.py):" >&2
  relmse "$work/magg-$q.pfm" detail >/dev/null
  for ((k = 0; k < count; k++)); do
    f=$work/magg-$q.pfm
    [[ ${PER_RECEIVER:-0} == 1 ]] && f=$work/magg-$q-r$k.pfm
    python3 deploy/mitsuba/regions.py "$f" "$work/ref-r$k.exr" "$work/mask-r$k.exr" "  ${shapes[k]}" >&2
  done
done
