//! The BVH and the uniform grid give the same hits, bit for bit: against a brute-force
//! nearest hit over random rays (with edge, vertex and tie hits), and on every shipped
//! scene, whose frames and element energies must be identical with either structure.

mod common;
#[path = "common/hard.rs"]
mod hard;
use common::*;
use glam::DVec3;
use hard::random_scene;
use magg_core::geometry::{intersect_watertight, Ray};
use magg_core::prepared::PreparedScene;
use magg_core::render::{render, RenderOptions};
use magg_core::rng::Rng;
use magg_core::scene::{parse_scene_with_path, Accel, DirectLight, Scene};
use magg_core::trace::{cast, cast_all, occluded_all, Bundled, Hit, TraceScratch, NO_PATCH, PACKET};
use magg_core::view::SceneView;
use magg_prepare::prepare;
use std::path::{Path, PathBuf};

/// The contract of `trace::cast`, by brute force: among the patches of non-zero area
/// other than `exclude`, hit with `tmin < t <= tmax`, the nearest, ties to the lower id.
fn brute_force(view: &mut SceneView, ray: &Ray, tmin: f64, tmax: f64, exclude: u32) -> Option<Hit> {
    let up = if tmax.is_finite() { next_up(tmax) } else { tmax };
    let mut best: Option<Hit> = None;
    for pid in 0..view.header.counts.patches {
        let v = view.patch(pid).expect("patch").v;
        if pid == exclude || (v[1] - v[0]).cross(v[2] - v[0]) == DVec3::ZERO {
            continue;
        }
        if let Some(h) = intersect_watertight(ray, &v, tmin, up) {
            if best.is_none_or(|b| h.t < b.t) {
                best = Some(Hit { t: h.t, patch: pid, bary: h.bary });
            }
        }
    }
    best
}

fn next_up(x: f64) -> f64 {
    if x > 0.0 {
        f64::from_bits(x.to_bits() + 1)
    } else if x == 0.0 {
        f64::from_bits(1)
    } else {
        f64::from_bits(x.to_bits() - 1)
    }
}

fn with_accel(s: &Scene, accel: Accel) -> PreparedScene {
    let mut s = s.clone();
    s.settings.accel = accel;
    prepare(&s).expect("prepare")
}

/// A flat 8 x 8 sheet of quads (two triangles each, shared edges and vertices), a
/// second sheet exactly on top of part of it (coincident patches: ties), random
/// triangles, and an enclosing box.
fn tie_scene(seed: u64) -> Scene {
    let mut s = random_scene(seed, 300, [5, 4, 6]);
    for i in 0..8 {
        for j in 0..8 {
            let (x, z) = (-1.0 + 0.25 * i as f64, -1.0 + 0.25 * j as f64);
            s.patches.extend(quad(
                v(x, 0.1, z),
                v(x + 0.25, 0.1, z),
                v(x + 0.25, 0.1, z + 0.25),
                v(x, 0.1, z + 0.25),
                0,
                1,
            ));
        }
    }
    for i in 0..3 {
        let x = -1.0 + 0.25 * i as f64;
        s.patches.extend(quad(
            v(x, 0.1, -1.0),
            v(x + 0.25, 0.1, -1.0),
            v(x + 0.25, 0.1, -0.75),
            v(x, 0.1, -0.75),
            0,
            1,
        ));
    }
    // A zero-area patch is never hit.
    s.patches.push(tri(v(0.0, 0.5, 0.0), v(0.5, 0.5, 0.0), v(1.0, 0.5, 0.0), 0, 1));
    s
}

#[test]
fn bvh_and_grid_agree_with_brute_force_on_random_rays() {
    for seed in 1..=3u64 {
        let s = tie_scene(seed);
        let (bvh, grid) = (with_accel(&s, Accel::Bvh), with_accel(&s, Accel::Grid));
        assert!(bvh.header.bvh.nodes > 1 && grid.header.bvh.nodes == 0);
        let (mut vb, mut vg) = (view_of(&bvh), view_of(&grid));
        // Every vertex of the sheet is a target: rays through shared vertices and edges.
        let mut targets: Vec<DVec3> = Vec::new();
        for i in 0..=8 {
            for j in 0..=8 {
                targets.push(v(-1.0 + 0.25 * i as f64, 0.1, -1.0 + 0.25 * j as f64));
                targets.push(v(-1.0 + 0.25 * i as f64 + 0.125, 0.1, -1.0 + 0.25 * j as f64));
            }
        }
        let mut rng = Rng::from_words(&[seed, 0xacce1]);
        let mut u = move || rng.next_f64() * 2.0 - 1.0;
        let (mut sb, mut sg) = (TraceScratch::default(), TraceScratch::default());
        let mut hits = 0;
        for k in 0..3000 {
            let o = v(u() * 1.9, u() * 1.9, u() * 1.9);
            let target = if k % 2 == 0 { targets[k / 2 % targets.len()] } else { v(u(), u(), u()) * 1.5 };
            let Some(ray) = (target != o).then(|| Ray::new(o, (target - o).normalize())) else { continue };
            let (tmin, tmax) = match k % 4 {
                0 => (0.0, f64::INFINITY),
                1 => (1e-9, (target - o).length()),
                2 => (0.3, 2.0),
                _ => (0.0, (target - o).length() * 0.5),
            };
            let exclude = if k % 5 == 0 { (k as u32 * 7) % s.patches.len() as u32 } else { NO_PATCH };
            let want = brute_force(&mut vb, &ray, tmin, tmax, exclude);
            let got_b = cast(&mut vb, &mut sb, &ray, tmin, tmax, exclude, false).unwrap();
            let got_g = cast(&mut vg, &mut sg, &ray, tmin, tmax, exclude, false).unwrap();
            assert_eq!(got_b, want, "BVH, seed {seed}, ray {k}: {ray:?} [{tmin}, {tmax}] exclude {exclude}");
            assert_eq!(got_g, want, "grid, seed {seed}, ray {k}: {ray:?} [{tmin}, {tmax}] exclude {exclude}");
            // Occlusion queries, through both structures.
            let any = cast(&mut vb, &mut sb, &ray, tmin, tmax, exclude, true).unwrap();
            assert_eq!(any.is_some(), want.is_some(), "BVH occlusion, seed {seed}, ray {k}");
            let any = cast(&mut vg, &mut sg, &ray, tmin, tmax, exclude, true).unwrap();
            assert_eq!(any.is_some(), want.is_some(), "grid occlusion, seed {seed}, ray {k}");
            if let Some(h) = want {
                // The same ray again, without the patch it hit, then stopped short of it:
                // an occlusion query must not answer with what it found before.
                for (ex, top) in [(h.patch, tmax), (exclude, h.t * 0.5)] {
                    let want = brute_force(&mut vb, &ray, tmin, top, ex).is_some();
                    for (view, scratch, what) in [(&mut vb, &mut sb, "BVH"), (&mut vg, &mut sg, "grid")] {
                        let got = cast(view, scratch, &ray, tmin, top, ex, true).unwrap().is_some();
                        assert_eq!(got, want, "{what} occlusion after a hit, seed {seed}, ray {k}, exclude {ex}");
                    }
                }
            }
            hits += want.is_some() as u32;
        }
        assert!(hits > 1000, "too few hits to mean anything: {hits}");
    }
}

#[test]
fn a_tie_goes_to_the_lower_patch_id_in_the_bvh() {
    // Two coincident triangles, the higher id first in the file: the lower id wins.
    let mut s = scene(
        vec![tri(v(-1.0, 0.0, -1.0), v(1.0, 0.0, -1.0), v(0.0, 0.0, 1.0), 0, 1)],
        vec![material("white", 0.5, 0.0, 0.0)],
        vec![light(v(0.0, 1.0, 0.0), 1.0)],
    );
    for k in 0..40 {
        let z = -0.9 + 0.05 * k as f64;
        s.patches.push(tri(v(-1.0, 0.0, z), v(1.0, 0.0, z), v(0.0, 0.0, z + 0.05), 0, 1));
    }
    s.patches.push(tri(v(-1.0, 0.0, -1.0), v(1.0, 0.0, -1.0), v(0.0, 0.0, 1.0), 0, 1));
    let p = with_accel(&s, Accel::Bvh);
    let mut view = view_of(&p);
    let last = s.patches.len() as u32 - 1;
    let ray = Ray::new(v(0.0, 1.0, -0.5), v(0.0, -1.0, 0.0));
    let hit = cast(&mut view, &mut TraceScratch::default(), &ray, 0.0, f64::INFINITY, NO_PATCH, false).unwrap();
    assert_eq!(hit.map(|h| h.patch), Some(0));
    assert_eq!(hit, brute_force(&mut view, &ray, 0.0, f64::INFINITY, NO_PATCH));
    // Without patch 0, the lowest of the others at the same distance.
    let hit = cast(&mut view, &mut TraceScratch::default(), &ray, 0.0, f64::INFINITY, 0, false).unwrap().unwrap();
    assert!(hit.patch > 0 && hit.patch < last, "{hit:?}");
    assert_eq!(Some(hit), brute_force(&mut view, &ray, 0.0, f64::INFINITY, 0));
}

/// Rays from one origin walk the BVH as packets (`cast_all`, `occluded_all`): each
/// gets exactly the hit it gets alone, through shared edges and vertices, coincident
/// patches, its own interval and excluded patch; and the packets visit fewer nodes.
#[test]
fn packets_of_rays_from_one_origin_give_each_ray_its_own_hit() {
    for seed in 1..=3u64 {
        let s = tie_scene(seed);
        for accel in [Accel::Bvh, Accel::Grid] {
            let p = with_accel(&s, accel);
            let (mut view, mut scratch) = (view_of(&p), TraceScratch::default());
            let mut rng = Rng::from_words(&[seed, 0x9ac4e7]);
            let mut u = move || rng.next_f64() * 2.0 - 1.0;
            let (mut alone_steps, mut packed_steps, mut hits) = (0, 0, 0);
            for k in 0..400 {
                let o = v(u() * 1.9, u() * 1.9, u() * 1.9);
                // Towards neighbouring vertices of the sheet (a narrow bundle), or anywhere.
                let (cx, cz) = (u() * 0.9, u() * 0.9);
                let width = [0.01, 0.25, 1.0, 3.0][k % 4];
                let rays: Vec<Bundled> = (0..13)
                    .map(|i| {
                        let snap = |x: f64| (x * 8.0).round() / 8.0;
                        let target = if i % 3 == 0 {
                            v(snap(cx + u() * width), 0.1, snap(cz + u() * width))
                        } else {
                            v(cx + u() * width, 0.1 + u() * width * 0.1, cz + u() * width)
                        };
                        let d = target - o;
                        let (tmin, tmax) = match (k + i) % 4 {
                            0 => (0.0, f64::INFINITY),
                            1 => (1e-9, d.length()),
                            2 => (0.3, 2.0),
                            _ => (0.0, d.length() * 0.5),
                        };
                        let exclude = if i % 5 == 0 { (k * 7 + i) as u32 % s.patches.len() as u32 } else { NO_PATCH };
                        Bundled { ray: Ray::new(o, d.normalize()), tmin, tmax, exclude }
                    })
                    .collect();
                let steps = view.counters.grid_steps;
                let mut want = Vec::new();
                for b in &rays {
                    want.push(cast(&mut view, &mut scratch, &b.ray, b.tmin, b.tmax, b.exclude, false).unwrap());
                }
                alone_steps += view.counters.grid_steps - steps;
                let steps = view.counters.grid_steps;
                let mut got = Vec::new();
                cast_all(&mut view, &mut scratch, &rays, &mut got).unwrap();
                packed_steps += view.counters.grid_steps - steps;
                assert_eq!(got, want, "{accel:?}, seed {seed}, bundle {k}");
                for (b, w) in rays.iter().zip(&want) {
                    assert_eq!(brute_force(&mut view, &b.ray, b.tmin, b.tmax, b.exclude), *w);
                }
                let mut occluded = Vec::new();
                occluded_all(&mut view, &mut scratch, &rays, &mut occluded).unwrap();
                let want: Vec<bool> = want.iter().map(Option::is_some).collect();
                assert_eq!(occluded, want, "{accel:?} occlusion, seed {seed}, bundle {k}");
                hits += want.iter().filter(|h| **h).count();
            }
            assert!(hits > 1500, "too few hits to mean anything: {hits}");
            if accel == Accel::Bvh {
                // Packed: a node is visited once for up to PACKET rays.
                assert!(packed_steps * 3 < alone_steps * 2, "{packed_steps} node visits packed, {alone_steps} alone");
            } else {
                assert_eq!(packed_steps, alone_steps);
            }
        }
    }
    assert!(PACKET >= 4);
}

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("scenes")
}

/// Every shipped scene: `scenes/*.toml` and `scenes/paths/*.toml`, sorted.
fn shipped_scenes() -> Vec<PathBuf> {
    let mut v = Vec::new();
    for dir in [scenes_dir(), scenes_dir().join("paths")] {
        v.extend(
            std::fs::read_dir(&dir)
                .unwrap()
                .map(|e| e.unwrap().path())
                .filter(|p| p.extension().is_some_and(|e| e == "toml")),
        );
    }
    v.sort();
    v
}

#[test]
fn every_shipped_scene_renders_the_same_bits_with_the_grid_and_the_bvh() {
    let scenes = shipped_scenes();
    assert!(scenes.len() >= 7, "expected the shipped scenes, found {scenes:?}");
    for path in scenes {
        let text = std::fs::read_to_string(&path).unwrap();
        let label = path.display().to_string();
        let dir = path.parent().unwrap();
        let (mut s, _) =
            parse_scene_with_path(&label, &text, dir, &|p: &Path| std::fs::read(p)).unwrap_or_else(|e| panic!("{e}"));
        s.settings.width = 48;
        s.settings.height = 48;
        s.settings.pixel_samples = 1;
        s.settings.light_rays = s.settings.light_rays.min(4);
        let opts =
            RenderOptions { nodes: 2, forks: 3, cache_blocks: magg_core::blocks::CacheSize::Unlimited, subscreen: 16 };
        // Direct light deposited by light rays (every pair traced), and where the plan
        // puts it (shadow rays at VRT).
        for direct in [DirectLight::Lrt, DirectLight::Auto] {
            s.settings.direct = direct;
            let mut outs = Vec::new();
            for accel in [Accel::Grid, Accel::Bvh] {
                let p = with_accel(&s, accel);
                let o = render(&p, &opts, &magg_core::progress::NoProgress).unwrap();
                if direct == DirectLight::Lrt {
                    assert!(o.stats.light.reached.0[0] > 0.0, "{label} ({accel:?}): no light reached an element");
                }
                outs.push(o);
            }
            let label = format!("{label} (direct {direct:?})");
            assert_eq!(outs[0].element_flux, outs[1].element_flux, "{label}: element energies differ");
            assert_eq!(outs[0].vertex_irradiance, outs[1].vertex_irradiance, "{label}: vertex irradiance differs");
            assert_eq!(outs[0].frame, outs[1].frame, "{label}: frames differ");
        }
    }
}

#[test]
fn a_bounded_cache_reads_bvh_blocks_like_any_other() {
    let s = random_scene(9, 400, [4, 4, 4]);
    let p = with_accel(&s, Accel::Bvh);
    let unlimited = run(&p, 1, None);
    let bounded = run(&p, 1, Some(8));
    assert_eq!(unlimited.frame, bounded.frame);
    assert_eq!(unlimited.element_flux, bounded.element_flux);
    assert!(bounded.stats.cache.misses > unlimited.stats.cache.misses);
    // The grid of a BVH scene is one empty subspace: no subspace block at all.
    assert_eq!((p.header.grid.dims, p.header.counts.subspace_blocks), ([1, 1, 1], 0));
    assert_eq!(p.header.counts.bvh_blocks, p.header.bvh.node_blocks + p.header.bvh.triangle_blocks);
    let g = with_accel(&s, Accel::Grid);
    assert_eq!((g.header.counts.bvh_blocks, g.header.grid.dims), (0, [4, 4, 4]));
}

/// BVH node blocks whose nodes point back up the tree (a cycle) are an error of the
/// cast, not a walk without end: for rays walked with the f32 slab test and for rays it
/// refuses (a tiny largest direction component), which take the f64 test.
#[test]
fn a_bvh_node_pointing_back_up_the_tree_is_an_error_not_a_hang() {
    use magg_core::blocks::bvh::{BvhNode, BVH_NODES_PER_BLOCK, BVH_NODE_RECORD};
    let p = with_accel(&tie_scene(1), Accel::Bvh);
    assert!(p.header.bvh.nodes >= BVH_NODES_PER_BLOCK as u32, "{} nodes", p.header.bvh.nodes);
    let mut bad = p.clone();
    let base = bad.header.layout.bvh_base as usize;
    // The inner children of every node but the root point at the root.
    let mut inner = 0;
    for n in 1..p.header.bvh.nodes as usize {
        let (block, at) = (base + n / BVH_NODES_PER_BLOCK, n % BVH_NODES_PER_BLOCK * BVH_NODE_RECORD);
        let mut node = BvhNode::decode(&bad.blocks[block], at);
        for c in node.children.iter_mut().filter(|c| c.count == 0 && c.index != u32::MAX) {
            c.index = 0;
            inner += 1;
        }
        node.encode(&mut bad.blocks[block], at);
    }
    assert!(inner > 0, "no node but the root has an inner child");
    let mut view = view_of(&bad);
    let mut scratch = TraceScratch::default();
    for (what, d) in [("f32 test", v(0.0, -1.0, 0.0)), ("f64 test", v(1e-30, -1e-30, 1e-31))] {
        let mut errors = 0;
        for i in 0..200 {
            let o = v(-1.0 + 0.01 * i as f64, 2.5, 0.3 - 0.003 * i as f64);
            let ray = Ray::new(o, d);
            if let Err(e) = cast(&mut view, &mut scratch, &ray, 0.0, f64::INFINITY, NO_PATCH, false) {
                assert!(e.to_string().contains("corrupt BVH node block"), "{what}, ray {i}: {e}");
                errors += 1;
            }
        }
        assert!(errors > 0, "{what}: no ray reached the corrupt node");
    }
}
