#!/usr/bin/env python3
"""Edits of a scene exported by `magg-host export --mitsuba`, for the comparison scripts.

    python3 deploy/mitsuba/scene_xml.py first SCENE.xml [MATERIAL]
        wrap MATERIAL's BSDF (every shape's, without MATERIAL) in `firstdiffuse`
        (deploy/mitsuba/first_diffuse.py), in place: a path ends at its first diffuse
        bounce there, which is what magg carries with `diffuse_bounces = 0`
    python3 deploy/mitsuba/scene_xml.py mask SCENE.xml MATERIAL OUT.xml
        write OUT.xml: the scene without its point and spot lights, MATERIAL's shape an
        area light of radiance 1; rendered with `path` at depth 1 it is 1 where the
        camera sees that shape directly, the mask of `magg-host diff --mask`

The export writes each material's shape after a comment `<!-- material "NAME": ...`, its
BSDF as the shape's last element. Used by deploy/accuracy-vs-mitsuba.sh and
deploy/ptracer-vs-mitsuba.sh.
"""
import re
import sys


def shape_span(xml, material):
    """(start, end) of the text from MATERIAL's comment to the end of its shape."""
    start = xml.find(f'<!-- material "{material}"')
    if start < 0:
        sys.exit(f"scene_xml: the export has no material named {material}")
    return start, xml.index("</shape>", start)


def wrap_first(xml, material=None):
    """The scene with MATERIAL's BSDF (or every shape's) wrapped in `firstdiffuse`."""
    names = [material] if material else re.findall(r'<!-- material "([^"]+)"', xml)
    for name in names:
        start, end = shape_span(xml, name)
        lo, hi = xml.index("<bsdf", start), xml.rindex("</bsdf>", start, end) + len("</bsdf>")
        xml = xml[:lo] + '<bsdf type="firstdiffuse">' + xml[lo:hi] + "</bsdf>" + xml[hi:]
    return xml


def mask(xml, material):
    """The scene lit only by MATERIAL's shape, an area light of radiance 1."""
    xml = re.sub(r'\s*<emitter type="(point|spot)">.*?</emitter>', "", xml, flags=re.S)
    _, end = shape_span(xml, material)
    light = '<emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter>\n  '
    return xml[:end] + light + xml[end:]


def main():
    a = sys.argv[1:]
    if len(a) in (2, 3) and a[0] == "first":
        xml = open(a[1]).read()
        open(a[1], "w").write(wrap_first(xml, a[2] if len(a) == 3 else None))
    elif len(a) == 4 and a[0] == "mask":
        open(a[3], "w").write(mask(open(a[1]).read(), a[2]))
    else:
        lines = __doc__.strip().splitlines()
        sys.exit("usage:\n" + lines[2] + "\n" + lines[6])


if __name__ == "__main__":
    main()
