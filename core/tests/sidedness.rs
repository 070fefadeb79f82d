//! Sidedness: light arriving on a patch's back is kept apart from the light on its
//! front. One-sided materials (`sides = 1`) refuse it: only the front, the side the
//! winding's normal points to, takes light, in both passes. Two-sided materials with a
//! diffuse part keep it in back elements of their own, seen only from the back. Either
//! way a light inside a closed box lights the inside and leaves the outside black, and a
//! thin panel between two lights shows each face its own light.

mod common;
use common::*;
use magg_core::fixed::from_fixed;
use magg_core::prepared::Face;
use magg_core::scene::{DirectLight, Scene};
use std::f64::consts::PI;

fn boxed_scene(one_sided: bool, direct: DirectLight) -> Scene {
    let patches = boxed(v(-0.5, 0.0, -0.5), v(0.5, 1.0, 0.5), 0, 4, true);
    let mut m = material("white", 0.7, 0.0, 0.0);
    m.one_sided = one_sided;
    let mut s = scene(patches, vec![m], vec![light(v(0.1, 0.45, -0.05), 5.0)]);
    s.camera.eye = v(1.5, 2.0, 3.0);
    s.settings.direct = direct;
    s.settings.ambient = magg_core::color::Rgb::BLACK;
    s
}

fn brightest(s: &Scene, out: &magg_core::machine::RenderOutput) -> f32 {
    let (w, h) = (s.settings.width, s.settings.height);
    (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| out.frame.get(x, y)[0]).fold(0.0, f32::max)
}

#[test]
fn one_sided_walls_keep_a_boxed_light_inside() {
    for direct in [DirectLight::Lrt, DirectLight::Vrt] {
        let s = boxed_scene(true, direct);
        let (p, out) = prepare_and_run(&s);
        assert_eq!(brightest(&s, &out), 0.0, "{direct:?}: the outside of the box is black");
        if direct == DirectLight::Lrt {
            // The inside still receives all of 4 pi I (on the walls' fronts).
            let q = p.header.energy_quantum;
            let total: f64 = out.element_flux.iter().map(|f| from_fixed(*f, q).0[0]).sum();
            let emitted = 4.0 * PI * 5.0;
            assert!((total - emitted).abs() < 1e-6 * emitted, "inside {total} vs {emitted}");
        }
    }
}

#[test]
fn two_sided_walls_keep_a_boxed_light_inside_on_their_fronts() {
    // The walls' back elements hold what arrives on their backs: nothing, here. With a
    // diffuse bounce the light deposited by secondary rays stays inside as well.
    for (direct, bounces) in [(DirectLight::Lrt, 0), (DirectLight::Lrt, 1), (DirectLight::Vrt, 1)] {
        let mut s = boxed_scene(false, direct);
        s.settings.diffuse_bounces = bounces;
        let (p, out) = prepare_and_run(&s);
        assert_eq!(brightest(&s, &out), 0.0, "{direct:?}, {bounces} bounces: the outside of the box is black");
        let backs = p.elements.iter().filter(|e| e.face == Face::Back).count();
        assert_eq!(backs * 2, p.elements.len(), "every element has a back element");
        let q = p.header.energy_quantum;
        let (mut front, mut back) = (0.0, 0.0);
        for (info, f) in p.elements.iter().zip(&out.element_flux) {
            match info.face {
                Face::Back => back += from_fixed(*f, q).0[0],
                _ => front += from_fixed(*f, q).0[0],
            }
        }
        assert_eq!(back, 0.0, "{direct:?}: nothing arrives on the walls' backs");
        if direct == DirectLight::Lrt && bounces == 0 {
            let emitted = 4.0 * PI * 5.0;
            assert!((front - emitted).abs() < 1e-6 * emitted, "inside {front} vs {emitted}");
        }
    }
}

/// A horizontal two-sided panel (front up) at y = 0 between a red light above and a
/// blue light below, seen from `eye`.
fn panel_between_two_lights(eye: glam::DVec3, direct: DirectLight) -> Scene {
    let patches = quad(v(-1.0, 0.0, -1.0), v(-1.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, -1.0), 0, 6);
    let mut red = light(v(0.2, 1.0, 0.1), 3.0);
    red.intensity = magg_core::color::Rgb::new(3.0, 0.0, 0.0);
    let mut blue = light(v(-0.1, -0.8, 0.3), 2.0);
    blue.intensity = magg_core::color::Rgb::new(0.0, 0.0, 2.0);
    let mut s = scene(patches, vec![material("panel", 0.7, 0.0, 0.0)], vec![red, blue]);
    s.camera.eye = eye;
    s.camera.look_at = v(0.0, 0.0, 0.0);
    s.camera.up = v(0.0, 0.0, -1.0);
    s.settings.direct = direct;
    s.settings.ambient = magg_core::color::Rgb::BLACK;
    s
}

#[test]
fn a_thin_two_sided_panel_shows_each_face_its_own_light() {
    for direct in [DirectLight::Lrt, DirectLight::Vrt] {
        for (eye, lit, dark, side) in [(v(0.0, 3.0, 0.0), 0, 2, "above"), (v(0.0, -3.0, 0.0), 2, 0, "below")] {
            let s = panel_between_two_lights(eye, direct);
            let (p, out) = prepare_and_run(&s);
            let (w, h) = (s.settings.width, s.settings.height);
            let mut seen = 0;
            for y in 0..h {
                for x in 0..w {
                    let px = out.frame.get(x, y);
                    assert_eq!(px[dark], 0.0, "{direct:?}, from {side}: pixel ({x}, {y}) shows the other face's light");
                    seen += (px[lit] > 0.0) as u32;
                }
            }
            assert!(seen > 100, "{direct:?}, from {side}: {seen} lit pixels");
            if direct == DirectLight::Lrt {
                // Front elements hold exactly the red light's I x Omega, back ones the blue.
                let q = p.header.energy_quantum;
                for (e, (info, f)) in p.elements.iter().zip(&out.element_flux).enumerate() {
                    let f = from_fixed(*f, q);
                    let (on, off) = if info.face == Face::Back { (2, 0) } else { (0, 2) };
                    assert_eq!(f.0[off], 0.0, "element {e} ({:?}) holds the other face's light", info.face);
                    assert!(f.0[on] > 0.0, "element {e} ({:?}) is dark", info.face);
                }
            }
        }
    }
}

#[test]
fn light_behind_a_one_sided_floor_is_absorbed_not_reflected() {
    // A floor facing up, lit from below, with a diffuse bounce: nothing is deposited on
    // it, nothing bounces off it, and what reached it is tallied as absorbed.
    let mut patches = quad(v(-1.0, 0.0, -1.0), v(-1.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, -1.0), 0, 4);
    patches.extend(quad(v(-1.0, -1.0, -1.0), v(1.0, -1.0, -1.0), v(1.0, -1.0, 1.0), v(-1.0, -1.0, 1.0), 1, 4));
    let mut floor = material("floor", 0.8, 0.0, 0.0);
    floor.one_sided = true;
    let mut s = scene(patches, vec![floor, material("below", 0.5, 0.0, 0.0)], vec![light(v(0.0, -0.5, 0.0), 1.0)]);
    s.settings.diffuse_bounces = 1;
    let (p, out) = prepare_and_run(&s);
    let q = p.header.energy_quantum;
    for (e, info) in p.elements.iter().enumerate() {
        if s.patches[info.patch as usize].material == 0 {
            assert_eq!(from_fixed(out.element_flux[e], q).0[0], 0.0, "floor element {e} got light from behind");
        }
    }
    let t = out.stats.light;
    assert!(t.absorbed.0[0] > 0.3 * t.reached.0[0], "{t:?}");
    // Seen from above (the camera is over the floor's front), the floor is black.
    let rig = magg_core::camera::CameraRig::new(&s.camera, s.settings.width, s.settings.height);
    let mut seen = 0;
    for y in 0..s.settings.height {
        for x in 0..s.settings.width {
            let r = rig.ray(x as f64 + 0.5, y as f64 + 0.5);
            let p = r.at(-r.origin.y / r.direction.y);
            if r.direction.y < 0.0 && p.x.abs() < 0.99 && p.z.abs() < 0.99 {
                assert_eq!(out.frame.get(x, y)[0], 0.0, "pixel ({x}, {y}) on the floor");
                seen += 1;
            }
        }
    }
    assert!(seen > 100, "{seen} floor pixels");
}

#[test]
fn sides_parse_and_glass_refuses_one_side() {
    let parse = |text: &str| {
        magg_core::scene::parse_scene_str("t.toml", text, std::path::Path::new("."), &|p: &std::path::Path| {
            std::fs::read(p)
        })
    };
    let base = "[camera]\neye=[0,0,3]\nlook_at=[0,0,0]\nfov=40\n[[light]]\nposition=[0,1,0]\nintensity=[1,1,1]\n\
                [[triangle]]\nvertices=[[0,0,0],[1,0,0],[0,0,1]]\nmaterial=\"m\"\n";
    let ok = format!("{base}[[material]]\nname=\"m\"\ndiffuse=[0.5,0.5,0.5]\nsides=1\n");
    let s = parse(&ok).unwrap();
    assert!(s.materials[0].one_sided);
    let glass = format!("{base}[[material]]\nname=\"m\"\ntransmit=[0.9,0.9,0.9]\nsides=1\n");
    let e = parse(&glass).unwrap_err().to_string();
    assert!(e.contains("t.toml:") && e.contains("sides"), "{e}");
    let three = format!("{base}[[material]]\nname=\"m\"\ndiffuse=[0.5,0.5,0.5]\nsides=3\n");
    assert!(parse(&three).is_err());
}
