//! One-sided materials (`sides = 1`): only the front, the side the winding's normal points
//! to, takes light. Light arriving on the back is absorbed in both passes, so a light inside
//! a closed box of one-sided walls (normals in) lights the inside and leaves the outside
//! black, where two-sided walls glow outside with the light deposited inside.

mod common;
use common::*;
use magg_core::energy::from_fixed;
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
fn two_sided_walls_show_light_deposited_inside_from_outside() {
    // The paper's receiving: an element's energy is seen from both sides.
    let s = boxed_scene(false, DirectLight::Lrt);
    let (_, out) = prepare_and_run(&s);
    assert!(brightest(&s, &out) > 0.0);
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
