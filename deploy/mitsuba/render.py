#!/usr/bin/env python3
"""Render a scene exported by `magg-host export --mitsuba` with Mitsuba 3 (PyPI `mitsuba`).

    python3 deploy/mitsuba/render.py DIR --spp 256 --out ref.exr [--integrator path]
        [--max-depth D] [--variant scalar_rgb|llvm_ad_rgb] [--seed S] [--threads N]
        [--scene FILE.xml]

Prints one JSON line: {"spp", "seconds", "integrator", "variant", "out"}; the time is the
render alone (scene loading excluded), measured around `mi.render`. `llvm_ad_rgb` needs
LLVM (Debian `libllvm19`); `scalar_rgb` works as is. Scenes may use the `firstdiffuse`
BSDF (deploy/mitsuba/first_diffuse.py). Used by deploy/accuracy-vs-mitsuba.sh and
deploy/ptracer-vs-mitsuba.sh.
"""
import argparse
import json
import os
import sys
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", help="directory holding scene.xml (from magg-host export --mitsuba)")
    ap.add_argument("--spp", type=int, required=True)
    ap.add_argument("--out", required=True, help="output .exr")
    ap.add_argument("--integrator", default="path", help="path or ptracer (default path)")
    ap.add_argument("--scene", default="scene.xml", help="the scene file in DIR (default scene.xml)")
    ap.add_argument("--max-depth", type=int, default=None, help="default: the exported scene's")
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=0, help="0 = all cores")
    a = ap.parse_args()
    try:
        import mitsuba as mi
    except ImportError:
        sys.exit("mitsuba is not installed: pip install mitsuba")
    try:
        mi.set_variant(a.variant)
    except Exception as e:  # the variant's backend (LLVM) may be missing
        sys.exit(f"cannot use Mitsuba variant {a.variant}: {e}")
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import first_diffuse  # noqa: F401 (registers the `firstdiffuse` BSDF)
    if a.threads:
        mi.Thread.thread_count = a.threads  # noqa: best effort; older versions ignore it
    params = {"spp": str(a.spp)}
    if a.max_depth is not None:
        params["max_depth"] = str(a.max_depth)
    scene = mi.load_file(os.path.join(a.dir, a.scene), **params)
    integrator = None
    if a.integrator != "path":
        depth = a.max_depth if a.max_depth is not None else -1
        integrator = mi.load_dict({"type": a.integrator, "max_depth": depth})
    # Long renders draw a progress bar on standard output: send it to standard error, so
    # that standard output holds only the JSON line.
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        t0 = time.perf_counter()
        if integrator is None:
            img = mi.render(scene, spp=a.spp, seed=a.seed)
        else:
            img = mi.render(scene, integrator=integrator, spp=a.spp, seed=a.seed)
        bitmap = mi.Bitmap(img)
        seconds = time.perf_counter() - t0
    finally:
        os.dup2(saved, 1)
        os.close(saved)
    bitmap.write(a.out)
    print(json.dumps({"spp": a.spp, "seconds": round(seconds, 4), "integrator": a.integrator,
                      "variant": a.variant, "out": a.out}))


if __name__ == "__main__":
    main()
