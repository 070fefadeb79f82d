//! Hard cases for grid traversal (extends `tracing.rs`): signed zero, subnormal, huge,
//! NaN and infinite direction components; rays lying in a subspace boundary plane or a
//! grid face; origins inside, outside and on the boundary; patches lying exactly on a
//! subspace face; hits that lie beyond the subspace where they were found. The
//! reference is brute force over every patch: same patch and bitwise the same t.

mod common;
#[path = "common/hard.rs"]
mod hard;

use common::*;
use glam::DVec3;
use hard::*;
use magg_core::geometry::Ray;
use magg_core::prepared::PreparedScene;
use magg_core::scene::Accel;
use magg_core::trace::{cast, TraceScratch, NO_PATCH};
use magg_core::view::SceneView;
use magg_prepare::prepare;

const DIMS: [u32; 3] = [5, 4, 3];

fn assert_agrees(view: &mut SceneView, ray: &Ray, what: &str) -> Option<u32> {
    let got = nearest(view, ray, 0.0);
    let want = brute_force(view, ray, 0.0, f64::INFINITY);
    assert_eq!(got.map(|h| (h.patch, h.t)), want.map(|h| (h.patch, h.t)), "{what}: ray {ray:?}");
    got.map(|h| h.patch)
}

fn prepared() -> PreparedScene {
    prepare(&random_scene(11, 40, DIMS)).unwrap()
}

/// The same scene traced through the grid, then through the BVH: the rays of the tests
/// below are as hostile to one as to the other.
fn both() -> [PreparedScene; 2] {
    let mut s = random_scene(11, 40, DIMS);
    s.settings.accel = Accel::Bvh;
    [prepared(), prepare(&s).unwrap()]
}

#[test]
fn signed_zero_subnormal_and_huge_direction_components_agree_with_brute_force() {
    for p in both() {
        signed_zero_subnormal_and_huge_direction_components_agree_with_brute_force_on(&p);
    }
}

fn signed_zero_subnormal_and_huge_direction_components_agree_with_brute_force_on(p: &PreparedScene) {
    let mut view = view_of(&p);
    let comps = [0.0, -0.0, 5e-324, -5e-324, 1e-300, 0.37, -0.61, 1.0, -1.0, 1e300];
    let origins = [v(0.05, -0.1, 0.2), v(-1.3, 0.7, 0.4), v(1.9, 1.9, -1.9)];
    let (mut hits, mut n) = (0, 0);
    for o in origins {
        for &x in &comps {
            for &y in &comps {
                for &z in &comps {
                    let d = v(x, y, z);
                    if d.abs().max_element() == 0.0 {
                        // All-zero (either sign): hits nothing.
                        assert_eq!(nearest(&mut view, &Ray::new(o, d), 0.0), None);
                        continue;
                    }
                    if d.length_squared() == 0.0 || !d.length_squared().is_finite() {
                        // Only subnormal parts (length underflows) or 1e300 parts
                        // (length overflows): the core treats those as zero / non-finite
                        // in `cast`; nothing to compare beyond "no panic".
                        let _ = nearest(&mut view, &Ray::new(o, d), 0.0);
                        continue;
                    }
                    hits += assert_agrees(&mut view, &Ray::new(o, d), "odd components").is_some() as u32;
                    n += 1;
                }
            }
        }
    }
    // Inside the closed box every well-formed ray hits something.
    assert!(n > 1500 && hits == n, "{hits} hits of {n}");
}

#[test]
fn nan_and_infinite_inputs_hit_nothing_and_do_not_panic() {
    for p in both() {
        nan_and_infinite_inputs_hit_nothing_and_do_not_panic_on(&p);
    }
}

fn nan_and_infinite_inputs_hit_nothing_and_do_not_panic_on(p: &PreparedScene) {
    let mut view = view_of(&p);
    let mut scratch = TraceScratch::default();
    let (nan, inf) = (f64::NAN, f64::INFINITY);
    let good_o = v(0.1, 0.2, 0.3);
    let good_d = v(0.3, -0.5, 0.8);
    let rays = [
        Ray::new(good_o, v(nan, nan, nan)),
        Ray::new(good_o, v(0.0, nan, 0.0)),
        Ray::new(good_o, v(0.0, 0.0, -inf)),
        Ray::new(good_o, v(inf, inf, inf)),
        Ray::new(good_o, v(inf, -inf, 1.0)),
        Ray::new(v(nan, 0.0, 0.0), good_d),
        Ray::new(v(inf, 0.0, 0.0), v(-1.0, 0.0, 0.0)),
        Ray::new(v(0.0, -inf, 0.0), v(0.0, 1.0, 0.0)),
    ];
    for r in rays {
        for any in [false, true] {
            assert_eq!(cast(&mut view, &mut scratch, &r, 0.0, inf, NO_PATCH, any).unwrap(), None, "{r:?}");
        }
    }
    // NaN or empty parameter ranges.
    let r = Ray::new(good_o, good_d);
    for (tmin, tmax) in [(nan, inf), (0.0, nan), (2.0, 1.0), (inf, inf), (0.0, 0.0), (-inf, -1.0)] {
        assert_eq!(cast(&mut view, &mut scratch, &r, tmin, tmax, NO_PATCH, false).unwrap(), None, "[{tmin}, {tmax}]");
    }
    // tmin = -0.0 behaves exactly like +0.0.
    let a = cast(&mut view, &mut scratch, &r, -0.0, inf, NO_PATCH, false).unwrap();
    let b = cast(&mut view, &mut scratch, &r, 0.0, inf, NO_PATCH, false).unwrap();
    assert!(a.is_some() && a == b, "{a:?} vs {b:?}");
}

#[test]
fn rays_lying_in_subspace_boundary_planes_and_grid_faces_agree_with_brute_force() {
    let grid = prepared();
    for p in both() {
        rays_lying_in_subspace_boundary_planes_and_grid_faces_agree_with_brute_force_on(&p, &grid);
    }
}

fn rays_lying_in_subspace_boundary_planes_and_grid_faces_agree_with_brute_force_on(
    p: &PreparedScene,
    grid: &PreparedScene,
) {
    let g = p.header.grid.clone();
    let mut view = view_of(&p);
    let mut rng = magg_core::rng::Rng::from_words(&[0x9d1d, 2]);
    let mut n = 0;
    for axis in 0..3 {
        // Interior boundaries as the grid traversal computes them, plus both grid faces.
        let mut planes = cell_planes(grid, axis);
        planes.push(g.min[axis]);
        planes.push(g.max[axis]);
        for &x in &planes {
            for _ in 0..60 {
                let mut o = v(rng.next_f64() * 3.8 - 1.9, rng.next_f64() * 3.8 - 1.9, rng.next_f64() * 3.8 - 1.9);
                let mut d = v(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5);
                let set = |w: &mut DVec3, a: usize, val: f64| match a {
                    0 => w.x = val,
                    1 => w.y = val,
                    _ => w.z = val,
                };
                set(&mut o, axis, x);
                set(&mut d, axis, if rng.next_f64() < 0.5 { 0.0 } else { -0.0 });
                let on_face = x == g.min[axis] || x == g.max[axis];
                let hit = assert_agrees(&mut view, &Ray::new(o, d), "in a boundary plane");
                if !on_face {
                    // Inside the closed box: the ray must hit.
                    assert!(hit.is_some(), "ray in plane {x} of axis {axis} escaped");
                }
                n += 1;
            }
        }
    }
    assert!(n >= 3 * 4 * 60);
}

#[test]
fn origins_inside_outside_and_on_the_grid_boundary_agree_with_brute_force() {
    for p in both() {
        origins_inside_outside_and_on_the_grid_boundary_agree_with_brute_force_on(&p);
    }
}

fn origins_inside_outside_and_on_the_grid_boundary_agree_with_brute_force_on(p: &PreparedScene) {
    let g = p.header.grid.clone();
    let mut view = view_of(&p);
    let mut rng = magg_core::rng::Rng::from_words(&[0x0819, 3]);
    let pick = |r: &mut magg_core::rng::Rng, a: usize| -> f64 {
        // On the min face, on the max face, inside, or outside on either side.
        match (r.next_f64() * 5.0) as u32 {
            0 => g.min[a],
            1 => g.max[a],
            2 => g.min[a] - 1.0 - r.next_f64(),
            3 => g.max[a] + 1.0 + r.next_f64(),
            _ => g.min[a] + (g.max[a] - g.min[a]) * r.next_f64(),
        }
    };
    let (mut n, mut from_outside_hits) = (0, 0);
    for _ in 0..3000 {
        let o = v(pick(&mut rng, 0), pick(&mut rng, 1), pick(&mut rng, 2));
        // Aim at a random point inside half the time (so that rays from outside enter),
        // otherwise a random direction (many leave at once).
        let d = if rng.next_f64() < 0.5 {
            v(rng.next_f64() * 3.0 - 1.5, rng.next_f64() * 3.0 - 1.5, rng.next_f64() * 3.0 - 1.5) - o
        } else {
            v(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5)
        };
        let outside = (0..3).any(|a| o[a] < g.min[a] || o[a] > g.max[a]);
        if assert_agrees(&mut view, &Ray::new(o, d), "origin test").is_some() && outside {
            from_outside_hits += 1;
        }
        n += 1;
    }
    assert!(n == 3000 && from_outside_hits > 200, "{from_outside_hits} hits from outside");
}

#[test]
fn patches_lying_exactly_on_subspace_faces_are_found_from_both_sides() {
    let base = random_scene(12, 10, DIMS);
    let p0 = prepare(&base).unwrap();
    // Axis-aligned triangles lying exactly in every interior boundary plane.
    let mut s = base.clone();
    let first_new = s.patches.len() as u32;
    for axis in 0..3 {
        for x in cell_planes(&p0, axis) {
            let at = |a: f64, b: f64| match axis {
                0 => v(x, a, b),
                1 => v(a, x, b),
                _ => v(a, b, x),
            };
            s.patches.push(tri(at(-1.7, -1.6), at(1.8, -1.5), at(0.1, 1.9), 0, 1));
        }
    }
    let p = prepare(&s).unwrap();
    assert_eq!(p.header.grid.min, p0.header.grid.min, "the enclosing box must fix the grid");
    assert_eq!(p.header.grid.max, p0.header.grid.max);
    let mut view = view_of(&p);
    let mut rng = magg_core::rng::Rng::from_words(&[0xface, 4]);
    let mut on_plane_hits = 0;
    for _ in 0..3000 {
        let o = v(rng.next_f64() * 3.8 - 1.9, rng.next_f64() * 3.8 - 1.9, rng.next_f64() * 3.8 - 1.9);
        let d = v(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5);
        if assert_agrees(&mut view, &Ray::new(o, d), "face patches").is_some_and(|id| id >= first_new) {
            on_plane_hits += 1;
        }
    }
    assert!(on_plane_hits > 300, "{on_plane_hits}");
}

#[test]
fn a_hit_beyond_its_subspace_loses_to_a_nearer_one_in_the_last_subspace_before_it() {
    // A long slanted patch spans all 16 subspaces along x; a small patch sits in the
    // subspace just before the point where the ray meets the long one. Both directions,
    // and with the ids either way round.
    for swap in [false, true] {
        let long = tri(v(-4.0, 0.975, -2.0), v(4.0, -0.025, -2.0), v(4.0, -0.025, 2.0), 0, 1);
        let small_at = |x: f64| tri(v(x, -0.5, -0.5), v(x, 0.5, -0.5), v(x, 0.0, 0.7), 0, 1);
        // The long patch is met at x = 3 (from -x) and the small one at x = 2.55.
        let patches = if swap { vec![small_at(2.55), long] } else { vec![long, small_at(2.55)] };
        let mut s = scene(patches, vec![material("white", 0.5, 0.0, 0.0)], vec![light(v(0.0, 3.0, 0.0), 1.0)]);
        s.settings.grid = magg_core::scene::GridSpec::Fixed([16, 1, 1]);
        s.settings.accel = magg_core::scene::Accel::Grid;
        let p = prepare(&s).unwrap();
        let mut view = view_of(&p);
        let small = if swap { 0 } else { 1 };
        let r = Ray::new(v(-5.0, 0.1, 0.1), v(1.0, 0.0, 0.0));
        let h = nearest(&mut view, &r, 0.0).expect("hit");
        assert_eq!(h.patch, small, "swap {swap}: the nearer small patch must win");
        assert!((h.t - 7.55).abs() < 1e-12);
        // tmax just short of the small patch: the farther long one must not leak in.
        let mut scratch = TraceScratch::default();
        let short = cast(&mut view, &mut scratch, &r, 0.0, h.t * (1.0 - 1e-12), NO_PATCH, false).unwrap();
        assert_eq!(short, None, "a hit beyond tmax leaked in");
        // Negative direction from the far side: met at x = 3 (long) before anything else.
        let r = Ray::new(v(5.0, 0.1, -1.0), v(-1.0, 0.0, 0.0));
        assert_agrees(&mut view, &r, "negative direction");
        // Shadow-ray mode finds some hit whenever brute force does.
        for o in [v(-5.0, 0.1, 0.1), v(5.0, 0.1, 1.5), v(0.0, 0.1, 1.9)] {
            for d in [v(1.0, 0.0, 0.0), v(-1.0, 0.0, 0.0)] {
                let ray = Ray::new(o, d);
                let any = cast(&mut view, &mut scratch, &ray, 0.0, f64::INFINITY, NO_PATCH, true).unwrap();
                let want = brute_force(&mut view, &ray, 0.0, f64::INFINITY);
                assert_eq!(any.is_some(), want.is_some(), "any-hit mode disagrees for {ray:?}");
            }
        }
    }
}

#[test]
fn every_subspace_lists_every_patch_touching_it_even_from_a_cell_face() {
    // Regression: a patch whose bounding box started exactly on a subspace face (the
    // octahedron's vertex (0, 1, 0) on the planes x = 0 and z = 0) was never tried in the
    // subspace before that face, so a tie at that vertex went to the higher patch id.
    let (px, nx, py, ny, pz, nz) =
        (v(1.0, 0.0, 0.0), v(-1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.0, -1.0, 0.0), v(0.0, 0.0, 1.0), v(0.0, 0.0, -1.0));
    let faces = [[px, py, pz], [py, nx, pz], [nx, ny, pz], [ny, px, pz], [py, px, nz], [nx, py, nz], [ny, nx, nz]];
    let mut diamond = scene(
        faces.iter().map(|f| tri(f[0], f[1], f[2], 0, 1)).collect::<Vec<_>>(),
        vec![material("white", 0.5, 0.0, 0.0)],
        vec![light(v(0.0, 0.0, 0.0), 1.0)],
    );
    diamond.patches.push(tri(px, ny, nz, 0, 1));
    diamond.settings.grid = magg_core::scene::GridSpec::Fixed([4, 4, 4]);
    diamond.settings.accel = magg_core::scene::Accel::Grid;
    for (label, s) in [("octahedron", diamond), ("random", random_scene(13, 30, DIMS))] {
        let p = prepare(&s).unwrap();
        let g = p.header.grid.clone();
        let cs = g.cell_size();
        let mut view = view_of(&p);
        let mut ids = Vec::new();
        let mut listed = 0;
        for z in 0..g.dims[2] {
            for y in 0..g.dims[1] {
                for x in 0..g.dims[0] {
                    let cmin = v(g.min.x + cs.x * x as f64, g.min.y + cs.y * y as f64, g.min.z + cs.z * z as f64);
                    view.subspace(g.cell_index([x, y, z]), &mut ids).unwrap();
                    for (pid, pd) in s.patches.iter().enumerate() {
                        let touches = magg_core::geometry::triangle_overlaps_box(&pd.vertices, cmin, cmin + cs);
                        if touches {
                            assert!(
                                ids.contains(&(pid as u32)),
                                "{label}: patch {pid} touches cell ({x},{y},{z}) but is not listed"
                            );
                            listed += 1;
                        }
                    }
                }
            }
        }
        assert!(listed > 0);
    }
    // The tie at the vertex now goes to the lower id.
    let p = prepare(&{
        let mut s = scene(
            faces.iter().map(|f| tri(f[0], f[1], f[2], 0, 1)).collect::<Vec<_>>(),
            vec![material("white", 0.5, 0.0, 0.0)],
            vec![light(v(0.0, 0.0, 0.0), 1.0)],
        );
        s.settings.grid = magg_core::scene::GridSpec::Fixed([4, 4, 4]);
        s.settings.accel = magg_core::scene::Accel::Grid;
        s
    })
    .unwrap();
    let mut view = view_of(&p);
    let o = v(-0.3, 0.1, 0.2);
    let h = nearest(&mut view, &Ray::new(o, py - o), 0.0).unwrap();
    assert_eq!((h.patch, h.t), (0, 1.0));
}
