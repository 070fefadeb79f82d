//! Hard cases in the energy bookkeeping of the light pass: flux reached = absorbed +
//! diffuse_end + escaped + cut, to rounding, with rays cut at the depth limit (two
//! facing mirrors, a closed mirror box with closed forms per depth) and by the
//! minimum-flux rule, and every deposit landing in exactly one element.

mod common;
#[path = "common/hard.rs"]
mod hard;

use common::*;
use hard::*;
use magg_core::geometry::solid_angle;
use magg_core::lrt::MIN_RELATIVE_FLUX;
use magg_core::scene::Scene;
use std::f64::consts::PI;

/// A closed box of walls with `diffuse` and `mirror` reflectance (the rest absorbed),
/// light inside, light-pass depth `depth`.
fn mirror_box(diffuse: f64, mirror: f64, depth: u32) -> Scene {
    let patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 3, true);
    let mut s = scene(patches, vec![material("wall", diffuse, mirror, 0.0)], vec![light(v(0.13, 1.21, -0.07), 2.0)]);
    s.settings.lrt_depth = depth;
    s.settings.light_rays = 8;
    s.settings.width = 8;
    s.settings.height = 8;
    s
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

#[test]
fn closed_mirror_box_matches_closed_forms_at_every_depth() {
    let (d, m): (f64, f64) = (0.3, 0.5);
    let emitted = 4.0 * PI * 2.0;
    for depth in 0..=4u32 {
        let s = mirror_box(d, m, depth);
        let (p, out) = prepare_and_run(&s);
        assert_render_finite("mirror box", &out);
        let t = out.stats.light;
        // Every ray of a closed box stays inside: the geometric series of the mirror
        // part, truncated after `depth` bounces, the rest cut.
        let series: f64 = (0..=depth).map(|k| m.powi(k as i32)).sum();
        let reached = t.reached.0[0];
        assert!(rel(reached, emitted) < 1e-12, "depth {depth}: reached {reached} of {emitted}");
        assert_eq!(t.escaped.0[0], 0.0, "depth {depth}: flux escaped a closed box");
        assert_eq!(t.occluded.0[0], 0.0);
        assert!(rel(t.cut.0[0], reached * m.powi(depth as i32 + 1)) < 1e-12, "depth {depth}: cut {}", t.cut.0[0]);
        assert!(rel(t.absorbed.0[0], reached * (1.0 - d - m) * series) < 1e-12, "depth {depth}: absorbed");
        assert!(rel(t.diffuse_end.0[0], reached * d * series) < 1e-12, "depth {depth}: diffuse_end");
        assert!(rel(accounted(&t), reached) < 1e-12, "depth {depth}: {t:?}");
        // Deposits: every arrival, primary or not, lands in exactly one element.
        let deposited: f64 = fluxes(&p, &out).iter().sum();
        assert!(rel(deposited, reached * series) < 1e-9, "depth {depth}: deposited {deposited}");
    }
}

#[test]
fn two_facing_mirrors_balance_at_depth_limits_1_to_4() {
    // Two parallel mirror quads 1 apart, the light between them; rays bounce to and
    // fro until they leave past an edge or reach the depth limit.
    let m: f64 = 0.7;
    let build = |depth: u32| {
        let mut patches = quad(v(-1.0, 0.0, -1.0), v(-1.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, -1.0), 0, 6);
        patches.extend(quad(v(-1.0, 1.0, -1.0), v(1.0, 1.0, -1.0), v(1.0, 1.0, 1.0), v(-1.0, 1.0, 1.0), 0, 6));
        let mut s = scene(patches, vec![material("mirror", 0.2, m, 0.0)], vec![light(v(0.11, 0.43, 0.07), 1.0)]);
        s.settings.lrt_depth = depth;
        s.settings.light_rays = 8;
        s.settings.width = 8;
        s.settings.height = 8;
        s
    };
    let mut last: Option<(f64, f64, f64)> = None;
    for depth in 1..=4u32 {
        let s = build(depth);
        let (p, out) = prepare_and_run(&s);
        assert_render_finite("facing mirrors", &out);
        let t = out.stats.light;
        let reached = t.reached.0[0];
        // Nothing stands between the light and either mirror: reached = I * sum Omega.
        let lp = s.lights[0].position;
        let exact: f64 = (0..p.elements.len())
            .filter(|&e| faces_towards(&s, &p, e, lp))
            .map(|e| solid_angle(lp, &element_tri(&s, &p, e)))
            .sum();
        assert!(rel(reached, exact) < 1e-12, "depth {depth}: reached {reached} vs I Omega {exact}");
        assert!(rel(accounted(&t), reached) < 1e-12, "depth {depth}: {t:?}");
        assert!(t.cut.0[0] > 0.0 && t.escaped.0[0] > 0.0);
        let deposited: f64 = fluxes(&p, &out).iter().sum();
        if let Some((cut0, esc0, dep0)) = last {
            // The same primary rays at every depth (seeded per pair): what depth - 1
            // cut either escapes or arrives (and deposits) one bounce further.
            let moved = (t.escaped.0[0] - esc0) + (deposited - dep0);
            assert!(rel(moved, cut0) < 1e-9, "depth {depth}: cut before {cut0}, escaped + deposited now {moved}");
            assert!(t.cut.0[0] <= m * cut0 * (1.0 + 1e-12), "depth {depth}: cut grew {} vs {cut0}", t.cut.0[0]);
            assert!(t.escaped.0[0] >= esc0);
        }
        last = Some((t.cut.0[0], t.escaped.0[0], deposited));
    }
}

#[test]
fn minimum_flux_rule_cuts_where_the_closed_form_says() {
    // Mirror reflectance 0.02: the k-th bounce carries 0.02^k of its primary ray, under
    // MIN_RELATIVE_FLUX (1e-6) from k = 4 (1.6e-7) on. With a depth limit of 10 the
    // rule, not the depth, stops the rays: exactly like depth 3.
    let m: f64 = 0.02;
    assert!(m.powi(3) >= MIN_RELATIVE_FLUX && m.powi(4) < MIN_RELATIVE_FLUX);
    let by_rule = mirror_box(0.3, m, 10);
    let by_depth = mirror_box(0.3, m, 3);
    let (p1, o1) = prepare_and_run(&by_rule);
    let (_, o2) = prepare_and_run(&by_depth);
    let (t1, t2) = (o1.stats.light, o2.stats.light);
    let reached = t1.reached.0[0];
    assert!(rel(t1.cut.0[0], reached * m.powi(4)) < 1e-12, "cut {} vs {}", t1.cut.0[0], reached * m.powi(4));
    assert!(rel(accounted(&t1), reached) < 1e-12);
    // Same rays stopped: bitwise the same element energies (the f64 tally is summed
    // over node threads in arrival order, so it agrees to rounding only).
    assert_eq!(o1.element_flux, o2.element_flux, "the minimum-flux rule and depth 3 must stop the same rays");
    for (a, b) in [(t1.cut, t2.cut), (t1.absorbed, t2.absorbed), (t1.diffuse_end, t2.diffuse_end)] {
        assert!(rel(a.0[0], b.0[0]) < 1e-12, "{t1:?} vs {t2:?}");
    }
    let deposited: f64 = fluxes(&p1, &o1).iter().sum();
    let series: f64 = (0..=3).map(|k| m.powi(k)).sum();
    assert!(rel(deposited, reached * series) < 1e-9);
}

#[test]
fn fixed_point_sums_lose_at_most_half_a_quantum_per_deposit() {
    // The energy quantum is 4 pi sum(I) / 2^52; each (pair, element) deposit is rounded
    // once. Check the bound on a render with many small deposits (mirror box, depth 4).
    let s = mirror_box(0.3, 0.5, 4);
    let (p, out) = prepare_and_run(&s);
    let q = p.header.energy_quantum;
    assert_eq!(q, 4.0 * PI * 2.0 / (1u64 << 52) as f64);
    let t = out.stats.light;
    let series: f64 = (0..=4).map(|k| 0.5f64.powi(k)).sum();
    let exact = t.reached.0[0] * series;
    let fixed: i128 = out.element_flux.iter().map(|f| f[0] as i128).sum();
    let err_quanta = (fixed as f64 - exact / q).abs();
    // Deposits are merged per element within a pair, then rounded once each: count
    // them by re-tracing every pair.
    let mut view = view_of(&p);
    let mut scratch = magg_core::trace::TraceScratch::default();
    let roundings: usize = (0..p.elements.len() as u32)
        .map(|e| magg_core::lrt::trace_pair(&mut view, &mut scratch, 0, e).unwrap().deposits.len())
        .sum();
    let bound = roundings as f64 * 0.5;
    assert!(err_quanta <= bound, "{err_quanta} quanta off (bound {bound})");
    // ... and in relative terms far below anything visible.
    assert!(err_quanta * q / exact < 1e-11, "relative rounding {}", err_quanta * q / exact);
}
