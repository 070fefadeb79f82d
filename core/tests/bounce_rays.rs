//! Several diffuse bounce rays per light ray (`[render] bounce_rays`): with direct light at
//! VRT, a diffuse element's pairs trace light rays only to start its bounce, so each
//! light ray sends `bounce_rays` stratified bounce directions with an equal share of its
//! flux. The bounced flux must not depend on how it is split: checked against the closed
//! form of a closed box (every bounce ray lands on a wall) and between splits.

mod common;
use common::*;
use magg_core::fixed::from_fixed;
use magg_core::machine::RenderOutput;
use magg_core::prepared::PreparedScene;
use magg_core::scene::{DirectLight, Scene};
use std::f64::consts::PI;

const RHO: f64 = 0.5;
const INTENSITY: f64 = 3.0;

/// A closed white box around a point light, direct light at VRT, one diffuse bounce:
/// the elements hold only the bounce.
fn closed_box(light_rays: u32, bounce_rays: u32) -> Scene {
    let patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 6, true);
    let mut s = scene(patches, vec![material("white", RHO, 0.0, 0.0)], vec![light(v(0.2, 1.3, -0.1), INTENSITY)]);
    s.settings.direct = DirectLight::Vrt;
    s.settings.diffuse_bounces = 1;
    s.settings.light_rays = light_rays;
    s.settings.bounce_rays = bounce_rays;
    s
}

fn flux(p: &PreparedScene, out: &RenderOutput) -> Vec<f64> {
    out.element_flux.iter().map(|f| from_fixed(*f, p.header.energy_quantum).0[0]).collect()
}

#[test]
fn a_closed_box_holds_rho_times_four_pi_i_of_bounce_light_however_it_is_split() {
    let emitted = 4.0 * PI * INTENSITY;
    // 16 rays per pair: one bounce each, 4 and 16 per light ray, and 3 (which does not
    // divide 16: 6 light rays, 18 bounce rays).
    // Pairs that trace rays (the walls' back elements see none of the light's rays).
    let mut traced = None;
    for fan in [1, 3, 4, 16] {
        let (p, out) = prepare_and_run(&closed_box(16, fan));
        assert!(p.header.plan.direct_vrt, "the light's direct light is computed at VRT");
        let total: f64 = flux(&p, &out).iter().sum();
        let want = RHO * emitted;
        assert!((total - want).abs() / want < 1e-9, "bounce_rays {fan}: deposited {total}, rho 4 pi I = {want}");
        // Rays: per pair ceil(16 / fan) light rays, each with `fan` bounce rays.
        let pairs = *traced.get_or_insert(out.stats.work.light_rays / (16 * 2));
        assert!(pairs > 0 && pairs <= out.stats.work.pairs);
        let light = 16u64.div_ceil(fan as u64);
        assert_eq!(out.stats.work.light_rays, pairs * light * (1 + fan as u64), "bounce_rays {fan}");
        let t = out.stats.light;
        assert!((t.reached.0[0] - emitted).abs() / emitted < 1e-9, "reached {} of {emitted}", t.reached.0[0]);
        let accounted = t.absorbed.0[0] + t.diffuse_end.0[0] + t.escaped.0[0] + t.cut.0[0];
        assert!(
            (accounted - t.reached.0[0]).abs() < 1e-9 * emitted,
            "reached {} but accounted {accounted}",
            t.reached.0[0]
        );
    }
}

#[test]
fn splitting_the_bounce_keeps_where_it_lands_within_its_noise() {
    // The same bounce rays per pair, sent from 64 light rays or from 8 (eight each): each
    // wall receives the same share of the bounce within the sampling noise, and the
    // elements agree with each other as two independent estimates do.
    let (p1, one) = prepare_and_run(&closed_box(64, 1));
    let (p8, eight) = prepare_and_run(&closed_box(64, 8));
    let (a, b) = (flux(&p1, &one), flux(&p8, &eight));
    assert_eq!(a.len(), b.len());
    let per_patch = |f: &[f64], p: &PreparedScene| {
        let mut sums = vec![0.0; 12];
        for (e, info) in p.elements.iter().enumerate() {
            sums[info.patch as usize] += f[e];
        }
        sums
    };
    let (wa, wb) = (per_patch(&a, &p1), per_patch(&b, &p8));
    for (k, (x, y)) in wa.iter().zip(&wb).enumerate() {
        assert!((x - y).abs() / x < 0.03, "patch {k}: {x} with one bounce ray per light ray, {y} with eight");
    }
    // Element by element the two differ by their noise, not by a bias.
    let diff: f64 = a.iter().zip(&b).map(|(x, y)| y - x).sum::<f64>() / a.iter().sum::<f64>();
    assert!(diff.abs() < 1e-9, "the totals agree exactly: {diff}");
    let rel = |x: f64, y: f64| (y - x) / (0.5 * (x + y));
    let lit: Vec<(f64, f64)> = a.iter().zip(&b).filter(|(x, y)| *x + *y > 0.0).map(|(x, y)| (*x, *y)).collect();
    assert!(lit.len() * 2 >= a.len(), "the front elements hold bounce light");
    let spread = (lit.iter().map(|(x, y)| rel(*x, *y).powi(2)).sum::<f64>() / lit.len() as f64).sqrt();
    assert!(spread < 0.25, "elements differ by {spread} rms: more than the noise of 64 bounce rays per pair");
    assert!(spread > 0.0, "two different splits give different samples");
}
