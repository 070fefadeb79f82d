#!/usr/bin/env python3
"""Print magg against Mitsuba 3 as one markdown table, with Mitsuba's time at magg's error.

    python3 deploy/mitsuba/table.py ROWS REF_SPP LABEL REPEATS

ROWS holds one line per render: `mitsuba SPP SECONDS RELMSE` or `magg QUALITY SECONDS
RELMSE`. Mitsuba's error against its own converged reference is its noise plus the
reference's, both falling as 1/spp: relMSE = c (1/spp + 1/REF_SPP), c the median over its
points; its time per spp is that of its largest point. Each magg row then gets the time
Mitsuba needs for the same error, and the ratio of the two times. Used by
deploy/accuracy-vs-mitsuba.sh and deploy/ptracer-vs-mitsuba.sh.
"""
import statistics
import sys


def main():
    path, n_ref, label, repeats = sys.argv[1], float(sys.argv[2]), sys.argv[3], sys.argv[4]
    rows = [line.split() for line in open(path) if line.strip()]
    mi = [(float(n), float(t), float(e)) for who, n, t, e in rows if who == "mitsuba"]
    c = statistics.median(e / (1 / n + 1 / n_ref) for n, _, e in mi)
    n_top, t_top, _ = max(mi)
    per_spp = t_top / n_top
    floor = c / n_ref
    print(f"Mitsuba fit: relMSE = {c:.3g} (1/spp + 1/{n_ref:.0f}), {per_spp * 1e3:.3g} ms per spp")
    print()
    print(f"| renderer | setting | seconds (median of {repeats}) | relMSE vs reference "
          "| Mitsuba's seconds at that relMSE | ratio |")
    print("|---|---|---:|---:|---:|---:|")
    for who, n, t, e in rows:
        t, e = float(t), float(e)
        if who == "mitsuba":
            print(f"| Mitsuba 3 {label} | {n} spp | {t:.3g} | {e:.3g} | | |")
        elif e > floor:
            tm = c / (e - floor) * per_spp
            print(f"| magg | --quality {n} | {t:.3g} | {e:.3g} | {tm:.3g} | {tm / t:.1f} |")
        else:
            print(f"| magg | --quality {n} | {t:.3g} | {e:.3g} | below the reference's noise | |")


if __name__ == "__main__":
    main()
