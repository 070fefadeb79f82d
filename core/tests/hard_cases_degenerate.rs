//! Hard cases: degenerate and sliver triangles built in code (bypassing the parser's
//! checks), and a point light on or just above a surface. Nothing may produce NaN or
//! infinity, degenerate triangles never hit, and energy stays within physical bounds.

mod common;
#[path = "common/hard.rs"]
mod hard;

use common::*;
use glam::DVec3;
use hard::*;
use magg_core::geometry::{intersect_watertight, sample_spherical_triangle, solid_angle, triangle_area, Ray};
use magg_core::scene::Scene;
use magg_prepare::prepare;
use std::f64::consts::PI;

/// Zero-area triangles: a point, a segment (collinear), one with a repeated corner.
fn degenerate_triangles() -> Vec<[DVec3; 3]> {
    let p = v(0.3, 0.4, 0.1);
    vec![
        [p, p, p],
        [v(0.0, 0.2, 0.0), v(1.0, 0.2, 0.0), v(2.0, 0.2, 0.0)],
        [v(-0.5, 0.3, -0.5), v(0.5, 0.6, 0.5), v(-0.5, 0.3, -0.5)],
        [v(0.1, 0.5, 0.1), v(0.1, 0.5, 0.1), v(0.7, 0.9, -0.3)],
    ]
}

/// Thin but not degenerate triangles: width 1e-9, 1e-15, 1e-300 and subnormal 1e-310
/// across a unit length, and a needle of tiny area away from the origin.
fn sliver_triangles() -> Vec<[DVec3; 3]> {
    let mut out = Vec::new();
    for w in [1e-9, 1e-15, 1e-300, 1e-310] {
        out.push([v(-0.5, 0.25, 0.0), v(0.5, 0.25, 0.0), v(0.1, 0.25 + w, w)]);
    }
    out.push([v(0.2, 0.1, 0.2), v(0.2 + 1e-12, 0.1, 0.2), v(0.2, 0.1 + 1e-12, 1.5)]);
    out
}

#[test]
fn degenerate_triangles_are_never_hit_and_have_zero_area_and_solid_angle() {
    // Raw `intersect_watertight` may report a rounding-level hit exactly through a
    // corner of a zero-area triangle (the edge functions of collinear points are not
    // exactly zero after the shear), with finite values; preprocessing lists such
    // patches in no subspace, so `cast` never returns one.
    let mut patches = boxed(v(-2.0, -2.0, -2.0), v(2.0, 2.0, 2.0), 0, 1, true);
    let first = patches.len() as u32;
    for t in degenerate_triangles() {
        patches.push(tri(t[0], t[1], t[2], 0, 2));
    }
    let s = scene(patches, vec![material("white", 0.5, 0.0, 0.0)], vec![light(v(0.0, 1.0, 0.0), 1.0)]);
    let p = prepare(&s).unwrap();
    let mut view = view_of(&p);
    let mut rng = magg_core::rng::Rng::from_words(&[0xde9e, 1]);
    let mut raw_corner_hits = 0;
    for t in degenerate_triangles() {
        assert_eq!(triangle_area(&t), 0.0);
        for k in 0..2000 {
            // Rays aimed at points of the degenerate triangle, a third at its corners.
            let target = if k % 3 == 0 { t[k % 3] } else { t[0].lerp(t[1], rng.next_f64()).lerp(t[2], rng.next_f64()) };
            let o = v(rng.next_f64() * 3.0 - 1.5, rng.next_f64() * 3.0 - 1.5, rng.next_f64() * 3.0 - 1.5);
            let ray = Ray::new(o, target - o);
            if let Some(h) = intersect_watertight(&ray, &t, 0.0, f64::INFINITY) {
                raw_corner_hits += 1;
                assert!(h.t.is_finite() && h.bary.iter().all(|b| b.is_finite()), "{t:?}: {h:?}");
            }
            let hit = nearest(&mut view, &ray, 0.0).expect("inside a closed box");
            assert!(hit.patch < first, "degenerate patch {} was hit by {ray:?}", hit.patch);
            let omega = solid_angle(o, &t);
            assert!(omega == 0.0 || (omega.is_finite() && omega < 1e-12), "solid angle {omega} of {t:?}");
            let w = sample_spherical_triangle(o, &t, rng.next_f64(), rng.next_f64());
            assert!(w.is_none_or(|w| w.is_finite()), "sample {w:?}");
        }
    }
    println!("raw corner hits on degenerate triangles: {raw_corner_hits} of 8000");
}

#[test]
fn sliver_hits_have_finite_distance_and_barycentrics() {
    let mut rng = magg_core::rng::Rng::from_words(&[0x511e, 2]);
    for t in sliver_triangles() {
        let mut hits = 0;
        for k in 0..4000 {
            // Aim at points along the long edge and inside; half the rays straight down.
            let target = if k % 3 == 0 {
                t[0].lerp(t[1], rng.next_f64())
            } else {
                t[0].lerp(t[1], rng.next_f64()).lerp(t[2], rng.next_f64() * 0.5)
            };
            let o =
                if k % 2 == 0 { target + v(0.0, 1.0, 0.0) } else { target + v(rng.next_f64(), 1.0, rng.next_f64()) };
            let ray = Ray::new(o, target - o);
            if let Some(h) = intersect_watertight(&ray, &t, 0.0, f64::INFINITY) {
                hits += 1;
                assert!(h.t.is_finite() && h.t > 0.0, "{t:?}: t = {}", h.t);
                assert!(
                    h.bary.iter().all(|b| b.is_finite() && (0.0..=1.0).contains(b)),
                    "{t:?}: barycentrics {:?}",
                    h.bary
                );
                assert!((h.bary.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{t:?}: {:?}", h.bary);
            }
            let omega = solid_angle(o, &t);
            assert!(omega.is_finite() && omega >= 0.0);
        }
        assert!(hits > 0, "{t:?} was never hit");
    }
}

/// A closed room with degenerate and sliver patches, mirrors and glass, seen by the
/// camera: every pixel, vertex irradiance, element flux and tally entry finite.
fn room_with_bad_triangles() -> Scene {
    let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 3, true);
    for t in degenerate_triangles().into_iter().chain(sliver_triangles()) {
        for (m, n) in [(0, 1), (1, 3), (2, 2)] {
            patches.push(tri(t[0], t[1], t[2], m, n));
        }
    }
    let mut s = scene(
        patches,
        vec![material("white", 0.6, 0.0, 0.0), material("mirror", 0.1, 0.8, 0.0), material("glass", 0.0, 0.0, 0.95)],
        vec![light(v(0.1, 1.5, 0.2), 2.0), light(v(0.3, 0.4, 0.1), 1.0)],
    );
    s.camera.eye = v(0.0, 1.0, 0.9);
    s.camera.look_at = v(0.0, 0.3, 0.0);
    s.settings.lrt_depth = 4;
    s.settings.vrt_depth = 4;
    s.settings.diffuse_bounces = 1;
    s.settings.light_rays = 8;
    s.settings.pixel_samples = 2;
    s
}

#[test]
fn a_scene_with_degenerate_and_sliver_patches_renders_finite() {
    let s = room_with_bad_triangles();
    let (p, out) = prepare_and_run(&s);
    assert_render_finite("bad triangles", &out);
    // Degenerate patches carry no energy (zero solid angle, never hit); the light sits
    // exactly on a corner of one (the point triangle at (0.3, 0.4, 0.1)).
    let flux = fluxes(&p, &out);
    for (e, info) in p.elements.iter().enumerate() {
        assert!(info.area.is_finite() && info.area >= 0.0);
        if info.area == 0.0 {
            assert_eq!(flux[e], 0.0, "zero-area element {e} of patch {} got flux", info.patch);
        }
    }
    // The room is closed: its walls still take the lights' 4 pi I (1 %: the slivers'
    // silhouettes are sampled).
    let t = out.stats.light;
    let emitted = 4.0 * PI * 3.0;
    assert!((t.reached.0[0] - emitted).abs() < 0.01 * emitted, "reached {} of {emitted}", t.reached.0[0]);
    assert!((accounted(&t) - t.reached.0[0]).abs() < 1e-9 * emitted);
    assert!(out.frame.pixels.iter().any(|px| px[0] > 0.0), "the image is black");
}

/// A floor at y = 0 (two patches, 4 x 4 elements each) and a ceiling at y = 1 facing
/// down, with the light at `lp`.
fn floor_and_ceiling(lp: DVec3) -> Scene {
    let mut patches = quad(v(-1.0, 0.0, -1.0), v(-1.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, -1.0), 0, 4);
    patches.extend(quad(v(-1.0, 1.0, -1.0), v(1.0, 1.0, -1.0), v(1.0, 1.0, 1.0), v(-1.0, 1.0, 1.0), 0, 4));
    let mut s = scene(patches, vec![material("white", 0.5, 0.0, 0.0)], vec![light(lp, 1.0)]);
    s.camera.eye = v(0.0, 0.5, 3.0);
    s.camera.look_at = v(0.0, 0.5, 0.0);
    s.settings.width = 16;
    s.settings.height = 16;
    s
}

#[test]
fn a_point_light_exactly_on_a_plane_gives_that_plane_nothing() {
    // Inside an element, on an element edge, on a lattice vertex, on the diagonal shared
    // by the floor's two patches, and on the floor's outer edge.
    for lp in [v(0.13, 0.0, -0.21), v(0.1, 0.0, 0.5), v(0.5, 0.0, 0.5), v(0.3, 0.0, 0.3), v(1.0, 0.0, 0.2)] {
        let s = floor_and_ceiling(lp);
        let (p, out) = prepare_and_run(&s);
        assert_render_finite("light on the floor", &out);
        let flux = fluxes(&p, &out);
        for (e, info) in p.elements.iter().enumerate() {
            let tri = element_tri(&s, &p, e);
            if info.patch < 2 || !faces_towards(&s, &p, e, lp) {
                assert_eq!(flux[e], 0.0, "light {lp:?}: floor element {e} got {}", flux[e]);
            } else {
                let exact = solid_angle(lp, &tri);
                assert!((flux[e] - exact).abs() <= 1e-9 * exact, "light {lp:?}: ceiling element {e}");
            }
        }
    }
}

#[test]
fn the_solid_angle_of_a_triangle_from_a_point_in_its_plane_is_zero() {
    // `solid_angle` documents zero for a point in the triangle's plane; that must hold
    // for points inside the triangle and on its edges too, not only outside it.
    let t = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)];
    for p in [v(0.25, 0.25, 0.0), v(0.5, 0.0, 0.0), v(0.5, 0.5, 0.0), v(0.1, 0.7, 0.0), v(2.0, 2.0, 0.0)] {
        assert_eq!(solid_angle(p, &t), 0.0, "point {p:?} in the plane");
    }
    // Just above the inside point the solid angle approaches 2 pi, continuously.
    let above = solid_angle(v(0.25, 0.25, 1e-9), &t);
    assert!((above - 2.0 * PI).abs() < 1e-6, "{above}");
}

#[test]
fn a_point_light_just_above_a_plane_is_finite_and_bounded_by_two_pi_i() {
    for h in [1e-9, 1e-12, 1e-6] {
        for (x, z) in [(0.13, -0.21), (0.5, 0.5), (0.3, 0.3)] {
            let lp = v(x, h, z);
            let s = floor_and_ceiling(lp);
            let (p, out) = prepare_and_run(&s);
            assert_render_finite("light above the floor", &out);
            let flux = fluxes(&p, &out);
            let floor: f64 = flux.iter().zip(&p.elements).filter(|(_, i)| i.patch < 2).map(|(f, _)| f).sum();
            let ceiling: f64 = flux.iter().zip(&p.elements).filter(|(_, i)| i.patch >= 2).map(|(f, _)| f).sum();
            // The floor takes almost the whole lower hemisphere (its edge is 0.5 away at
            // most: above 2 pi minus the sliver of sky past its edges), never more.
            assert!(floor <= 2.0 * PI * (1.0 + 1e-9), "h {h}: floor {floor} > 2 pi I");
            assert!(floor > 2.0 * PI * 0.99, "h {h} at ({x}, {z}): floor only {floor}");
            let whole = solid_angle(lp, &[v(-1.0, 1.0, -1.0), v(1.0, 1.0, -1.0), v(1.0, 1.0, 1.0)])
                + solid_angle(lp, &[v(-1.0, 1.0, -1.0), v(1.0, 1.0, 1.0), v(-1.0, 1.0, 1.0)]);
            assert!((ceiling - whole).abs() < 1e-9 * whole, "h {h}: ceiling {ceiling} vs {whole}");
        }
    }
}

#[test]
fn a_point_light_on_a_tilted_plane_is_finite_and_bounded() {
    // A tilted floor: the light "on" it is only as exact as f64 allows (a rounding
    // away on either side). The plane may take anything from 0 to 2 pi I, never more.
    let (a, b, c, d) = (v(-1.0, -0.3, -1.0), v(-1.0, 0.5, 1.0), v(1.0, 0.5, 1.0), v(1.0, -0.3, -1.0));
    let mut patches = quad(a, b, c, d, 0, 5);
    patches.extend(quad(v(-1.0, 1.5, -1.0), v(1.0, 1.5, -1.0), v(1.0, 1.5, 1.0), v(-1.0, 1.5, 1.0), 0, 2));
    for (s0, s1) in [(0.3, 0.6), (0.71, 0.2), (0.5, 0.5)] {
        let lp = a.lerp(b, s0).lerp(c.lerp(d, s0), s1);
        let mut s = scene(patches.clone(), vec![material("white", 0.5, 0.0, 0.0)], vec![light(lp, 1.0)]);
        s.settings.width = 8;
        s.settings.height = 8;
        let (p, out) = prepare_and_run(&s);
        assert_render_finite("light on a tilted plane", &out);
        let flux = fluxes(&p, &out);
        let plane: f64 = flux.iter().zip(&p.elements).filter(|(_, i)| i.patch < 2).map(|(f, _)| f).sum();
        assert!(plane <= 2.0 * PI * (1.0 + 1e-9), "light {lp:?}: plane {plane} > 2 pi I");
    }
}
