"""`firstdiffuse`, a Mitsuba 3 BSDF that ends a light path at its first diffuse bounce.

    <bsdf type="firstdiffuse"> <bsdf type="..."> ... </bsdf> </bsdf>

It wraps one BSDF and answers as it does (`eval`, `pdf`), except that a direction
sampled from a diffuse lobe carries no weight: the path ends there. Put on a receiver of
deploy/ptracer-vs-mitsuba.sh (whose other diffuse surfaces are black), a particle
tracer's image then holds only the light whose one diffuse reflection is the camera's
view of the receiver: light from the lights, directly or through mirrors and glass, and
none that the receiver sent back onto itself through them. That is what magg carries
with `diffuse_bounces = 0`. A specular lobe of the wrapped BSDF (the mirror part of a
blend) still carries the path on.

Importing this module registers the plugin for the variant already set. It is written in
Python, so Mitsuba calls back into the interpreter at every scattering in the scalar
variants; in the `llvm_ad_rgb` variant (Debian `libllvm19`) it is traced once into the
compiled kernel and costs nothing extra. Used by deploy/mitsuba/render.py.
"""
import drjit as dr
import mitsuba as mi


class FirstDiffuse(mi.BSDF):
    """The wrapped BSDF, with the weight of diffuse samples zeroed."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        nested = [o for _, o in props.objects() if isinstance(o, mi.BSDF)]
        if len(nested) != 1:
            raise ValueError(f"firstdiffuse wraps exactly one BSDF, not {len(nested)}")
        self.nested = nested[0]
        self.m_components = [self.nested.flags(i) for i in range(self.nested.component_count())]
        self.m_flags = self.nested.flags()

    def sample(self, ctx, si, sample1, sample2, active):
        bs, weight = self.nested.sample(ctx, si, sample1, sample2, active)
        diffuse = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Diffuse)
        return bs, dr.select(diffuse, mi.Color3f(0.0), weight)

    def eval(self, ctx, si, wo, active):
        return self.nested.eval(ctx, si, wo, active)

    def pdf(self, ctx, si, wo, active):
        return self.nested.pdf(ctx, si, wo, active)

    def eval_pdf(self, ctx, si, wo, active):
        return self.nested.eval_pdf(ctx, si, wo, active)

    def traverse(self, callback):
        pass

    def to_string(self):
        return f"FirstDiffuse[{self.nested}]"


mi.register_bsdf("firstdiffuse", lambda props: FirstDiffuse(props))
