//! Direct light at VRT (`direct = "vrt"`, the effects plan's choice for few lights)
//! against closed forms: each pixel that sees a lit plane has radiance
//! `rho / pi * I cos(theta) / r^2` exactly, shadows are sharp to the pixel, light never
//! reaches a face from behind, and the light pass then carries only what arrives via
//! specular surfaces.

mod common;
use common::*;
use glam::DVec3;
use magg_core::camera::CameraRig;
use magg_core::fixed::from_fixed;
use magg_core::geometry::solid_angle;
use magg_core::scene::{DirectLight, Scene};
use std::f64::consts::PI;

fn at_vrt(mut s: Scene) -> Scene {
    s.settings.direct = DirectLight::Auto;
    s.settings.ambient = magg_core::color::Rgb::BLACK;
    s
}

/// Where the centre ray of pixel (x, y) meets the plane y = 0, if in front.
fn floor_point(rig: &CameraRig, x: u32, y: u32) -> Option<DVec3> {
    let r = rig.ray(x as f64 + 0.5, y as f64 + 0.5);
    let t = -r.origin.y / r.direction.y;
    (t > 0.0).then(|| r.at(t))
}

#[test]
fn the_plan_puts_direct_light_at_vrt_for_few_lights() {
    let floor = quad(v(-2.0, 0.0, -2.0), v(-2.0, 0.0, 2.0), v(2.0, 0.0, 2.0), v(2.0, 0.0, -2.0), 0, 8);
    let s = at_vrt(scene(floor, vec![material("white", 0.5, 0.0, 0.0)], vec![light(v(0.0, 1.0, 0.0), 1.0)]));
    let plan = magg_core::plan::EffectsPlan::for_scene(&s);
    assert!(plan.direct_vrt && plan.passes().contains(&"vrt_direct"), "{plan}");
    let mut many = s.clone();
    many.lights = (0..=magg_core::plan::MAX_VRT_LIGHTS).map(|i| light(v(i as f64 * 0.1, 1.0, 0.0), 1.0)).collect();
    let plan = magg_core::plan::EffectsPlan::for_scene(&many);
    assert!(!plan.direct_vrt && plan.reasons.iter().any(|r| r.contains("lights (over")), "{plan}");
    let mut paper = s;
    paper.settings.direct = DirectLight::Lrt;
    assert!(!magg_core::plan::EffectsPlan::for_scene(&paper).direct_vrt);
}

#[test]
fn every_pixel_on_a_lit_plane_is_rho_over_pi_times_i_cos_over_r2() {
    let floor = quad(v(-4.0, 0.0, -4.0), v(-4.0, 0.0, 4.0), v(4.0, 0.0, 4.0), v(4.0, 0.0, -4.0), 0, 4);
    let (lp, intensity, rho) = (v(0.3, 1.5, 0.2), 2.0, 0.5);
    let s = at_vrt(scene(floor, vec![material("white", rho, 0.0, 0.0)], vec![light(lp, intensity)]));
    let (_, out) = prepare_and_run(&s);
    assert_eq!(out.stats.light.reached.0[0], 0.0, "no pair of a diffuse element is traced");
    let rig = CameraRig::new(&s.camera, s.settings.width, s.settings.height);
    let mut checked = 0;
    for y in 0..s.settings.height {
        for x in 0..s.settings.width {
            let Some(p) = floor_point(&rig, x, y) else { continue };
            if p.x.abs() > 3.9 || p.z.abs() > 3.9 {
                continue;
            }
            let d = lp - p;
            let r2 = d.length_squared();
            let want = rho / PI * intensity * (d.y / r2.sqrt()) / r2;
            let got = out.frame.get(x, y)[0] as f64;
            assert!((got - want).abs() <= 1e-6 * want, "pixel ({x}, {y}): {got} vs {want}");
            checked += 1;
        }
    }
    assert!(checked > 300, "{checked} pixels checked");
}

#[test]
fn shadows_are_sharp_to_the_pixel() {
    let mut patches = quad(v(-4.0, 0.0, -4.0), v(-4.0, 0.0, 4.0), v(4.0, 0.0, 4.0), v(4.0, 0.0, -4.0), 0, 4);
    // A 0.4 x 0.4 square at y = 0.5 under the light at y = 1: its shadow on the floor is
    // the square |x|, |z| < 0.4, one coarse element wide.
    patches.extend(quad(v(-0.2, 0.5, -0.2), v(-0.2, 0.5, 0.2), v(0.2, 0.5, 0.2), v(0.2, 0.5, -0.2), 0, 1));
    let lp = v(0.0, 1.0, 0.0);
    let mut s = at_vrt(scene(patches, vec![material("white", 0.5, 0.0, 0.0)], vec![light(lp, 1.0)]));
    s.camera.eye = v(0.0, 3.0, 0.01);
    s.camera.look_at = v(0.0, 0.0, 0.0);
    s.settings.width = 64;
    s.settings.height = 64;
    let (_, out) = prepare_and_run(&s);
    let rig = CameraRig::new(&s.camera, 64, 64);
    let (mut dark, mut lit) = (0, 0);
    for y in 0..64 {
        for x in 0..64 {
            let Some(p) = floor_point(&rig, x, y) else { continue };
            let m = p.x.abs().max(p.z.abs());
            // The occluder itself covers |x|, |z| < 0.2 in the view from above.
            let r = rig.ray(x as f64 + 0.5, y as f64 + 0.5);
            let top = r.at((0.5 - r.origin.y) / r.direction.y);
            if top.x.abs().max(top.z.abs()) < 0.2 + 1e-3 {
                continue;
            }
            let got = out.frame.get(x, y)[0];
            if m < 0.4 - 1e-3 {
                assert_eq!(got, 0.0, "pixel ({x}, {y}) at {p:?} is in the shadow");
                dark += 1;
            } else if m > 0.4 + 1e-3 {
                assert!(got > 0.0, "pixel ({x}, {y}) at {p:?} is lit");
                lit += 1;
            }
        }
    }
    assert!(dark > 20 && lit > 1000, "dark {dark}, lit {lit}");
}

#[test]
fn a_light_inside_a_closed_box_leaves_its_outside_dark() {
    let patches = boxed(v(-0.5, 0.0, -0.5), v(0.5, 1.0, 0.5), 0, 2, true);
    let mut s = at_vrt(scene(patches, vec![material("white", 0.7, 0.0, 0.0)], vec![light(v(0.0, 0.5, 0.0), 5.0)]));
    s.camera.eye = v(1.5, 2.0, 3.0);
    let (_, out) = prepare_and_run(&s);
    let (w, h) = (s.settings.width, s.settings.height);
    let brightest =
        (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| out.frame.get(x, y)[0]).fold(0.0, f32::max);
    assert_eq!(brightest, 0.0, "the box's outside receives nothing from the light inside");
}

#[test]
fn light_via_a_mirror_still_comes_from_the_light_pass() {
    // Floor x in [0, 3], mirror wall at x = 0 facing +x, light at (1, 1, 0): the floor's
    // elements hold only the mirrored light, rho * I * Omega of the light's image.
    let mut patches = quad(v(0.0, 0.0, -2.0), v(0.0, 0.0, 2.0), v(3.0, 0.0, 2.0), v(3.0, 0.0, -2.0), 0, 24);
    patches.extend(quad(v(0.0, 0.0, -4.0), v(0.0, 4.0, -4.0), v(0.0, 4.0, 4.0), v(0.0, 0.0, 4.0), 1, 48));
    let (lp, image, rho) = (v(1.0, 1.0, 0.0), v(-1.0, 1.0, 0.0), 0.8);
    let mut s = at_vrt(scene(
        patches,
        vec![material("floor", 0.5, 0.0, 0.0), material("mirror", 0.0, rho, 0.0)],
        vec![light(lp, 1.0)],
    ));
    s.settings.lrt_depth = 1;
    s.settings.light_rays = 64;
    let (p, out) = prepare_and_run(&s);
    let q = p.header.energy_quantum;
    let (mut got, mut want) = (0.0, 0.0);
    for (e, info) in p.elements.iter().enumerate() {
        if info.patch >= 2
            || !faces_towards(&s, &p, e, lp)
            || !(info.centroid.x > 0.4 && info.centroid.x < 2.6 && info.centroid.z.abs() < 1.6)
        {
            continue;
        }
        got += from_fixed(out.element_flux[e], q).0[0];
        want += rho * solid_angle(image, &element_tri(&s, &p, e));
    }
    let rel = (got - want).abs() / want;
    assert!(rel < 0.01, "floor flux {got} vs the mirrored light's {want} (relative error {rel})");
}
