//! Ray casting: the nearest patch along a ray, through the scene's acceleration
//! structure ([`crate::scene::Accel`]): the uniform grid of subspaces ([`grid`]) or the
//! BVH ([`bvh`]), both read through the node's block cache.
//!
//! Both give the same answer, bit for bit: among the patches other than `exclude`
//! whose watertight test (`geometry::intersect_watertight`) hits with `tmin < t <= tmax`,
//! the nearest, ties in distance to the lower patch id (so a ray through an edge shared
//! by two patches hits exactly one of them). Only the `any` queries (occlusion) may
//! stop at another hit: they answer whether there is one.

mod bvh;
mod grid;
mod query;

use query::Query;
pub use query::{Hit, TraceScratch};

use crate::blocks::BlockError;
use crate::geometry::Ray;
use crate::scene::Accel;
use crate::view::SceneView;

/// Marks "exclude no patch".
pub const NO_PATCH: u32 = u32::MAX;

/// Nearest hit of `ray` with `tmin < t <= tmax`, skipping patch `exclude`. With `any`,
/// the first hit found is returned (shadow rays). Non-finite or zero directions hit
/// nothing.
pub fn cast(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    ray: &Ray,
    tmin: f64,
    tmax: f64,
    exclude: u32,
    any: bool,
) -> Result<Option<Hit>, BlockError> {
    let Some(q) = Query::new(ray, tmin, tmax, exclude, any) else {
        return Ok(None);
    };
    match view.header.settings.accel {
        Accel::Bvh => bvh::cast(view, scratch, &q),
        Accel::Grid => grid::cast(view, scratch, &q),
    }
}

/// One ray of [`cast_all`] or [`occluded_all`]: what [`cast`] takes besides the view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bundled {
    /// The ray.
    pub ray: Ray,
    /// Hits count from beyond this distance...
    pub tmin: f64,
    /// ...up to this one.
    pub tmax: f64,
    /// A patch to skip ([`NO_PATCH`] for none).
    pub exclude: u32,
}

/// [`cast`] (nearest hit) of each of `rays`, in order, into `out` (replaced): the same
/// hits, bit for bit. Consecutive rays from one origin (a pinhole camera's, a point
/// light's) walk the BVH together, up to [`PACKET`] at a time, where their directions
/// allow (see `bvh/packet.rs`): a node is read and tested once for all of them.
pub fn cast_all(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    rays: &[Bundled],
    out: &mut Vec<Option<Hit>>,
) -> Result<(), BlockError> {
    out.clear();
    out.resize(rays.len(), None);
    in_packets(view, scratch, rays, false, out)
}

/// [`occluded`] of each of `rays`, in order, into `out` (replaced): the same answers,
/// rays from one origin walking the BVH together as in [`cast_all`].
pub fn occluded_all(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    rays: &[Bundled],
    out: &mut Vec<bool>,
) -> Result<(), BlockError> {
    let mut hits = std::mem::take(&mut scratch.hits);
    hits.clear();
    hits.resize(rays.len(), None);
    let done = in_packets(view, scratch, rays, true, &mut hits);
    out.clear();
    out.extend(hits.iter().map(Option::is_some));
    scratch.hits = hits;
    done
}

/// The most rays walked together by [`cast_all`] and [`occluded_all`].
pub const PACKET: usize = bvh::PACKET;

/// Answers `rays` into `out` (as long, every answer `None`), runs of one origin as
/// packets through the BVH.
fn in_packets(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    rays: &[Bundled],
    any: bool,
    out: &mut [Option<Hit>],
) -> Result<(), BlockError> {
    if !bvh::packs(view) {
        // The grid, or a BVH too small for packets to pay: one ray at a time.
        for (b, o) in rays.iter().zip(out.iter_mut()) {
            *o = cast(view, scratch, &b.ray, b.tmin, b.tmax, b.exclude, any)?;
        }
        return Ok(());
    }
    let mut i = 0;
    while i < rays.len() {
        let origin = rays[i].ray.origin;
        let mut j = i + 1;
        while j < rays.len() && j - i < PACKET && rays[j].ray.origin == origin {
            j += 1;
        }
        if j == i + 1 {
            // A ray alone (a secondary ray of a wave): cast as such, without filling a
            // packet's arrays.
            let b = &rays[i];
            out[i] = cast(view, scratch, &b.ray, b.tmin, b.tmax, b.exclude, any)?;
            i = j;
            continue;
        }
        // The run's valid queries (the others hit nothing, as in `cast`: `out` holds
        // `None` for them), side by side; the first stands in for the unused places.
        let mut valid = (i..j).filter_map(|k| {
            let b = &rays[k];
            Query::new(&b.ray, b.tmin, b.tmax, b.exclude, any).map(|q| (k, q))
        });
        if let Some((k0, q0)) = valid.next() {
            let (mut queries, mut at, mut n) = ([q0; PACKET], [k0; PACKET], 1);
            for (k, q) in valid {
                (queries[n], at[n]) = (q, k);
                n += 1;
            }
            let mut hits = [None; PACKET];
            bvh::cast_packet(view, scratch, &queries[..n], &mut hits[..n])?;
            for (&k, hit) in at[..n].iter().zip(hits) {
                out[k] = hit;
            }
        }
        i = j;
    }
    Ok(())
}

/// Whether anything other than patch `exclude` lies along `ray` with `tmin < t <= tmax`
/// (the light ray towards its target element, stopped short of it).
pub fn occluded(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    ray: &Ray,
    tmin: f64,
    tmax: f64,
    exclude: u32,
) -> Result<bool, BlockError> {
    Ok(cast(view, scratch, ray, tmin, tmax, exclude, true)?.is_some())
}
