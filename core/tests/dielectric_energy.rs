//! Energy through dielectrics, against closed forms.
//!
//! - A furnace: a closed diffuse room of albedo `a` with a glass body inside, a point
//!   light, every bounce counted. Glass absorbs nothing, so the walls absorb the whole
//!   emitted power `Phi` but for the geometric tail `a^(D+1)` left after the last of `D`
//!   bounces, and the light they receive (their elements' deposits) sums to
//!   `Phi (1 + a + ... + a^D)`, within the sampling at the glass's silhouette. Light
//!   created or lost where bounced light meets the glass shows as a departure from the
//!   series.
//! - Radiance through one surface of water: a lamp under an open water surface, seen
//!   from straight above, looks `(1 - F) / n^2` as bright as it is (its light is spread
//!   over a solid angle `n^2` times wider in air); through a closed slab the factors of
//!   the way in and out cancel.

mod common;
#[path = "common/hard.rs"]
mod hard;

use common::*;
use hard::*;
use magg_core::color::Rgb;
use magg_core::scatter::fresnel_dielectric;
use magg_core::scene::{Camera, DirectLight, Scene};
use std::f64::consts::PI;

/// The furnace: a 2 m room of albedo `a` (material 0), a glass cube (material 1, ior
/// 1.5, nothing absorbed) floating inside, a point light of intensity 1, direct light
/// deposited by light rays, `bounces` diffuse bounces.
fn furnace(a: f64, bounces: u32) -> Scene {
    let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 6, true);
    patches.extend(boxed(v(-0.35, 0.3, -0.35), v(0.35, 1.0, 0.35), 1, 3, false));
    let mut s = scene(
        patches,
        vec![material("wall", a, 0.0, 0.0), material("glass", 0.0, 0.0, 1.0)],
        vec![light(v(0.13, 1.6, -0.21), 1.0)],
    );
    s.settings.diffuse_bounces = bounces;
    s.settings.lrt_depth = 32;
    s.settings.light_rays = 64;
    s.settings.ambient = Rgb::BLACK;
    s
}

#[test]
fn a_closed_diffuse_room_with_glass_inside_absorbs_what_the_light_emits() {
    let emitted = 4.0 * PI;
    for (a, bounces) in [(0.5, 16u32), (0.3, 8), (0.5, 1)] {
        let s = furnace(a, bounces);
        let (p, out) = prepare_and_run(&s);
        assert_render_finite("furnace", &out);
        let t = out.stats.light;
        assert_eq!(t.escaped.0[0], 0.0, "a closed room lets nothing escape");
        let reached = t.reached.0[0];
        // The light rays of each pair are stratified over its element; only the pairs of
        // elements the glass partly hides miss or double a little.
        assert!((reached - emitted).abs() < 0.01 * emitted, "a = {a}: reached {reached} of {emitted}");
        assert!((accounted(&t) - reached).abs() < 1e-9 * emitted, "a = {a}: {t:?}");
        // Every bounce counted: what is cut (depth limit, minimum flux) is negligible.
        assert!(t.cut.0[0] < 1e-4 * emitted, "a = {a}: cut {}", t.cut.0[0]);
        let tail = a.powi(bounces as i32 + 1);
        let absorbed = t.absorbed.0[0];
        assert!(
            (absorbed - reached * (1.0 - tail)).abs() < 1e-4 * emitted,
            "a = {a}, D = {bounces}: absorbed {absorbed}"
        );
        assert!((t.diffuse_end.0[0] - reached * tail).abs() < 1e-4 * emitted, "a = {a}: diffuse_end");
        // The walls' deposits: the geometric series, direct light included.
        let series: f64 = (0..=bounces).map(|k| a.powi(k as i32)).sum();
        let walls: f64 = fluxes(&p, &out)
            .iter()
            .zip(&p.elements)
            .filter(|(_, e)| s.patches[e.patch as usize].material == 0)
            .map(|(f, _)| f)
            .sum();
        let want = emitted * series;
        assert!((walls - want).abs() < 0.01 * want, "a = {a}, D = {bounces}: walls took {walls}, series {want}");
    }
}

/// The walls' deposits (channel 0) of a render of `s`.
fn walls(s: &Scene) -> f64 {
    let (p, out) = prepare_and_run(s);
    fluxes(&p, &out)
        .iter()
        .zip(&p.elements)
        .filter(|(_, e)| s.patches[e.patch as usize].material == 0)
        .map(|(f, _)| f)
        .sum()
}

#[test]
fn with_direct_light_at_vrt_the_walls_hold_every_bounce_and_the_light_through_the_glass() {
    // Direct light at VRT: the light rays deposit everything but the light that reaches
    // a wall straight from the lamp (the shadow rays' part); the pairs of the walls are
    // traced for their bounce alone, their light rays split into bounce rays. So the
    // walls hold what they hold with direct light deposited, less that direct part.
    let (a, bounces) = (0.5, 8);
    let all = walls(&furnace(a, bounces));
    let mut direct_only = furnace(a, 0);
    direct_only.settings.lrt_depth = 0;
    let direct = walls(&direct_only);
    let mut at_vrt = furnace(a, bounces);
    at_vrt.settings.direct = DirectLight::Vrt;
    let got = walls(&at_vrt);
    let want = all - direct;
    assert!(direct > 0.5 * 4.0 * PI, "most of the lamp's light reaches a wall straight: {direct}");
    assert!((got - want).abs() < 0.01 * all, "at VRT the walls hold {got}, want {all} - {direct} = {want}");
}

/// A lamp of radiance 1 facing up at y = 0 and, above it at y = 0.5, `cover`: the
/// camera looks straight down at it from y = 2 through a narrow field of view.
fn lamp_under(cover: Vec<magg_core::scene::PatchDef>, ior: f64) -> Scene {
    let mut lamp = material("lamp", 0.0, 0.0, 0.0);
    lamp.emit = Rgb::splat(1.0);
    let mut water = material("water", 0.0, 0.0, 1.0);
    water.ior = ior;
    let mut patches = quad(v(-2.0, 0.0, -2.0), v(-2.0, 0.0, 2.0), v(2.0, 0.0, 2.0), v(2.0, 0.0, -2.0), 0, 1);
    patches.extend(cover);
    let mut s = scene(patches, vec![lamp, water], vec![]);
    s.camera = Camera { eye: v(0.0, 2.0, 0.0), look_at: v(0.0, 0.0, 0.0), up: v(0.0, 0.0, -1.0), fov_y_deg: 2.0 };
    s.settings.width = 4;
    s.settings.height = 4;
    s.settings.vrt_depth = 8;
    s.settings.lrt_depth = 0;
    s.settings.ambient = Rgb::BLACK;
    s
}

/// The centre pixel's red channel.
fn centre(s: &Scene) -> f64 {
    let (_, out) = prepare_and_run(s);
    out.frame.get(2, 2)[0] as f64
}

#[test]
fn a_lamp_under_open_water_looks_one_over_n_squared_as_bright() {
    for ior in [1.33, 1.8] {
        let sheet = quad(v(-2.0, 0.5, -2.0), v(-2.0, 0.5, 2.0), v(2.0, 0.5, 2.0), v(2.0, 0.5, -2.0), 1, 1);
        let got = centre(&lamp_under(sheet, ior));
        // Nearly normal incidence (the pixel is within 0.25 degrees of the axis).
        let want = (1.0 - fresnel_dielectric(1.0, 1.0 / ior)) / (ior * ior);
        assert!((got - want).abs() < 1e-4 * want, "ior {ior}: {got}, closed form {want}");
    }
}

#[test]
fn a_lamp_under_a_closed_glass_slab_keeps_its_radiance_but_for_fresnel() {
    let ior = 1.5;
    let slab = boxed(v(-2.0, 0.2, -2.0), v(2.0, 0.5, 2.0), 1, 1, false);
    let got = centre(&lamp_under(slab, ior));
    // In at the top, out at the bottom: (1 - F)^2; light reflected inside goes up again
    // and leaves towards the black sky or returns (F^2 of it) to the lamp.
    let f = fresnel_dielectric(1.0, 1.0 / ior);
    let want = (1.0 - f) * (1.0 - f) / (1.0 - f * f);
    assert!((got - want).abs() < 1e-4 * want, "{got}, closed form {want}");
}
