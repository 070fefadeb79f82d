//! A subscreen's pixels traced a generation of viewing rays at a time (a wave): every
//! sample's primary ray, then every ray those spawned, the rays of one kind of path
//! (reflected off the glass, refracted into it and out again, ...) side by side.
//!
//! Why waves: neighbouring pixels' rays read the same blocks (BVH nodes, leaf
//! triangles, the patch, its shading and element records, vertex energies), but a
//! pixel's own ray tree through a glass sphere reads blocks all over the scene. Traced
//! one pixel's tree after another, each pixel cycles through every branch's blocks, and
//! when they add up to more than a bounded node cache holds, LRU evicts each block just
//! before it is wanted again. Traced a generation at a time, sorted by the branches
//! taken, the rays of one branch read their blocks back to back.
//!
//! The radiance is unchanged, bit for bit: each ray's tree is kept (a node per ray, its
//! local radiance and how its children's join it), and evaluated from the leaves up
//! with the same arithmetic, in the same order, as the depth-first recursion that
//! traces pixels when every block is resident (where waves would only add bookkeeping).

use super::{arrival, arrive_at, interpolated, lit, pixel_rays, query, Arrived, Join};
use crate::blocks::BlockError;
use crate::camera::CameraRig;
use crate::color::Rgb;
use crate::direct::{self, PixelStrata};
use crate::geometry::Ray;
use crate::subscreen::Subscreen;
use crate::trace::{cast_all, TraceScratch, NO_PATCH};
use crate::view::{patch_block, vertex_block, ElementPoint, LeafPoint, SceneView, NO_BLOCK};
use glam::DVec3;

/// One viewing ray of a row's trees.
struct Node {
    local: Rgb,
    join: Join,
    /// Its children: node ids `first..first + count`, in the order they were spawned.
    first: u32,
    count: u32,
}

/// A ray waiting for its wave: its node, the branches its path took (rays of equal
/// `path` are traced side by side), its depth and the patch it leaves.
struct Queued {
    node: u32,
    path: u64,
    ray: Ray,
    depth: u32,
    exclude: u32,
    /// A primary ray's place among its pixel's shadow rays to the area lights.
    strata: Option<PixelStrata>,
}

/// Linear radiance of the pixels of subscreen `s`, appended to `out` row by row: for
/// each, the mean of its viewing rays (as [`super::shade_pixel`] gives it, bit for bit).
/// The pixels' rays are traced in Morton order (neighbours in the image, whose rays read
/// the same blocks, come one after another in both directions).
pub fn shade_pixels(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    rig: &CameraRig,
    s: Subscreen,
    out: &mut Vec<Rgb>,
) -> Result<(), BlockError> {
    let (n, seed) = (view.header.plan.pixel_samples.max(1), view.header.settings.seed);
    let area = view.header.plan.area_samples() > 0;
    if !view.cache_is_bounded() {
        // Every block resident: tile by tile (4 x 4 pixels), the tile's primary rays cast
        // together (they leave the eye: packets through the BVH), then each ray's tree
        // depth first, with no bookkeeping (the same bits).
        let start = out.len();
        out.resize(start + s.pixels() as usize, Rgb::BLACK);
        let (mut pixels, mut queries, mut hits, mut strata_of) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for ty in (0..s.h).step_by(4) {
            for tx in (0..s.w).step_by(4) {
                pixels.clear();
                queries.clear();
                strata_of.clear();
                for dy in ty..(ty + 4).min(s.h) {
                    for dx in tx..(tx + 4).min(s.w) {
                        pixels.push((dy * s.w + dx) as usize);
                        queries.extend(pixel_rays(seed, n, area, rig, s.x + dx, s.y + dy).map(|(r, strata)| {
                            strata_of.push(strata);
                            query(&r, NO_PATCH)
                        }));
                    }
                }
                cast_all(view, scratch, &queries, &mut hits)?;
                let rays = queries.chunks(n as usize).zip(hits.chunks(n as usize)).zip(strata_of.chunks(n as usize));
                for (&pixel, ((qs, hs), ps)) in pixels.iter().zip(rays) {
                    let mut sum = Rgb::BLACK;
                    for ((q, h), strata) in qs.iter().zip(hs).zip(ps) {
                        let arrived = arrival(view, &q.ray, *h, 0, *strata)?;
                        sum = sum.add(radiance_from(view, scratch, arrived, 0)?);
                    }
                    out[start + pixel] = sum.scale(1.0 / n as f64);
                }
            }
        }
        return Ok(());
    }
    let leaf = Node { local: Rgb::BLACK, join: Join::None, first: 0, count: 0 };
    let mut coded: Vec<(u64, u32, u32)> =
        (0..s.h).flat_map(|dy| (0..s.w).map(move |dx| (morton(dx, dy), dx, dy))).collect();
    coded.sort_unstable();
    let order: Vec<(u32, u32)> = coded.into_iter().map(|(_, dx, dy)| (dx, dy)).collect();
    // The primary rays are nodes 0.., pixel by pixel in that order, sample by sample.
    // Room for the primary rays and as many again spawned (no growing copies while
    // tracing; a wave of more rays grows its buffers once).
    let rays = order.len() * n as usize;
    let mut nodes: Vec<Node> = Vec::with_capacity(2 * rays);
    let mut wave: Vec<Queued> = Vec::with_capacity(rays);
    for &(dx, dy) in &order {
        for (ray, strata) in pixel_rays(seed, n, area, rig, s.x + dx, s.y + dy) {
            let node = nodes.len() as u32;
            nodes.push(Node { ..leaf });
            wave.push(Queued { node, path: 0, ray, depth: 0, exclude: NO_PATCH, strata });
        }
    }
    let mut spawned = [Ray::new(DVec3::ZERO, DVec3::Z); 3];
    let mut next: Vec<Queued> = Vec::with_capacity(rays);
    let mut arrived: Vec<(u32, Arrived, Rgb)> = Vec::with_capacity(rays);
    let mut by_element: Vec<(u32, u32)> = Vec::with_capacity(rays);
    let mut lookups = Lookups::default();
    let (mut queries, mut hits) = (Vec::with_capacity(rays), Vec::with_capacity(rays));
    while !wave.is_empty() {
        // Node ids grow with the pixel and the sample: ties keep that order.
        if !wave.is_sorted_by_key(|q| (q.path, q.node)) {
            wave.sort_unstable_by_key(|q| (q.path, q.node));
        }
        // In stages, each over the whole wave, so that each stage's blocks are read back
        // to back: the hits (BVH, leaf triangles, patches, shading), the elements'
        // light (element records, vertex energies), then the shadow rays (the BVH
        // again, towards the lights).
        // (The first wave's rays leave the eye, neighbours side by side: packets.)
        queries.clear();
        queries.extend(wave.iter().map(|q| query(&q.ray, q.exclude)));
        cast_all(view, scratch, &queries, &mut hits)?;
        // (The patches hit, a run of blocks fetched ahead at a time.)
        let header = view.header.clone();
        let patch = |i: usize| hits[i].map_or(NO_BLOCK, |h| patch_block(&header, h.patch));
        view.in_prefetched_runs(
            &mut (&mut arrived, &mut nodes),
            wave.len(),
            |_, i| [patch(i), NO_BLOCK, NO_BLOCK],
            |view, (arrived, nodes), i| {
                let q = &wave[i];
                match arrival(view, &q.ray, hits[i], q.depth, q.strata)? {
                    Ok(a) => arrived.push((i as u32, a, Rgb::BLACK)),
                    Err(local) => nodes[q.node as usize].local = local,
                }
                Ok(())
            },
        )?;
        // The elements in the order of their ids: neighbours share element and
        // vertex-energy blocks.
        by_element.clear();
        by_element.extend(arrived.iter().enumerate().filter(|(_, a)| a.1.shaded).map(|(i, a)| (a.1.element, i as u32)));
        if !by_element.is_sorted() {
            by_element.sort_unstable();
        }
        lit_all(view, scratch, &mut arrived, &by_element, &mut lookups)?;
        let area_samples = view.header.plan.area_samples();
        for (_, a, irr) in arrived.iter_mut().filter(|(_, a, _)| a.direct) {
            *irr = irr.add(direct::all_irradiance(view, scratch, &a.at, a.patch, area_samples, a.strata)?);
        }
        for (i, a, irr) in &arrived {
            let q = &wave[*i as usize];
            let shaded = a.finish(*irr, &mut spawned);
            let first = nodes.len() as u32;
            let count = shaded.spawned as u32;
            nodes[q.node as usize] = Node { local: shaded.local, join: shaded.join, first, count };
            for (k, &ray) in spawned[..shaded.spawned].iter().enumerate() {
                let node = nodes.len() as u32;
                nodes.push(Node { ..leaf });
                // The branch taken, one base-4 digit per generation.
                let path = q.path.wrapping_mul(4).wrapping_add(k as u64 + 1);
                next.push(Queued { node, path, ray, depth: q.depth + 1, exclude: shaded.patch, strata: None });
            }
        }
        arrived.clear();
        wave.clear();
        std::mem::swap(&mut wave, &mut next);
    }
    // Children come after their parents: from the last node back, each joins its own.
    let mut radiance = vec![Rgb::BLACK; nodes.len()];
    for (id, node) in nodes.iter().enumerate().rev() {
        let kids = node.first as usize..(node.first + node.count) as usize;
        let joined = node.join.radiance(node.local, &radiance[kids]);
        radiance[id] = joined;
    }
    let start = out.len();
    out.resize(start + order.len(), Rgb::BLACK);
    for (&(dx, dy), pixel) in order.iter().zip(radiance.chunks(n as usize)) {
        let sum = pixel.iter().fold(Rgb::BLACK, |s, &r| s.add(r));
        out[start + (dy * s.w + dx) as usize] = sum.scale(1.0 / n as f64);
    }
    Ok(())
}

/// Radiance arriving along `ray` (of recursion depth `depth`, leaving patch `exclude` or
/// the eye), its spawned rays followed depth first.
fn radiance(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    ray: &Ray,
    depth: u32,
    exclude: u32,
) -> Result<Rgb, BlockError> {
    let arrived = arrive_at(view, scratch, ray, depth, exclude)?;
    radiance_from(view, scratch, arrived, depth)
}

/// [`radiance`] once the ray has arrived.
fn radiance_from(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    arrived: Result<Arrived, Rgb>,
    depth: u32,
) -> Result<Rgb, BlockError> {
    let a = match arrived {
        Ok(a) => a,
        Err(whole) => return Ok(whole),
    };
    let mut irr = Rgb::BLACK;
    if a.shaded {
        irr = interpolated(view, scratch, &a)?;
    }
    if a.direct {
        let area_samples = view.header.plan.area_samples();
        irr = irr.add(direct::all_irradiance(view, scratch, &a.at, a.patch, area_samples, a.strata)?);
    }
    let mut spawned = [Ray::new(DVec3::ZERO, DVec3::Z); 3];
    let shaded = a.finish(irr, &mut spawned);
    let mut joined = [Rgb::BLACK; 3];
    for (r, ray) in joined.iter_mut().zip(&spawned[..shaded.spawned]) {
        *r = radiance(view, scratch, ray, depth + 1, shaded.patch)?;
    }
    Ok(shaded.join.radiance(shaded.local, &joined[..shaded.spawned]))
}

/// The Morton code of (x, y): their bits interleaved.
fn morton(x: u32, y: u32) -> u64 {
    let spread = |v: u32| {
        let mut v = v as u64;
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        (v | (v << 1)) & 0x5555_5555_5555_5555
    };
    spread(x) | (spread(y) << 1)
}

/// Buffers of [`lit_all`], kept across waves.
#[derive(Default)]
struct Lookups {
    points: Vec<ElementPoint>,
    leaves: Vec<LeafPoint>,
}

/// [`interpolated`] for the arrivals `order` names (`(element, index into arrived)`, in
/// the order of their elements), into each arrival's irradiance: the leaf elements under
/// all the hits a level of refinement at a time, then their vertex energies, each
/// stage's blocks fetched ahead in runs ([`SceneView::leaf_elements`],
/// [`SceneView::in_prefetched_runs`]). The same records, the same arithmetic.
fn lit_all(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    arrived: &mut [(u32, Arrived, Rgb)],
    order: &[(u32, u32)],
    lookups: &mut Lookups,
) -> Result<(), BlockError> {
    let Lookups { points, leaves } = lookups;
    points.clear();
    points.extend(order.iter().map(|&(element, i)| (element, arrived[i as usize].1.w)));
    leaves.clear();
    view.leaf_elements(points, leaves)?;
    let header = view.header.clone();
    let mut ctx = (arrived, scratch);
    view.in_prefetched_runs(
        &mut ctx,
        order.len(),
        |_, k| leaves[k].1.vertices.map(|v| vertex_block(&header, v)),
        |view, (arrived, scratch), k| {
            let (_, e, w) = &leaves[k];
            let (_, a, irr) = &mut arrived[order[k].1 as usize];
            *irr = lit(view, scratch, a, e, *w)?;
            Ok(())
        },
    )
}
