#!/usr/bin/env python3
"""Split a magg scene into one scene per receiver, for a particle-tracer reference.

    python3 deploy/mitsuba/receivers.py SCENE.toml OUTDIR

A receiver is a `[[quad]]`, `[[triangle]]` or `[[mesh]]` whose material has a diffuse
part. For each receiver k this writes OUTDIR/receiver-k.toml: the scene with every other
receiver's diffuse part made black (its mirror, glass and emission kept), so that a
particle tracer's image of receiver k holds the light that reaches it from the lights
directly or through mirrors and glass, and none that another diffuse surface sent on:
what magg carries with `diffuse_bounces = 0`. Summed over the receivers, on the pixels
where each is seen directly, these images are a reference for the whole scene. (A flat
receiver cannot light itself except through a mirror or glass; that light, from the
receiver back onto itself, stays in its image: magg carries it only with a diffuse
bounce.)

Mesh paths become absolute, so run magg with MAGG_ALLOW_PATH set to the scene's folder.
The receiver keeps its material's name, which no other shape of its scene uses (the
others get a copy named NAME__dark), so `material "NAME"` finds it in the export.
Prints one JSON line: [{"file", "material", "shape"}, ...] in file order.
"""
import json
import os
import sys
import tomllib

SHAPES = ("triangle", "quad", "mesh")


def fmt(v):
    """A TOML value (the subset scene files use)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    raise ValueError(f"cannot write {v!r}")


def dump(scene):
    """The scene as TOML: its tables, then its arrays of tables in the original order."""
    out = []
    for key, val in scene.items():
        if isinstance(val, dict):
            out.append(f"[{key}]")
            out += [f"{k} = {fmt(x)}" for k, x in val.items()]
            out.append("")
    for key, val in scene.items():
        if isinstance(val, list):
            for table in val:
                out.append(f"[[{key}]]")
                out += [f"{k} = {fmt(x)}" for k, x in table.items()]
                out.append("")
    return "\n".join(out)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.strip().splitlines()[2].strip())
    path, outdir = sys.argv[1], sys.argv[2]
    with open(path, "rb") as f:
        scene = tomllib.load(f)
    scene.pop("camera_path", None)
    base = os.path.dirname(os.path.abspath(path))
    for mesh in scene.get("mesh", []):
        for key in ("file", "obj"):
            if key in mesh:
                mesh[key] = os.path.join(base, mesh[key])
    materials = {m["name"]: m for m in scene.get("material", [])}
    diffuse = {n for n, m in materials.items() if any(c > 0 for c in m.get("diffuse", [0, 0, 0]))}
    shapes = [(kind, i, s) for kind in SHAPES for i, s in enumerate(scene.get(kind, []))]
    for kind, i, s in shapes:
        if "material" not in s:
            sys.exit(f"receivers: {path}: [[{kind}]] {i + 1} takes its materials from its file; name one")
    receivers = [(kind, i, s) for kind, i, s in shapes if s["material"] in diffuse]
    if not receivers:
        sys.exit(f"receivers: {path}: no shape has a material with a diffuse part")
    darks = []
    for name in sorted(diffuse):
        dark = dict(materials[name], name=name + "__dark", diffuse=[0.0, 0.0, 0.0])
        dark.pop("texture", None)
        darks.append(dark)
    os.makedirs(outdir, exist_ok=True)
    listing = []
    for k, (kind, i, _) in enumerate(receivers):
        variant = dict(scene, material=scene["material"] + darks)
        for other in SHAPES:
            if other in scene:
                variant[other] = [dict(s) for s in scene[other]]
        for okind, oi, s in receivers:
            if (okind, oi) != (kind, i):
                variant[okind][oi]["material"] = s["material"] + "__dark"
        file = os.path.join(outdir, f"receiver-{k}.toml")
        with open(file, "w") as f:
            f.write(f"# {path} with only [[{kind}]] {i + 1} diffuse (deploy/mitsuba/receivers.py)\n")
            f.write(dump(variant))
        listing.append({"file": file, "material": scene[kind][i]["material"], "shape": f"{kind} {i + 1}"})
    print(json.dumps(listing))


if __name__ == "__main__":
    main()
