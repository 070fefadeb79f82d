//! Gathering the bounce at VRT (`[render] gather_rays`): beside elements that received no
//! light (a contact with another surface), a diffuse hit gathers the bounced light with
//! rays of its own instead of interpolating the elements'. Both estimate the same light,
//! one diffuse bounce of the direct light, so where the elements are right the two must
//! agree; and only the vertices around the unlit elements are marked for it.

mod common;
use common::*;
use magg_core::energy::gather_vertices;
use magg_core::fixed::from_fixed;
use magg_core::prepared::{Face, PreparedScene};
use magg_core::scatter::Arrival;
use magg_core::scene::{DirectLight, Scene};
use magg_core::trace::TraceScratch;
use magg_core::vrt::gathered;

const RHO: f64 = 0.5;

/// A closed white room (2 x 2 x 2) around a point light, direct light at VRT, one diffuse
/// bounce: the elements hold only the bounce. With `block`, a white box stands on the
/// floor in one corner.
fn room(block: bool) -> Scene {
    let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 8, true);
    if block {
        patches.extend(boxed(v(0.2, 0.0, 0.2), v(0.8, 0.6, 0.8), 0, 4, false));
    }
    let mut s = scene(patches, vec![material("white", RHO, 0.0, 0.0)], vec![light(v(-0.2, 1.5, -0.1), 3.0)]);
    s.settings.direct = DirectLight::Vrt;
    s.settings.diffuse_bounces = 1;
    s.settings.light_rays = 512;
    // Inside the room, looking down at the box's corner of the floor.
    s.camera.eye = v(-0.8, 1.8, -0.8);
    s.camera.look_at = v(0.5, 0.0, 0.5);
    (s.settings.width, s.settings.height) = (32, 32);
    s
}

/// The floor's lit elements (front faces at y = 0) away from the walls.
fn floor_elements(p: &PreparedScene) -> Vec<usize> {
    (0..p.elements.len())
        .filter(|&i| {
            let e = &p.elements[i];
            let c = e.centroid;
            e.face != Face::Back && c.y.abs() < 1e-9 && c.x.abs() < 0.6 && c.z.abs() < 0.6
        })
        .collect()
}

#[test]
fn a_gather_finds_the_bounce_that_the_elements_hold() {
    let s = room(false);
    let (p, out) = prepare_and_run(&s);
    assert!(p.header.plan.gathers(s.settings.gather_rays, &s.materials), "{:?}", p.header.plan.reasons);
    let floor = floor_elements(&p);
    assert!(floor.len() > 20, "{} floor elements", floor.len());
    let q = p.header.energy_quantum;
    let held: f64 = floor.iter().map(|&i| from_fixed(out.element_flux[i], q).0[0] / p.elements[i].area).sum::<f64>()
        / floor.len() as f64;
    let mut view = view_of(&p);
    let mut scratch = TraceScratch::default();
    let mut found = 0.0;
    for &i in &floor {
        let c = p.elements[i].centroid;
        let at = Arrival::new(c, v(0.3, -1.0, 0.2).normalize(), v(0.0, 1.0, 0.0));
        let e = gathered(&mut view, &mut scratch, &at, p.elements[i].patch, 1024).unwrap();
        assert!(e.0.iter().all(|x| x.is_finite() && *x >= 0.0), "{e:?}");
        found += e.0[0];
    }
    found /= floor.len() as f64;
    // Two estimates of the same light: light rays binned per element (LRT) and gather
    // rays with a shadow ray each (VRT). Both are noisy; 1024 gather rays at each of
    // the centroids and 512 bounce rays a pair keep the means within a few percent.
    assert!(held > 0.0 && (found - held).abs() / held < 0.04, "gathered {found}, elements hold {held}");
}

#[test]
fn only_the_elements_around_a_contact_are_marked() {
    let s = room(true);
    let (p, out) = prepare_and_run(&s);
    let marks = gather_vertices(&p.elements, &out.element_flux, p.vertex_positions.len());
    // The faces that can be seen: every back element (outside the room, inside the box)
    // is unlit, and its own vertices are marked, but no viewing ray reaches them.
    let mut front = vec![false; marks.len()];
    for e in p.elements.iter().filter(|e| e.face != Face::Back) {
        for &v in &e.vertices {
            front[v as usize] = true;
        }
    }
    let marked: Vec<_> = (0..marks.len()).filter(|&i| marks[i] && front[i]).map(|i| p.vertex_positions[i]).collect();
    assert!(!marked.is_empty(), "the box's footprint leaves floor elements unlit");
    // The room's elements are 0.25 wide, the box's 0.15: two rings of elements around
    // the footprint (x, z in [0.2, 0.8] on the floor) and the box's own bottom.
    for m in &marked {
        let near = m.x > 0.2 - 0.55 && m.z > 0.2 - 0.55 && m.y < 0.6 + 1e-9;
        assert!(near, "vertex {m} marked far from the box");
    }
    // The rest of the room interpolates.
    let seen = front.iter().filter(|&&f| f).count();
    assert!(marked.len() * 4 < seen, "{} of {seen} vertices marked", marked.len());
}

#[test]
fn gathering_keeps_renders_identical_across_cluster_shapes() {
    let s = room(true);
    let p = magg_prepare::prepare(&s).unwrap();
    let (a, b) = (run(&p, 1, None), run(&p, 3, Some(60)));
    assert_eq!(a.frame.pixels, b.frame.pixels);
    let mut off = s.clone();
    off.settings.gather_rays = 0;
    let q = magg_prepare::prepare(&off).unwrap();
    let c = run(&q, 1, None);
    assert_ne!(a.frame.pixels, c.frame.pixels, "the box's contact gathers");
}
