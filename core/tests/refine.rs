//! Adaptive element refinement (`[render] refine`): elements split in four keep the
//! light of their parent (flux conserved across a split, against the closed form of a
//! point light), refinement chooses the elements along a shadow's edge, the irradiance
//! stays continuous across a T-junction, the image comes closer to a finer render,
//! pilots that trace each pair once choose the splits of pilots that trace every level,
//! and the light pass that bins the pilots' pairs gives the bits of tracing them.

mod common;
use common::*;
use magg_core::fixed::from_fixed;
use magg_core::plan::EffectsPlan;
use magg_core::prepared::PreparedScene;
use magg_core::scene::Scene;
use magg_prepare::{prepare_split, refine};

/// A 2 x 2 floor (n = 8 per triangle) under a point light, with a small square blocker
/// between them when `blocker`.
fn floor_scene(blocker: bool) -> Scene {
    let mut patches = quad(v(-1.0, 0.0, -1.0), v(-1.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, -1.0), 0, 8);
    if blocker {
        patches.extend(quad(v(-0.3, 0.5, -0.3), v(0.3, 0.5, -0.3), v(0.3, 0.5, 0.3), v(-0.3, 0.5, 0.3), 0, 1));
    }
    let mut s = scene(patches, vec![material("white", 0.7, 0.0, 0.0)], vec![light(v(0.05, 1.0, 0.02), 2.0)]);
    s.camera.eye = v(0.0, 2.5, 1.5);
    s.camera.look_at = v(0.0, 0.0, 0.0);
    s.settings.ambient = magg_core::color::Rgb::BLACK;
    s.settings.light_rays = 32;
    s
}

fn total_flux(p: &PreparedScene, flux: &[[i64; 3]]) -> f64 {
    let q = p.header.energy_quantum;
    p.elements.iter().zip(flux).filter(|(e, _)| e.is_leaf()).map(|(_, f)| from_fixed(*f, q).0[0]).sum()
}

#[test]
fn a_split_keeps_its_parents_flux_and_the_closed_form() {
    // Unoccluded: each pair deposits I times the element's solid angle exactly, so the
    // four children of a split element hold what it held, to rounding.
    let s = floor_scene(false);
    let plan = EffectsPlan::for_scene(&s);
    let base = prepare_split(&s, plan.clone(), &[]).unwrap();
    let lattice = base.elements.len() as u32;
    let first: Vec<u32> = (0..lattice).step_by(3).collect();
    let second: Vec<u32> = (lattice..lattice + 4 * first.len() as u32).step_by(2).collect();
    let split = prepare_split(&s, plan, &[first.clone(), second.clone()]).unwrap();
    assert_eq!(split.elements.len(), base.elements.len() + 4 * (first.len() + second.len()));
    let (a, b) = (run(&base, 2, None), run(&split, 2, None));
    let (fa, fb) = (total_flux(&base, &a.element_flux), total_flux(&split, &b.element_flux));
    assert!((fa - fb).abs() <= 1e-9 * fa, "flux {fa} before the splits, {fb} after");
    // Element by element: a split element's leaves sum to its own flux before the split.
    let q = base.header.energy_quantum;
    let leaves_under = |e: u32| -> f64 {
        let mut stack = vec![e];
        let mut sum = 0.0;
        while let Some(x) = stack.pop() {
            let info = split.elements[x as usize];
            if info.is_leaf() {
                sum += from_fixed(b.element_flux[x as usize], q).0[0];
            } else {
                stack.extend(info.child..info.child + 4);
            }
        }
        sum
    };
    for &e in &first {
        let before = from_fixed(a.element_flux[e as usize], q).0[0];
        assert!((leaves_under(e) - before).abs() <= 1e-9 * before.max(1e-30), "element {e}");
        assert_eq!(b.element_flux[e as usize], [0, 0, 0], "a split element holds nothing itself");
    }
    // The closed form: the floor's flux is I times its solid angle seen from the light.
    let omega: f64 =
        s.patches.iter().map(|p| magg_core::geometry::solid_angle(s.lights[0].position, &p.vertices)).sum();
    assert!((fb - 2.0 * omega).abs() <= 1e-9 * fb, "flux {fb} against I omega {}", 2.0 * omega);
    // Areas: children tile their parent.
    for &e in &first {
        let info = split.elements[e as usize];
        let children: f64 = (info.child..info.child + 4).map(|c| split.elements[c as usize].area).sum();
        assert!((children - info.area).abs() <= 1e-12 * info.area);
    }
}

#[test]
fn bounce_only_pairs_cast_as_many_rays_per_unit_area_after_a_split() {
    // Direct light at VRT, one diffuse bounce: a diffuse element's pair is traced only
    // for the bounce its rays start. A child of depth d casts 32 / 4^d rays, so splits
    // leave the rays (one bounce each, none escaping a floor under a closed lid) and the
    // flux that bounces unchanged. (With one bounce ray per light ray, so that the rays
    // counted are twice the bounce rays; several per light ray round each pair's light
    // rays up, checked below.)
    let mut s = floor_scene(false);
    s.settings.diffuse_bounces = 1;
    s.settings.bounce_rays = 1;
    s.settings.direct = magg_core::scene::DirectLight::Vrt;
    // Deposits descend to the leaf under the hit when the scene refines.
    s.settings.refine = 2;
    s.patches.extend(quad(v(-1.0, 2.0, -1.0), v(1.0, 2.0, -1.0), v(1.0, 2.0, 1.0), v(-1.0, 2.0, 1.0), 0, 2));
    let plan = EffectsPlan::for_scene(&s);
    assert!(!plan.deposits_direct(), "direct light at VRT");
    let base = prepare_split(&s, plan.clone(), &[]).unwrap();
    let lattice = base.elements.len() as u32;
    let first: Vec<u32> = (0..lattice).step_by(3).collect();
    let second: Vec<u32> = (lattice..lattice + 4 * first.len() as u32).step_by(2).collect();
    let split = prepare_split(&s, plan, &[first, second]).unwrap();
    let (a, b) = (run(&base, 2, None), run(&split, 2, None));
    let rays = |o: &magg_core::machine::RenderOutput| o.stats.work.light_rays;
    assert_eq!(rays(&a), rays(&b), "light rays before and after the splits");
    assert!(rays(&a) > 0);
    let (fa, fb) = (total_flux(&base, &a.element_flux), total_flux(&split, &b.element_flux));
    assert!((fa - fb).abs() <= 0.05 * fa, "bounced flux {fa} before the splits, {fb} after");
    // Eight bounce rays per light ray: the same bounce rays from fewer light rays, and the
    // same flux lands on the lid within the sampling noise.
    for (scene, one) in [(&base, fa), (&split, fb)] {
        let mut eight = scene.clone();
        std::sync::Arc::make_mut(&mut eight.header).settings.bounce_rays = 8;
        let o = run(&eight, 2, None);
        let f = total_flux(&eight, &o.element_flux);
        assert!((f - one).abs() <= 0.05 * one, "bounced flux {f} with eight bounce rays per light ray, {one} with one");
        assert!(o.stats.work.light_rays < rays(&a), "fewer rays: {} against {}", o.stats.work.light_rays, rays(&a));
    }
}

#[test]
fn refinement_splits_the_elements_along_a_shadows_edge() {
    let mut s = floor_scene(true);
    s.settings.refine = 1;
    let p = refine::prepare(&s, EffectsPlan::for_scene(&s)).unwrap();
    assert_eq!(p.splits.len(), 1);
    let split = &p.splits[0];
    let floor_elements = 2 * 64;
    assert!(!split.is_empty() && split.len() < floor_elements * 3 / 4, "{} of {floor_elements} split", split.len());
    // The shadow of the blocker (|x|, |z| <= 0.3 at y = 0.5) under the light at height
    // 1: a square of half-width 0.6 around the light's foot. Elements on both sides of
    // the edge are split (a lit element beside a dark one has a contrast of 1), so every
    // split element lies within two elements' size (0.25 on a side) of the edge; the
    // floor's far corners, in smooth light, are left alone.
    let l = s.lights[0].position;
    for &e in split {
        let c = p.elements[e as usize].centroid;
        let edge_x = ((c.x - 2.0 * 0.3 - l.x).abs()).min((c.x + 2.0 * 0.3 - l.x).abs());
        let edge_z = ((c.z - 2.0 * 0.3 - l.z).abs()).min((c.z + 2.0 * 0.3 - l.z).abs());
        let inside = |a: f64, la: f64| (a - la).abs() <= 0.6 + 0.5;
        let near = (edge_x <= 0.5 && inside(c.z, l.z)) || (edge_z <= 0.5 && inside(c.x, l.x));
        assert!(near, "element {e} at {c} is not by the shadow's edge");
    }
}

#[test]
fn irradiance_is_continuous_across_a_t_junction() {
    let mut s = floor_scene(true);
    s.settings.refine = 2;
    let p = refine::prepare(&s, EffectsPlan::for_scene(&s)).unwrap();
    assert!(!p.t_junctions.is_empty(), "a partial refinement leaves T-junctions");
    let out = run(&p, 2, None);
    for &[a, b, m] in &p.t_junctions {
        let (ea, eb, em) =
            (out.vertex_irradiance[a as usize], out.vertex_irradiance[b as usize], out.vertex_irradiance[m as usize]);
        assert_eq!(em, ea.add(eb).scale(0.5), "midpoint {m} of {a}, {b}");
    }
    // Shading reads the leaf under a hit: every pixel is finite and the lit floor is lit.
    assert!(out.frame.pixels.iter().all(|p| p.iter().all(|c| c.is_finite())));
    let mut view = view_of(&p);
    for (id, info) in p.elements.iter().enumerate().filter(|(_, e)| e.parent != magg_core::prepared::NO_PARENT) {
        let rec = view.element(id as u32).unwrap();
        let (_, _, tri) = view.element_geometry(id as u32, rec).unwrap();
        let c = (tri[0] + tri[1] + tri[2]) / 3.0;
        assert!((c - info.centroid).length() < 1e-12, "element {id}: the geometry nodes read is the host's");
    }
}

#[test]
fn refinement_brings_the_image_closer_to_a_finer_render() {
    let mut fine = floor_scene(true);
    fine.patches = fine
        .patches
        .into_iter()
        .map(|mut p| {
            p.subdivisions = p.subdivisions.map(|n| n * 8);
            p
        })
        .collect();
    let (_, reference) = prepare_and_run(&fine);
    let error = |refine_levels: u32| {
        let mut s = floor_scene(true);
        s.settings.refine = refine_levels;
        let p = refine::prepare(&s, EffectsPlan::for_scene(&s)).unwrap();
        let out = run(&p, 2, None);
        let (a, b) = (&out.frame.pixels, &reference.frame.pixels);
        a.iter().zip(b).map(|(x, y)| ((x[0] - y[0]) as f64).powi(2) / ((y[0] as f64).powi(2) + 0.01)).sum::<f64>()
            / a.len() as f64
    };
    let (e0, e2) = (error(0), error(2));
    assert!(e2 < 0.5 * e0, "relMSE {e0} without refinement, {e2} with two levels");
}

#[test]
fn pilots_that_trace_each_pair_once_split_as_pilots_that_trace_every_level() {
    // The floor and blocker, and a mirror beside them sending light back onto the floor:
    // pairs of direct light (carried by light rays) and of light via the mirror, whose
    // deposits land on elements that later levels split.
    let mut s = floor_scene(true);
    s.materials.push(material("mirror", 0.0, 0.9, 0.0));
    s.patches.extend(quad(v(0.9, 0.2, -0.5), v(0.9, 0.2, 0.5), v(0.9, 1.2, 0.5), v(0.9, 1.2, -0.5), 1, 2));
    s.settings.direct = magg_core::scene::DirectLight::Lrt;
    s.settings.refine = 3;
    let plan = EffectsPlan::for_scene(&s);
    let refined = refine::prepare(&s, plan.clone()).unwrap();
    assert!(refined.splits.len() >= 2, "levels split: {:?}", refined.splits.iter().map(Vec::len).collect::<Vec<_>>());

    // The same levels with every pair traced anew at each, as a machine's light pass does.
    let mut pilot_scene = s.clone();
    pilot_scene.settings.diffuse_bounces = 0;
    let pilot_plan = EffectsPlan::for_scene(&pilot_scene);
    let mut splits: Vec<Vec<u32>> = Vec::new();
    for _ in 0..s.settings.refine {
        let pilot = prepare_split(&pilot_scene, pilot_plan.clone(), &splits).unwrap();
        let flux = run(&pilot, 1, None).element_flux;
        let room = s.settings.max_elements.saturating_sub(pilot.elements.len() as u64) / 4;
        let split = refine::choose(&s, &pilot, &flux, room as usize);
        if split.is_empty() {
            break;
        }
        splits.push(split);
    }
    assert_eq!(refined.splits, splits, "the same elements split at every level");
    let again = prepare_split(&s, plan, &splits).unwrap();
    assert!(again.kept_pairs.is_empty());
    // The refined scene's light pass bins the pilots' pairs (only the last level's new
    // elements' pairs are traced): the bits of tracing every pair, with fewer rays.
    assert!(!refined.kept_pairs.is_empty(), "no diffuse bounce: the pilots' pairs are kept");
    let (a, b) = (run(&refined, 2, None), run(&again, 2, None));
    assert!(refined.kept_pairs.is_empty(), "the light pass took them");
    assert_eq!(a.element_flux, b.element_flux, "the same element energies");
    assert_eq!(a.frame.pixels, b.frame.pixels, "and the same image");
    let rays = |o: &magg_core::machine::RenderOutput| o.stats.work.light_rays;
    assert!(0 < rays(&a) && rays(&a) < rays(&b), "light rays traced: {} kept, {} all", rays(&a), rays(&b));
}

#[test]
fn pilot_pairs_are_kept_only_where_the_light_pass_carries_the_pilots_light() {
    let mut s = floor_scene(true);
    s.settings.direct = magg_core::scene::DirectLight::Lrt;
    s.settings.refine = 1;
    let plan = EffectsPlan::for_scene(&s);
    assert!(!refine::prepare(&s, plan.clone()).unwrap().kept_pairs.is_empty());

    // Another plan (every effect forced on) or a diffuse bounce: the light pass carries
    // other light than the pilots', and traces every pair.
    assert!(refine::prepare(&s, EffectsPlan::forced_on(&s)).unwrap().kept_pairs.is_empty());
    s.settings.diffuse_bounces = 1;
    assert!(refine::prepare(&s, EffectsPlan::for_scene(&s)).unwrap().kept_pairs.is_empty());
    // No refinement: no pilot.
    s.settings.diffuse_bounces = 0;
    s.settings.refine = 0;
    assert!(refine::prepare(&s, plan).unwrap().kept_pairs.is_empty());
}
