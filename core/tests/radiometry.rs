//! Radiometry against closed forms: a point light on a plane, a mirror image, energy
//! conservation in a closed box, an occluder's shadow.

mod common;
use common::*;
use magg_core::fixed::from_fixed;
use magg_core::geometry::solid_angle;
use std::f64::consts::PI;

#[test]
fn point_light_on_a_plane_matches_i_cos_over_r2() {
    let floor = quad(v(-2.0, 0.0, -2.0), v(-2.0, 0.0, 2.0), v(2.0, 0.0, 2.0), v(2.0, 0.0, -2.0), 0, 40);
    let lp = v(0.3, 1.5, 0.2);
    let intensity = 2.0;
    let s = scene(floor, vec![material("white", 0.5, 0.0, 0.0)], vec![light(lp, intensity)]);
    let (p, out) = prepare_and_run(&s);
    let q = p.header.energy_quantum;
    let mut worst: f64 = 0.0;
    for (e, info) in p.elements.iter().enumerate() {
        let flux = from_fixed(out.element_flux[e], q).0[0];
        if !faces_towards(&s, &p, e, lp) {
            // A back element, on the side away from the light.
            assert_eq!(flux, 0.0, "element {e} faces away from the light");
            continue;
        }
        // Exact: the element receives I * Omega.
        let exact = intensity * solid_angle(lp, &element_tri(&s, &p, e));
        assert!((flux - exact).abs() <= 1e-9 * exact + 1e-12, "element {e}: {flux} vs {exact}");
        // Closed form at the centroid: E = I cos(theta) / r^2.
        let d = lp - info.centroid;
        let r2 = d.length_squared();
        let e_closed = intensity * (d.y / r2.sqrt()) / r2;
        let rel = (flux / info.area - e_closed).abs() / e_closed;
        worst = worst.max(rel);
    }
    assert!(worst < 0.01, "worst relative error {worst}");
}

#[test]
fn mirror_adds_the_mirrored_light_times_its_reflectance() {
    // Floor x in [0, 3], mirror wall at x = 0 facing +x, light at (1, 1, 0).
    let mut patches = quad(v(0.0, 0.0, -2.0), v(0.0, 0.0, 2.0), v(3.0, 0.0, 2.0), v(3.0, 0.0, -2.0), 0, 24);
    patches.extend(quad(v(0.0, 0.0, -4.0), v(0.0, 4.0, -4.0), v(0.0, 4.0, 4.0), v(0.0, 0.0, 4.0), 1, 48));
    let lp = v(1.0, 1.0, 0.0);
    let image = v(-1.0, 1.0, 0.0);
    let rho = 0.8;
    let mut s =
        scene(patches, vec![material("floor", 0.5, 0.0, 0.0), material("mirror", 0.0, rho, 0.0)], vec![light(lp, 1.0)]);
    s.settings.lrt_depth = 1;
    s.settings.light_rays = 64;
    let (p, out) = prepare_and_run(&s);
    let q = p.header.energy_quantum;
    let (mut got, mut want) = (0.0, 0.0);
    for (e, info) in p.elements.iter().enumerate() {
        if info.patch >= 2 || !faces_towards(&s, &p, e, lp) {
            continue;
        }
        let c = info.centroid;
        if !(c.x > 0.4 && c.x < 2.6 && c.z.abs() < 1.6) {
            continue;
        }
        let tri = element_tri(&s, &p, e);
        got += from_fixed(out.element_flux[e], q).0[0];
        want += solid_angle(lp, &tri) + rho * solid_angle(image, &tri);
    }
    let rel = (got - want).abs() / want;
    assert!(rel < 0.01, "floor flux {got} vs closed form {want} (relative error {rel})");
}

#[test]
fn closed_box_receives_all_of_four_pi_i() {
    let patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 6, true);
    let s = scene(patches, vec![material("white", 0.5, 0.0, 0.0)], vec![light(v(0.2, 1.3, -0.1), 3.0)]);
    let (p, out) = prepare_and_run(&s);
    let total: f64 = out.element_flux.iter().map(|f| from_fixed(*f, p.header.energy_quantum).0[0]).sum();
    let emitted = 4.0 * PI * 3.0;
    assert!((total - emitted).abs() / emitted < 1e-9, "deposited {total}, emitted {emitted}");
}

#[test]
fn flux_bookkeeping_balances_with_mirrors_and_diffuse_bounces() {
    let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 5, true);
    // Replace the back wall's material by a mirror, add a glass block inside.
    for pd in patches.iter_mut().skip(8).take(2) {
        pd.material = 1;
    }
    patches.extend(boxed(v(-0.3, 0.0, -0.3), v(0.3, 0.6, 0.3), 2, 2, false));
    let mut s = scene(
        patches,
        vec![material("white", 0.6, 0.0, 0.0), material("mirror", 0.1, 0.8, 0.0), material("glass", 0.0, 0.0, 0.9)],
        vec![light(v(0.1, 1.5, 0.2), 1.0)],
    );
    s.settings.lrt_depth = 4;
    s.settings.diffuse_bounces = 2;
    let (_, out) = prepare_and_run(&s);
    let t = out.stats.light;
    let emitted = 4.0 * PI;
    // Closed box: every direction from the light reaches some element first.
    let reached = t.reached.0[0] + t.occluded.0[0];
    assert!(t.reached.0[0] > 0.5 * emitted);
    let accounted = t.absorbed.0[0] + t.diffuse_end.0[0] + t.escaped.0[0] + t.cut.0[0];
    assert!(
        (accounted - t.reached.0[0]).abs() < 1e-9 * emitted,
        "reached {} but accounted {accounted}",
        t.reached.0[0]
    );
    // Occluded rays are covered by their occluder's pairs: reached alone sums to 4 pi I
    // up to sampling error at the glass block's silhouette.
    assert!((t.reached.0[0] - emitted).abs() / emitted < 0.01, "reached {} vs {emitted}", t.reached.0[0]);
    assert!(reached >= t.reached.0[0]);
}

#[test]
fn an_occluder_casts_a_shadow() {
    let mut patches = quad(v(-2.0, 0.0, -2.0), v(-2.0, 0.0, 2.0), v(2.0, 0.0, 2.0), v(2.0, 0.0, -2.0), 0, 40);
    // A 0.4 x 0.4 square at y = 0.5 under the light at y = 1: umbra radius ~0.2 at y = 0.
    patches.extend(quad(v(-0.2, 0.5, -0.2), v(-0.2, 0.5, 0.2), v(0.2, 0.5, 0.2), v(0.2, 0.5, -0.2), 0, 2));
    let lp = v(0.0, 1.0, 0.0);
    let s = scene(patches, vec![material("white", 0.5, 0.0, 0.0)], vec![light(lp, 1.0)]);
    let (p, out) = prepare_and_run(&s);
    let q = p.header.energy_quantum;
    let (mut dark, mut lit) = (0, 0);
    for (e, info) in p.elements.iter().enumerate() {
        if info.patch >= 2 {
            continue;
        }
        let c = info.centroid;
        let flux = from_fixed(out.element_flux[e], q).0[0];
        let r = (c.x * c.x + c.z * c.z).sqrt();
        if c.x.abs().max(c.z.abs()) < 0.3 {
            assert_eq!(flux, 0.0, "element {e} at {c:?} should be in full shadow");
            dark += 1;
        } else if c.x.abs().max(c.z.abs()) > 0.6 && r < 1.8 && faces_towards(&s, &p, e, lp) {
            let exact = solid_angle(lp, &element_tri(&s, &p, e));
            assert!((flux - exact).abs() <= 1e-9 * exact, "element {e} should be fully lit");
            lit += 1;
        }
    }
    assert!(dark > 10 && lit > 100, "dark {dark}, lit {lit}");
}
