#!/usr/bin/env bash
# magg's caustics against an independent reference: scenes/caustics.toml (cornell with
# every surface but the floor black) rendered by magg and by Mitsuba 3's particle tracer
# (`ptracer`, which carries a point light's light through the mirror and the glass onto
# the floor), compared on the floor's pixels only: a particle tracer cannot see through
# glass or in a mirror, and elsewhere the image is black in both. Prints both renderers'
# relMSE against a converged ptracer reference and their times, and for each magg row
# the time Mitsuba needs for the same error (deploy/mitsuba/table.py).
#
#   deploy/caustics-vs-mitsuba.sh [-- MAGG/EXPORT ARGS...]
#
# Environment: SIZE (128), REF_SPP (4096: particles per pixel of the reference), SPPS
# ("16 64 256"), QUALITIES ("draft good final"), REPEATS (3), WORK (a temporary
# directory), REUSE_REF (1: keep WORK/ref.exr and WORK/mask.exr), MAGG_HOST (a built
# magg-host; default: cargo build --release), SCENE (scenes/caustics.toml).
#
# The mask: the exported scene with the floor made an area light of radiance 1 and the
# point light removed, rendered by Mitsuba's path tracer at depth 1 (what the camera sees
# directly), so a pixel's value is the share of it covered by directly visible floor;
# pixels wholly floor are compared (`magg-host diff --mask`).
set -euo pipefail
cd "$(dirname "$0")/.."
source deploy/mitsuba/common.sh
[[ ${1:-} == -- ]] && shift
extra=("$@")
scene=${SCENE:-scenes/caustics.toml}
size=${SIZE:-128}
ref_spp=${REF_SPP:-4096}
spps=(${SPPS:-16 64 256})
qualities=(${QUALITIES:-draft good final})
repeats=${REPEATS:-3}
work=${WORK:-$(mktemp -d)}
tools caustics-vs-mitsuba
common=(--width "$size" --height "$size" "${extra[@]}")
"$host" export --mitsuba "$scene" --out "$work/mitsuba" "${common[@]}" >&2
# The mask scene, beside the exported one (same meshes).
python3 - "$work/mitsuba/scene.xml" "$work/mitsuba/mask.xml" <<'PY'
import re, sys
xml = open(sys.argv[1]).read()
xml = re.sub(r'\s*<emitter type="point">.*?</emitter>', "", xml, flags=re.S)
head, sep, rest = xml.partition('<!-- material "floor"')
if not sep:
    sys.exit("caustics-vs-mitsuba: the scene has no material named floor")
shape_end = rest.index("</shape>")
rest = rest[:shape_end] + '<emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter>\n  ' + rest[shape_end:]
open(sys.argv[2], "w").write(head + sep + rest)
PY
mitsuba() { # xml integrator depth spp out seed -> seconds
  python3 deploy/mitsuba/render.py "$work/mitsuba" --scene "$1" --integrator "$2" --max-depth "$3" --spp "$4" \
    --out "$5" --seed "$6" | python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"])'
}
mitsuba_at() { mitsuba scene.xml ptracer -1 "$@"; } # spp out seed -> seconds
relmse() {
  "$host" diff "$1" "$work/ref.exr" --mask "$work/mask.exr" --json |
    python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["rel_mse"])'
}

if [[ ${REUSE_REF:-0} == 1 && -f $work/ref.exr && -f $work/mask.exr ]]; then
  ref_s="reused"
  echo "reference: reusing $work/ref.exr and $work/mask.exr" >&2
else
  mitsuba mask.xml path 1 64 "$work/mask.exr" 0 >/dev/null
  echo "reference: Mitsuba ptracer, $ref_spp spp, ${size}x${size}" >&2
  ref_s=$(mitsuba_at "$ref_spp" "$work/ref.exr" 7)
fi
floor=$("$host" diff "$work/ref.exr" "$work/ref.exr" --mask "$work/mask.exr" --json |
  python3 -c 'import json,sys; print(json.load(sys.stdin)["pixels"])')
compare "scene $scene, ${size}x${size} ($floor floor pixels compared), extra args: ${extra[*]:-(none)}; reference Mitsuba ptracer $ref_spp spp ($ref_s s)" "ptracer (scalar_rgb)"
