//! Area lights: patches of a material with `emit` are LRT light sources, traced as
//! (emitting element, receiving element) pairs (here with `direct = "lrt"`, their direct
//! light deposited on the elements; tests/area_closed_forms.rs checks it at VRT). Checked against closed forms (a closed
//! box takes the whole `pi L A`, a plane under a small emitter the irradiance
//! `L A cos cos / d^2`), for soft shadows, for what VRT sees of the emitter, and for
//! the bits staying the same whatever the nodes and cache.

mod common;
use common::*;
use magg_core::color::Rgb;
use magg_core::energy::element_irradiance;
use magg_core::fixed::from_fixed;
use magg_core::machine::RenderOutput;
use magg_core::scene::{Camera, DirectLight, Material, Scene};
use std::f64::consts::PI;

fn emitter(l: f64) -> Material {
    let mut m = material("lamp", 0.0, 0.0, 0.0);
    m.emit = Rgb::splat(l);
    m
}

/// A square lamp of side `a` centred on (0, y, 0), facing down, `n` elements per edge.
fn lamp(a: f64, y: f64, material: u32, n: u32) -> Vec<magg_core::scene::PatchDef> {
    let h = a / 2.0;
    quad(v(-h, y, -h), v(h, y, -h), v(h, y, h), v(-h, y, h), material, n)
}

/// A floor of side 2 at y = 0, facing up, `n` elements per edge.
fn floor(material: u32, n: u32) -> Vec<magg_core::scene::PatchDef> {
    quad(v(-1.0, 0.0, -1.0), v(-1.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, -1.0), material, n)
}

fn lit_only_by(patches: Vec<magg_core::scene::PatchDef>, materials: Vec<Material>) -> Scene {
    let mut s = scene(patches, materials, vec![]);
    s.settings.ambient = Rgb::BLACK;
    s.settings.light_rays = 64;
    s
}

fn total_flux(p: &magg_core::prepared::PreparedScene, out: &RenderOutput) -> f64 {
    out.element_flux.iter().map(|f| from_fixed(*f, p.header.energy_quantum).0[0]).sum()
}

#[test]
fn a_closed_box_receives_pi_l_a_from_an_emitter() {
    let (l, a) = (3.0, 0.3);
    for direct in [DirectLight::Lrt, DirectLight::Vrt] {
        let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 6, true);
        patches.extend(lamp(a, 1.5, 1, 2));
        let mut s = lit_only_by(patches, vec![material("white", 0.5, 0.0, 0.0), emitter(l)]);
        s.settings.direct = direct;
        let (p, out) = prepare_and_run(&s);
        assert_eq!(p.header.emitters.len(), 8, "2 triangles of 2 x 2 elements");
        assert!(p.header.plan.area_lights);
        assert_eq!(p.header.plan.direct_vrt, direct == DirectLight::Vrt);
        // Emitted power is what the header says.
        let want = PI * l * a * a;
        let power: f64 = p.header.emitters.iter().map(|e| e.power.0[0]).sum();
        assert!((power - want).abs() < 1e-9 * want);
        let got = total_flux(&p, &out);
        if direct == DirectLight::Vrt {
            // Direct light at VRT (tests/area_closed_forms.rs finds the pi L A there): the
            // elements hold none of it, and no pair is traced.
            assert_eq!(got, 0.0);
            assert_eq!(out.stats.light.reached.0[0], 0.0);
            continue;
        }
        println!("{direct:?}: box received {got} W of pi L A = {want} W ({:+.3}%)", 100.0 * (got / want - 1.0));
        assert!((got - want).abs() < 0.01 * want, "{direct:?}: the box took {got} W of {want} W");
    }
}

#[test]
fn a_plane_under_a_small_emitter_gets_the_closed_form_irradiance() {
    let (l, a, h) = (5.0, 0.05, 1.0);
    let mut patches = floor(0, 8);
    patches.extend(lamp(a, h, 1, 1));
    let s = lit_only_by(patches, vec![material("floor", 0.5, 0.0, 0.0), emitter(l)]);
    let (p, out) = prepare_and_run(&s);
    let irr = element_irradiance(&p.elements, &out.element_flux, p.header.energy_quantum);
    let (mut checked, mut worst) = (0, 0.0f64);
    for (e, info) in p.elements.iter().enumerate() {
        if s.patches[info.patch as usize].material != 0 {
            continue;
        }
        if info.face == magg_core::prepared::Face::Back {
            // The floor's back (facing down, away from the lamp) holds nothing.
            assert_eq!(irr[e].0[0], 0.0, "back element {e}");
            continue;
        }
        let d = v(0.0, h, 0.0) - info.centroid;
        let cos = h / d.length();
        let want = l * a * a * cos * cos / d.length_squared();
        let got = irr[e].0[0];
        assert!((got - want).abs() < 0.03 * want, "element {e} at {}: {got} vs {want}", info.centroid);
        checked += 1;
        worst = worst.max((got / want - 1.0).abs());
    }
    println!("largest relative error of element irradiance: {:.3}%", 100.0 * worst);
    assert_eq!(checked, 128);
}

/// Visibility of the light along the middle row of a camera looking straight down at the
/// floor from between it and the occluder: the radiance with the occluder over that
/// without it (`scene(with_occluder)`).
fn visibility_row(scene: impl Fn(bool) -> Scene) -> Vec<f32> {
    let row = |occluded: bool| {
        let mut s = scene(occluded);
        s.camera = Camera { eye: v(0.0, 0.3, 0.0), look_at: v(0.0, 0.0, 0.0), up: v(0.0, 0.0, -1.0), fov_y_deg: 120.0 };
        s.settings.width = 64;
        s.settings.height = 64;
        let (_, out) = prepare_and_run(&s);
        (0..64).map(|x| out.frame.get(x, 32)[0]).collect::<Vec<f32>>()
    };
    let (shadowed, open) = (row(true), row(false));
    assert!(open.iter().all(|&x| x > 0.0), "the floor is lit everywhere without the occluder");
    shadowed.iter().zip(&open).map(|(s, o)| s / o).collect()
}

/// Pixels that see part of the light: visibility strictly between 0.1 and 0.9.
fn penumbra(row: &[f32]) -> usize {
    row.iter().filter(|&&x| x > 0.1 && x < 0.9).count()
}

#[test]
fn an_occluder_under_an_area_light_casts_a_soft_shadow() {
    // A 0.2 m lamp at 1 m, a 0.3 m occluder at 0.5 m: umbra 0.4 m wide, a 0.2 m penumbra
    // on either side. A point light at the lamp's centre gives a hard shadow instead.
    let occluder =
        |m: u32| quad(v(-0.15, 0.5, -0.15), v(-0.15, 0.5, 0.15), v(0.15, 0.5, 0.15), v(0.15, 0.5, -0.15), m, 1);
    let (white, black) = (material("floor", 0.5, 0.0, 0.0), material("black", 0.0, 0.0, 0.0));
    let area = visibility_row(|occluded| {
        let mut patches = floor(0, 40);
        patches.extend(lamp(0.2, 1.0, 1, 2));
        if occluded {
            patches.extend(occluder(2));
        }
        lit_only_by(patches, vec![white.clone(), emitter(10.0), black.clone()])
    });
    assert!(area[32] < 0.02, "umbra under the occluder: visibility {}", area[32]);
    assert!(area[0] > 0.98 && area[63] > 0.98, "lit at the edges: {} and {}", area[0], area[63]);
    let soft = penumbra(&area);
    println!("penumbra: {soft} of 64 pixels");
    assert!(soft >= 8, "penumbra pixels {soft} in {area:?}");

    let point = visibility_row(|occluded| {
        let mut patches = floor(0, 40);
        if occluded {
            patches.extend(occluder(1));
        }
        let mut s = scene(patches, vec![white.clone(), black.clone()], vec![light(v(0.0, 1.0, 0.0), 1.0)]);
        s.settings.direct = DirectLight::Vrt;
        s.settings.ambient = Rgb::BLACK;
        s
    });
    let hard = penumbra(&point);
    assert!(hard == 0 && soft > hard, "a point light's shadow has no penumbra: {point:?}");
}

#[test]
fn vrt_sees_the_front_of_an_emitter_at_its_radiance_and_its_back_black() {
    let emit = Rgb::new(2.0, 1.0, 0.5);
    let mut m = emitter(1.0);
    m.emit = emit;
    let mut s = lit_only_by(lamp(2.0, 1.0, 0, 1), vec![m]);
    s.settings.width = 8;
    s.settings.height = 8;
    for (eye, want) in [(0.0, emit), (2.0, Rgb::BLACK)] {
        s.camera = Camera { eye: v(0.0, eye, 0.0), look_at: v(0.0, 1.0, 0.0), up: v(0.0, 0.0, -1.0), fov_y_deg: 30.0 };
        let (_, out) = prepare_and_run(&s);
        for (x, y) in [(0, 0), (4, 4), (7, 3)] {
            let px = out.frame.get(x, y);
            for c in 0..3 {
                assert_eq!(px[c], want.0[c] as f32, "eye at y = {eye}, pixel ({x}, {y})");
            }
        }
    }
}

#[test]
fn area_light_energies_do_not_depend_on_nodes_or_cache() {
    let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 4, true);
    patches.extend(lamp(0.4, 1.9, 1, 2));
    let mut mirror = material("mirror", 0.0, 0.8, 0.0);
    mirror.diffuse = Rgb::splat(0.1);
    patches.extend(quad(v(-0.3, 0.2, -0.3), v(-0.3, 0.2, 0.3), v(0.3, 0.2, 0.3), v(0.3, 0.2, -0.3), 2, 2));
    let mut s = lit_only_by(patches, vec![material("white", 0.6, 0.0, 0.0), emitter(4.0), mirror]);
    s.settings.diffuse_bounces = 1;
    let p = magg_prepare::prepare(&s).unwrap();
    let a = run(&p, 1, None);
    let b = run(&p, 3, Some(12));
    assert_eq!(a.element_flux, b.element_flux);
    assert_eq!(a.frame, b.frame);
    assert!(a.stats.work.pairs >= (p.header.emitters.len() * p.elements.len()) as u64);
}
