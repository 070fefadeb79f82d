#!/usr/bin/env python3
"""The light of a receiver's brightest and darkest pixels, magg against the reference:
where the caustic focuses and where shadows fall, the two places an element-based
renderer blurs (a focus loses its peak, a shadow fills in).

    python3 deploy/mitsuba/regions.py MAGG REF MASK [LABEL]

Over the pixels MASK keeps (mean of channels above 0.999, as ptracer-vs-mitsuba.sh
compares), the bright region is where the reference is above twice its median (a
caustic's focus) and the dark region where it is below a fifth of it (a shadow, lit only
by what reaches it through mirrors and glass). Prints one line: each region's pixels and
the ratio of magg's summed light to the reference's (1 is exact). Images in any format
Mitsuba reads (PFM, EXR).
"""
import statistics
import sys


def load(path, mi):
    t = mi.TensorXf(mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False))
    h, w, _ = t.shape
    v = list(t.array)
    return (w, h), [v[3 * i] + v[3 * i + 1] + v[3 * i + 2] for i in range(w * h)]


def main():
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__.strip().splitlines()[4].strip())
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    (size_a, a), (size_r, r), (size_m, m) = (load(p, mi) for p in sys.argv[1:4])
    if not size_a == size_r == size_m:
        sys.exit(f"regions.py: sizes differ: {size_a}, {size_r}, {size_m}")
    kept = [i for i, x in enumerate(m) if x > 3 * 0.999]
    median = statistics.median(r[i] for i in kept)
    label = sys.argv[4] if len(sys.argv) > 4 else sys.argv[1]
    out = [label]
    for name, region in (("bright", [i for i in kept if r[i] > 2 * median]),
                         ("dark", [i for i in kept if r[i] < 0.2 * median])):
        ref = sum(r[i] for i in region)
        ratio = f"{sum(a[i] for i in region) / ref:.3f}" if ref > 0 else "n/a"
        out.append(f"{name} {len(region)} px, magg/ref {ratio}")
    print(": ".join(out[:2]) + "; " + out[2])


if __name__ == "__main__":
    main()
