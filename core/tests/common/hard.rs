//! Helpers shared by the `hard_cases_*` tests (numerically hostile scenes and rays).
//! Included with `#[path = "common/hard.rs"] mod hard;` next to `mod common;`.
#![allow(dead_code)]

use crate::common::*;
use glam::DVec3;
use magg_core::color::Rgb;
use magg_core::fixed::from_fixed;
use magg_core::geometry::{intersect_watertight, Ray};
use magg_core::lrt::LrtTally;
use magg_core::machine::RenderOutput;
use magg_core::prepared::PreparedScene;
use magg_core::scene::Scene;
use magg_core::trace::{cast, Hit, TraceScratch};
use magg_core::view::SceneView;

/// Flux (channel 0, W) of every element.
pub fn fluxes(p: &PreparedScene, out: &RenderOutput) -> Vec<f64> {
    out.element_flux.iter().map(|f| from_fixed(*f, p.header.energy_quantum).0[0]).collect()
}

/// The offset rule of the kernels (`scatter::offset_scale`), restated here: a new
/// ray starts `1e-9 (1 + max |p|)` off the surface.
pub fn offset_rule(p: DVec3) -> f64 {
    1e-9 * (1.0 + p.abs().max_element())
}

/// `p` moved by `offset_rule(p)` along `n`.
pub fn spawn_origin(p: DVec3, n: DVec3) -> DVec3 {
    p + n * offset_rule(p)
}

/// The nearest patch by brute force over every patch (ties to the lower id): the
/// reference `trace::cast` must agree with.
pub fn brute_force(view: &mut SceneView, ray: &Ray, tmin: f64, tmax: f64) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    for pid in 0..view.header.counts.patches {
        let rec = view.patch(pid).expect("patch");
        if let Some(h) = intersect_watertight(ray, &rec.v, tmin, tmax) {
            if best.is_none_or(|b| h.t < b.t) {
                best = Some(Hit { t: h.t, patch: pid, bary: h.bary });
            }
        }
    }
    best
}

/// `trace::cast` with a fresh scratch, nearest hit, no exclusion.
pub fn nearest(view: &mut SceneView, ray: &Ray, tmin: f64) -> Option<Hit> {
    let mut scratch = TraceScratch::default();
    cast(view, &mut scratch, ray, tmin, f64::INFINITY, magg_core::trace::NO_PATCH, false).expect("cast")
}

/// True when every channel of every tally field is finite.
pub fn tally_is_finite(t: &LrtTally) -> bool {
    [t.reached, t.occluded, t.absorbed, t.diffuse_end, t.escaped, t.cut].iter().all(|c: &Rgb| c.is_finite())
}

/// `absorbed + diffuse_end + escaped + cut`, channel 0: where the reached flux went.
pub fn accounted(t: &LrtTally) -> f64 {
    t.absorbed.0[0] + t.diffuse_end.0[0] + t.escaped.0[0] + t.cut.0[0]
}

/// Asserts that every pixel, every vertex irradiance and the light tally of a render
/// are finite, and that element fluxes are non-negative and not saturated (the
/// fixed-point conversion maps NaN to 0 and clamps infinities, so the tally is where a
/// NaN in the light pass shows).
pub fn assert_render_finite(label: &str, out: &RenderOutput) {
    for (i, px) in out.frame.pixels.iter().enumerate() {
        assert!(px.iter().all(|c| c.is_finite()), "{label}: pixel {i} is {px:?}");
    }
    for (i, e) in out.vertex_irradiance.iter().enumerate() {
        assert!(e.is_finite(), "{label}: vertex {i} irradiance {e:?}");
    }
    assert!(tally_is_finite(&out.stats.light), "{label}: light tally {:?}", out.stats.light);
    for (i, f) in out.element_flux.iter().enumerate() {
        for c in f {
            assert!(*c >= 0 && *c < i64::MAX / 8, "{label}: element {i} fixed-point flux {f:?}");
        }
    }
}

/// Translates and scales every position of a scene (patches, lights, camera):
/// `p -> p * scale + offset`.
pub fn transform(s: &Scene, scale: f64, offset: DVec3) -> Scene {
    let f = |p: DVec3| p * scale + offset;
    let mut t = s.clone();
    for pd in &mut t.patches {
        pd.vertices = pd.vertices.map(f);
    }
    for l in &mut t.lights {
        l.position = f(l.position);
    }
    t.camera.eye = f(t.camera.eye);
    t.camera.look_at = f(t.camera.look_at);
    t.settings.element_size *= scale;
    t
}

/// A seeded scene of `count` random triangles (edges up to about 1) inside an
/// enclosing, inward-facing box [-2, 2]^3, traced through a fixed `dims` grid. The enclosing box
/// fixes the grid's bounds, so patches added later inside it leave the grid unchanged.
pub fn random_scene(seed: u64, count: usize, dims: [u32; 3]) -> Scene {
    let mut rng = magg_core::rng::Rng::from_words(&[seed, 0x7261_6e64]);
    let mut u = move || rng.next_f64() * 2.0 - 1.0;
    let mut patches = boxed(v(-2.0, -2.0, -2.0), v(2.0, 2.0, 2.0), 0, 1, true);
    for _ in 0..count {
        let c = v(u() * 1.5, u() * 1.5, u() * 1.5);
        let mut corner = || c + v(u(), u(), u()) * 0.6;
        let (a, b, d) = (corner(), corner(), corner());
        patches.push(tri(a, b, d, 0, 1));
    }
    let mut s = scene(patches, vec![material("white", 0.5, 0.0, 0.0)], vec![light(v(0.0, 0.0, 0.0), 1.0)]);
    s.settings.grid = magg_core::scene::GridSpec::Fixed(dims);
    s.settings.accel = magg_core::scene::Accel::Grid;
    s
}

/// Interior subspace boundaries along `axis`, computed as the traversal computes them.
pub fn cell_planes(p: &PreparedScene, axis: usize) -> Vec<f64> {
    let g = &p.header.grid;
    let cs = g.cell_size();
    (1..g.dims[axis]).map(|k| g.min[axis] + k as f64 * cs[axis]).collect()
}
