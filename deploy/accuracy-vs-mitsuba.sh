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
# diffuse_bounces), VARIANT (scalar_rgb; llvm_ad_rgb needs Debian libllvm19), WORK (a
# temporary directory), MAGG_HOST (a built magg-host; default: cargo build --release),
# REUSE_REF (1: keep WORK/ref.exr from an earlier run of the same scene and size).
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
scene=${1:?usage: deploy/accuracy-vs-mitsuba.sh SCENE [-- ARGS...]}
shift
[[ ${1:-} == -- ]] && shift
extra=("$@")
size=${SIZE:-128}
ref_spp=${REF_SPP:-4096}
spps=(${SPPS:-4 16 64 256})
qualities=(${QUALITIES:-draft good final})
repeats=${REPEATS:-3}
variant=${VARIANT:-scalar_rgb}
work=${WORK:-$(mktemp -d)}
mkdir -p "$work"
if ! python3 -c 'import mitsuba' 2>/dev/null; then
  echo "accuracy-vs-mitsuba: mitsuba is not installed (pip install mitsuba); skipped" >&2
  exit 0
fi
host=${MAGG_HOST:-}
if [[ -z $host ]]; then
  cargo build --release --quiet -p magg-host
  host=target/release/magg-host
fi
common=(--width "$size" --height "$size" --set 'render.ambient=[0,0,0]' "${extra[@]}")
"$host" export --mitsuba "$scene" --out "$work/mitsuba" "${common[@]}" >&2
depth=()
[[ -n ${MAX_DEPTH:-} ]] && depth=(--max-depth "$MAX_DEPTH")
mitsuba() { # spp out seed -> seconds
  python3 deploy/mitsuba/render.py "$work/mitsuba" --spp "$1" --out "$2" --seed "$3" --variant "$variant" "${depth[@]}" |
    python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"])'
}
magg() { # quality out -> seconds (wall time of the whole render, preprocessing included)
  local t0 t1
  t0=$(date +%s.%N)
  "$host" render "$scene" --quiet --quality "$1" --out "$2" "${common[@]}" >/dev/null
  t1=$(date +%s.%N)
  python3 -c "print(round($t1 - $t0, 4))"
}
relmse() { "$host" diff "$1" "$work/ref.exr" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["rel_mse"])'; }
median() { python3 -c 'import sys,statistics; print(statistics.median(float(x) for x in sys.argv[1:]))' "$@"; }

if [[ ${REUSE_REF:-0} == 1 && -f $work/ref.exr ]]; then
  ref_s="reused"
  echo "reference: reusing $work/ref.exr" >&2
else
  echo "reference: Mitsuba $variant, $ref_spp spp, ${size}x${size}" >&2
  ref_s=$(mitsuba "$ref_spp" "$work/ref.exr" 7)
fi
declare -A times
for ((r = 0; r < repeats; r++)); do
  for spp in "${spps[@]}"; do times[m$spp]+=" $(mitsuba "$spp" "$work/mitsuba-$spp.exr" "$r")"; done
  for q in "${qualities[@]}"; do times[q$q]+=" $(magg "$q" "$work/magg-$q.pfm")"; done
done
echo
echo "scene $scene, ${size}x${size}, extra args: ${extra[*]:-(none)}; reference Mitsuba $ref_spp spp ($ref_s s), $(nproc) cores, $(lscpu | sed -n 's/^Model name: *//p')"
echo
rows=$work/rows.txt
: >"$rows"
for spp in "${spps[@]}"; do
  echo "mitsuba $spp $(median ${times[m$spp]}) $(relmse "$work/mitsuba-$spp.exr")" >>"$rows"
done
for q in "${qualities[@]}"; do
  echo "magg $q $(median ${times[q$q]}) $(relmse "$work/magg-$q.pfm")" >>"$rows"
done
# Mitsuba's error against the reference is its own noise plus the reference's, both
# falling as 1/spp: e(N) = c (1/N + 1/N_ref). c is the median over Mitsuba's points of
# e / (1/N + 1/N_ref), its time per spp that of the largest; each magg row then gets the
# time Mitsuba needs for the same error, and the ratio of the two times.
python3 - "$rows" "$ref_spp" "$variant" "$repeats" <<'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
n_ref, variant, repeats = float(sys.argv[2]), sys.argv[3], sys.argv[4]
mi = [(float(n), float(t), float(e)) for who, n, t, e in rows if who == "mitsuba"]
xs = [1 / n + 1 / n_ref for n, _, _ in mi]
c = statistics.median(e / x for x, (_, _, e) in zip(xs, mi))
n_top, t_top, _ = max(mi)
per_spp = t_top / n_top
print(f"Mitsuba fit: relMSE = {c:.3g} (1/spp + 1/{n_ref:.0f}), {per_spp * 1e3:.3g} ms per spp")
print()
print(f"| renderer | setting | seconds (median of {repeats}) | relMSE vs reference | Mitsuba's seconds at that relMSE | ratio |")
print("|---|---|---:|---:|---:|---:|")
for who, n, t, e in rows:
    t, e = float(t), float(e)
    if who == "mitsuba":
        print(f"| Mitsuba 3 path ({variant}) | {n} spp | {t:.3g} | {e:.3g} | | |")
        continue
    floor = c / n_ref
    if e > floor:
        tm = c / (e - floor) * per_spp
        print(f"| magg | --quality {n} | {t:.3g} | {e:.3g} | {tm:.3g} | {tm / t:.1f} |")
    else:
        print(f"| magg | --quality {n} | {t:.3g} | {e:.3g} | below the reference's noise | |")
PY
