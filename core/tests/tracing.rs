//! Ray casting through the subspace grid: watertightness on shared edges and vertices,
//! hostile directions, and hits that lie beyond the subspace where they were found.

mod common;
use common::*;
use glam::DVec3;
use magg_core::geometry::Ray;
use magg_core::math::Normalized;
use magg_core::scene::GridSpec;
use magg_core::trace::{cast, TraceScratch, NO_PATCH};
use magg_prepare::prepare;

/// The octahedron of 8 patches (n = 3), light outside, 3x3x3 subspaces.
fn diamond() -> magg_core::scene::Scene {
    octahedron(3, v(3.0, 3.0, 3.0), [3, 3, 3])
}

#[test]
fn rays_aimed_exactly_at_shared_edges_and_vertices_never_miss() {
    let s = diamond();
    let p = prepare(&s).unwrap();
    let mut view = view_of(&p);
    let mut scratch = TraceScratch::default();
    // Targets: the 6 vertices, and points along every one of the 12 edges.
    let verts =
        [v(1.0, 0.0, 0.0), v(-1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.0, -1.0, 0.0), v(0.0, 0.0, 1.0), v(0.0, 0.0, -1.0)];
    let mut targets: Vec<DVec3> = verts.to_vec();
    for i in 0..6 {
        for j in i + 1..6 {
            if verts[i].dot(verts[j]) == 0.0 {
                for k in 1..8 {
                    targets.push(verts[i].lerp(verts[j], k as f64 / 8.0));
                }
            }
        }
    }
    // From inside the closed mesh no ray may escape: every ray aimed exactly at a shared
    // edge or vertex (direction = target - origin, unnormalised, so the ray passes
    // through the target exactly) must hit.
    let origins = [v(0.0, 0.0, 0.0), v(0.1, 0.2, 0.05), v(-0.3, 0.1, 0.2), v(0.2, -0.25, -0.3), v(0.0, 0.0, 0.4)];
    let mut n = 0;
    for o in origins {
        for t in &targets {
            let ray = Ray::new(o, *t - o);
            let hit = cast(&mut view, &mut scratch, &ray, 0.0, f64::INFINITY, NO_PATCH, false).unwrap();
            assert!(hit.is_some(), "ray from {o:?} to {t:?} slipped through the mesh");
            n += 1;
        }
    }
    assert!(n > 100);
}

#[test]
fn hostile_directions_do_not_panic_and_hit_nothing() {
    let p = prepare(&diamond()).unwrap();
    let mut view = view_of(&p);
    let mut scratch = TraceScratch::default();
    for d in [v(0.0, 0.0, 0.0), v(f64::NAN, 0.0, -1.0), v(f64::INFINITY, 0.0, 0.0), v(0.0, f64::NEG_INFINITY, 0.0)] {
        let r = Ray::new(v(0.0, 0.0, 5.0), d);
        assert_eq!(cast(&mut view, &mut scratch, &r, 0.0, f64::INFINITY, NO_PATCH, false).unwrap(), None);
    }
}

#[test]
fn axis_aligned_and_negative_zero_directions_work() {
    let p = prepare(&diamond()).unwrap();
    let mut view = view_of(&p);
    let mut scratch = TraceScratch::default();
    for d in [v(0.0, 0.0, -1.0), v(-0.0, -0.0, -1.0), v(-0.0, 0.0, -1.0)] {
        let r = Ray::new(v(0.2, 0.1, 5.0), d);
        let h = cast(&mut view, &mut scratch, &r, 0.0, f64::INFINITY, NO_PATCH, false).unwrap().expect("hit");
        assert!((h.t - (5.0 - 0.7)).abs() < 1e-12, "t = {}", h.t);
    }
    // A ray lying exactly in a subspace boundary plane (x = 0 is not a cell face with a
    // 3x3x3 grid, but y = z = 0 through the mesh's vertices is a ridge).
    let r = Ray::new(v(5.0, 0.0, 0.0), v(-1.0, 0.0, 0.0));
    let h = cast(&mut view, &mut scratch, &r, 0.0, f64::INFINITY, NO_PATCH, false).unwrap().expect("hit on the vertex");
    assert!((h.t - 4.0).abs() < 1e-12);
}

#[test]
fn origins_inside_outside_and_on_the_grid_boundary() {
    let p = prepare(&diamond()).unwrap();
    let mut view = view_of(&p);
    let mut scratch = TraceScratch::default();
    let g = p.header.grid.clone();
    // Inside the mesh: hits the shell.
    let r = Ray::new(v(0.0, 0.0, 0.0), v(0.3, 0.4, 0.5).normalized());
    assert!(cast(&mut view, &mut scratch, &r, 0.0, f64::INFINITY, NO_PATCH, false).unwrap().is_some());
    // On the grid's boundary face, pointing in.
    let r = Ray::new(v(g.min.x, 0.1, 0.1), v(1.0, 0.0, 0.0));
    assert!(cast(&mut view, &mut scratch, &r, 0.0, f64::INFINITY, NO_PATCH, false).unwrap().is_some());
    // Outside, pointing away.
    let r = Ray::new(v(10.0, 0.0, 0.0), v(1.0, 0.0, 0.0));
    assert!(cast(&mut view, &mut scratch, &r, 0.0, f64::INFINITY, NO_PATCH, false).unwrap().is_none());
}

#[test]
fn a_hit_beyond_its_subspace_does_not_hide_a_nearer_one() {
    // A long slanted patch (plane x + 8y = 3.8) spanning x in [-4, 4], met by the ray at
    // x = 3 though it is listed in the ray's first subspaces; a small patch at x = 1.
    let long = magg_core::scene::PatchDef {
        vertices: [v(-4.0, 0.975, -2.0), v(4.0, -0.025, -2.0), v(4.0, -0.025, 2.0)],
        material: 0,
        subdivisions: Some(1),
        size_hint: None,
        normals: None,
        uv: None,
        texture: None,
        loc: loc(),
    };
    let small = magg_core::scene::PatchDef {
        vertices: [v(1.0, -0.5, -0.5), v(1.0, 0.5, -0.5), v(1.0, 0.0, 0.7)],
        material: 0,
        subdivisions: Some(1),
        size_hint: None,
        normals: None,
        uv: None,
        texture: None,
        loc: loc(),
    };
    let mut s = scene(vec![long, small], vec![material("white", 0.5, 0.0, 0.0)], vec![light(v(0.0, 3.0, 0.0), 1.0)]);
    s.settings.grid = GridSpec::Fixed([16, 1, 1]);
    s.settings.accel = magg_core::scene::Accel::Grid;
    let p = prepare(&s).unwrap();
    let mut view = view_of(&p);
    let mut scratch = TraceScratch::default();
    let r = Ray::new(v(-5.0, 0.1, 0.1), v(1.0, 0.0, 0.0));
    let h = cast(&mut view, &mut scratch, &r, 0.0, f64::INFINITY, NO_PATCH, false).unwrap().expect("hit");
    assert_eq!(h.patch, 1, "nearer small patch must win");
    assert!((h.t - 6.0).abs() < 1e-12);
    // Without the small patch in the way, the long one is found at x = 3.
    let r = Ray::new(v(-5.0, 0.1, 1.0), v(1.0, 0.0, 0.0));
    let h = cast(&mut view, &mut scratch, &r, 0.0, f64::INFINITY, NO_PATCH, false).unwrap().expect("hit");
    assert_eq!(h.patch, 0);
    assert!((h.t - 8.0).abs() < 1e-9);
}
