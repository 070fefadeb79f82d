//! The effects plan: a pass left out costs nothing and changes nothing.

mod common;
use common::*;
use magg_core::plan::EffectsPlan;
use magg_prepare::{prepare, prepare_with_plan};

fn diffuse_scene() -> magg_core::scene::Scene {
    let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 6, true);
    patches.extend(boxed(v(-0.3, 0.0, -0.3), v(0.3, 0.6, 0.3), 1, 3, false));
    let mut s = scene(
        patches,
        vec![material("white", 0.7, 0.0, 0.0), material("grey", 0.4, 0.0, 0.0)],
        vec![light(v(0.1, 1.7, 0.2), 1.0)],
    );
    s.settings.ambient = magg_core::color::Rgb::splat(0.05);
    s
}

#[test]
fn a_purely_diffuse_scene_runs_no_secondary_rays() {
    let s = diffuse_scene();
    let plan = EffectsPlan::for_scene(&s);
    assert_eq!(plan.lrt_depth, 0);
    assert_eq!(plan.vrt_depth, 0);
    assert!(!plan.refraction);
    assert!(plan.ambient);
    assert!(plan.reasons.iter().any(|r| r.contains("secondary light rays off")));
    assert!(!plan.passes().contains(&"vrt_specular"));
}

#[test]
fn forcing_every_effect_on_gives_a_bitwise_identical_image_and_energies() {
    let s = diffuse_scene();
    let lean = prepare(&s).unwrap();
    let forced = prepare_with_plan(&s, EffectsPlan::forced_on(&s)).unwrap();
    assert!(forced.header.plan.lrt_depth > 0 && forced.header.plan.vrt_depth > 0);
    let a = run(&lean, 2, None);
    let b = run(&forced, 2, None);
    assert_eq!(a.element_flux, b.element_flux);
    assert_eq!(a.frame, b.frame);
    assert_eq!(a.stats.work.light_rays, b.stats.work.light_rays);
}

#[test]
fn forcing_effects_on_a_diffuse_bounce_scene_changes_nothing_either() {
    let mut s = diffuse_scene();
    s.settings.diffuse_bounces = 2;
    let lean = prepare(&s).unwrap();
    assert!(!lean.header.plan.ambient, "diffuse bounces replace the ambient term");
    let forced = prepare_with_plan(&s, EffectsPlan::forced_on(&s)).unwrap();
    let a = run(&lean, 1, None);
    let b = run(&forced, 3, Some(16));
    assert_eq!(a.element_flux, b.element_flux);
    assert_eq!(a.frame, b.frame);
}

#[test]
fn a_scene_with_a_mirror_turns_secondary_rays_on() {
    let mut s = diffuse_scene();
    s.materials[1] = material("mirror", 0.0, 0.9, 0.0);
    let plan = EffectsPlan::for_scene(&s);
    assert_eq!(plan.lrt_depth, s.settings.lrt_depth);
    assert_eq!(plan.vrt_depth, s.settings.vrt_depth);
    assert!(!plan.refraction);
}
