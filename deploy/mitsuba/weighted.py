#!/usr/bin/env python3
"""One relMSE over several masked comparisons: `magg-host diff --mask M --json` reports,
one per receiver, concatenated on standard input, in the order of RECEIVERS.json (from
deploy/mitsuba/receivers.py). Prints the relMSE over all their pixels (each report's
weighted by its pixel count); with --detail, also a line per receiver on standard error.
Used by deploy/ptracer-vs-mitsuba.sh.

    magg-host diff ... --json | python3 deploy/mitsuba/weighted.py RECEIVERS.json [--detail]
"""
import json
import sys


def main():
    shapes = [r["shape"] for r in json.load(open(sys.argv[1]))]
    text, rows, dec = sys.stdin.read().strip(), [], json.JSONDecoder()
    while text:
        row, end = dec.raw_decode(text)
        rows.append(row)
        text = text[end:].strip()
    if len(rows) != len(shapes):
        sys.exit(f"weighted.py: {len(rows)} reports for {len(shapes)} receivers")
    n = sum(r["pixels"] for r in rows)
    print(sum(r["rel_mse"] * r["pixels"] for r in rows) / n)
    if "--detail" in sys.argv[2:]:
        for shape, r in zip(shapes, rows):
            ratio = r["mean_ratio"] if r["mean_ratio"] is not None else float("nan")
            print(f"  {shape:>8}: {r['pixels']:6d} pixels, relMSE {r['rel_mse']:.3e}, mean ratio {ratio:.4f}",
                  file=sys.stderr)


if __name__ == "__main__":
    main()
