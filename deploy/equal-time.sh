#!/usr/bin/env bash
# magg's quality presets against Mitsuba 3's path tracer at equal time, on the
# public-style scenes (or the scenes given), each against a converged Mitsuba reference.
#
#   deploy/equal-time.sh [SCENE...]      # default: scenes/cornell-glass.toml scenes/spheres.toml
#
# For each scene: the scene is exported (`magg-host export --mitsuba`, ambient 0), Mitsuba
# renders the reference (REF_SPP samples per pixel); magg renders each of QUALITIES
# (`--quality`, defaults chosen by magg for the knobs the scene leaves unset), timed from
# start to finish (preprocessing included); Mitsuba then renders with as many samples per
# pixel as fit in each of magg's times (from its time per sample at 16 spp). Prints one
# table per scene: relMSE = mean((a - b)^2 / (b^2 + 0.01)) against the reference
# (`magg-host diff`), and each image's mean over the reference's.
#
# Environment: SIZE (64: width = height), REF_SPP (16384), QUALITIES ("draft good final"),
# SET (more arguments for magg's renders and the export, e.g. "--set
# render.element_size=0.12"), VARIANT (scalar_rgb), WORK (a temporary directory),
# MAGG_HOST (a built magg-host; default: cargo build --release).
#
# Mitsuba's path tracer finds a small lamp through glass or water only by chance (a
# caustic seen by a path that must hit the lamp after a refraction): on scenes/water.toml
# (a 4 cm lamp under a water surface) its reference does not converge in any time a
# script can spend; give the scene a larger lamp to compare there.
set -euo pipefail
cd "$(dirname "$0")/.."
size=${SIZE:-64}
ref_spp=${REF_SPP:-16384}
qualities=(${QUALITIES:-draft good final})
variant=${VARIANT:-scalar_rgb}
work=${WORK:-$(mktemp -d)}
extra=(${SET:-})
scenes=("$@")
[[ ${#scenes[@]} -eq 0 ]] && scenes=(scenes/cornell-glass.toml scenes/spheres.toml)
source deploy/mitsuba/common.sh
tools equal-time
common=(--width "$size" --height "$size" --set 'render.ambient=[0,0,0]' "${extra[@]}")
now() { date +%s.%N; }
mitsuba() { # dir spp out seed -> seconds
  python3 deploy/mitsuba/render.py "$1" --spp "$2" --out "$3" --seed "$4" --variant "$variant" |
    python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"])'
}
# relMSE and mean ratio of an image against the reference.
score() { # image ref
  "$host" diff "$1" "$2" --json |
    python3 -c 'import json,sys; d=json.load(sys.stdin); print("%.3g %.3f" % (d["rel_mse"], d["mean_ratio"]))'
}

echo "equal-time: ${size}x${size}, reference Mitsuba path ($variant) at $ref_spp spp, $(nproc) cores, $(lscpu | sed -n 's/^Model name: *//p')"
for scene in "${scenes[@]}"; do
  name=$(basename "$scene" .toml)
  w=$work/$name
  mkdir -p "$w"
  "$host" export --mitsuba "$scene" --out "$w/mitsuba" "${common[@]}" >/dev/null
  ref_s=$(mitsuba "$w/mitsuba" "$ref_spp" "$w/ref.exr" 7)
  per_spp=$(python3 -c "print($(mitsuba "$w/mitsuba" 16 "$w/probe.exr" 3) / 16)")
  echo
  echo "### $name (reference $ref_s s)"
  echo
  echo "| magg preset | magg s | magg relMSE | magg mean/ref | Mitsuba spp | Mitsuba s | Mitsuba relMSE | Mitsuba mean/ref |"
  echo "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
  for q in "${qualities[@]}"; do
    t0=$(now)
    "$host" render "$scene" --quiet --quality "$q" --out "$w/magg-$q.exr" "${common[@]}" >/dev/null
    t=$(python3 -c "print(round($(now) - $t0, 2))")
    read -r m_err m_mean <<<"$(score "$w/magg-$q.exr" "$w/ref.exr")"
    spp=$(python3 -c "print(max(1, round($t / $per_spp)))")
    ms=$(mitsuba "$w/mitsuba" "$spp" "$w/mitsuba-$q.exr" 11)
    read -r p_err p_mean <<<"$(score "$w/mitsuba-$q.exr" "$w/ref.exr")"
    echo "| $q | $t | $m_err | $m_mean | $spp | $ms | $p_err | $p_mean |"
  done
done
