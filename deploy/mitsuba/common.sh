# Shared by deploy/accuracy-vs-mitsuba.sh, deploy/ptracer-vs-mitsuba.sh and
# deploy/equal-time.sh (sourced).
# The caller sets scene, common (magg's arguments), work, spps, qualities, repeats,
# ref_spp, and defines `mitsuba_at SPP OUT SEED` (prints Mitsuba's seconds) and `relmse
# FILE` (prints FILE's relMSE against the reference).

# Makes WORK, exits 0 with a message when Mitsuba is missing, and sets host to MAGG_HOST
# or a fresh release build of magg-host.
tools() { # script name
  mkdir -p "$work"
  if ! python3 -c 'import mitsuba' 2>/dev/null; then
    echo "$1: mitsuba is not installed (pip install mitsuba); skipped" >&2
    exit 0
  fi
  host=${MAGG_HOST:-}
  if [[ -z $host ]]; then
    cargo build --release --quiet -p magg-host
    host=target/release/magg-host
  fi
}

# Sets variant to VARIANT, or else to Mitsuba's fastest CPU variant where its LLVM backend
# works (Debian libllvm19: older LLVMs load but fail to compile its kernels), about twice
# as fast as scalar_rgb, the fallback.
choose_variant() { # script name
  variant=${VARIANT:-}
  [[ -n $variant ]] && return
  if python3 -c 'import mitsuba as mi; mi.set_variant("llvm_ad_rgb"); mi.render(mi.load_dict(mi.cornell_box()), spp=1)' >/dev/null 2>&1; then
    variant=llvm_ad_rgb
  else
    variant=scalar_rgb
    echo "$1: Mitsuba's llvm_ad_rgb does not work here (apt install libllvm19); scalar_rgb, about half as fast" >&2
  fi
}

# magg's wall time for one render of a scene at a quality (start-up and preprocessing
# included); `magg` renders the caller's scene.
magg_on() { # scene quality out -> seconds
  local t0 t1
  t0=$(date +%s.%N)
  "$host" render "$1" --quiet --quality "$2" --out "$3" "${common[@]}" >/dev/null
  t1=$(date +%s.%N)
  python3 -c "print(round($t1 - $t0, 4))"
}
magg() { magg_on "$scene" "$@"; } # quality out -> seconds

mean() { python3 -c 'import sys; v=[float(x) for x in sys.argv[1:]]; print(round(sum(v)/len(v), 4))' "$@"; }
median() { python3 -c 'import sys,statistics; print(statistics.median(float(x) for x in sys.argv[1:]))' "$@"; }

# Renders both sides `repeats` times, interleaved, then prints HEADER and the table of
# medians (deploy/mitsuba/table.py) with LABEL naming Mitsuba's integrator.
compare() { # header label
  declare -A times
  local r spp q rows=$work/rows.txt
  for ((r = 0; r < repeats; r++)); do
    for spp in "${spps[@]}"; do times[m$spp]+=" $(mitsuba_at "$spp" "$work/mitsuba-$spp.exr" "$r")"; done
    for q in "${qualities[@]}"; do times[q$q]+=" $(magg "$q" "$work/magg-$q.pfm")"; done
  done
  echo
  echo "$1, $(nproc) cores, $(lscpu | sed -n 's/^Model name: *//p')"
  echo
  : >"$rows"
  for spp in "${spps[@]}"; do
    echo "mitsuba $spp $(median ${times[m$spp]}) $(relmse "$work/mitsuba-$spp.exr")" >>"$rows"
  done
  for q in "${qualities[@]}"; do
    echo "magg $q $(median ${times[q$q]}) $(relmse "$work/magg-$q.pfm")" >>"$rows"
  done
  python3 deploy/mitsuba/table.py "$rows" "$ref_spp" "$2" "$repeats"
}
