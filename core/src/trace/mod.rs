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

use crate::blocks::BlockError;
use crate::geometry::{Ray, TriHit, WatertightRay};
use crate::scene::Accel;
use crate::view::SceneView;
use glam::DVec3;

/// Marks "exclude no patch".
pub const NO_PATCH: u32 = u32::MAX;

/// The nearest patch a ray hits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray (unit direction).
    pub t: f64,
    /// Patch id.
    pub patch: u32,
    /// Barycentric weights of the patch corners.
    pub bary: [f64; 3],
}

/// Scratch buffers reused across rays.
#[derive(Default)]
pub struct TraceScratch {
    ids: Vec<u32>,
    /// BVH traversal stack: (node index or triangle address, leaf count, entry distance).
    stack: Vec<(u32, u32, f64)>,
    /// The packet walk's stack: (node index or triangle address, leaf count, nearest
    /// entry distance, rays as a bit mask).
    packet_stack: Vec<(u32, u32, f32, u32)>,
    /// [`occluded_all`]'s answers before they become booleans.
    hits: Vec<Option<Hit>>,
    recent: [u32; 16],
    recent_len: usize,
    recent_pos: usize,
}

impl TraceScratch {
    fn reset(&mut self) {
        self.recent_len = 0;
        self.recent_pos = 0;
    }
    fn seen(&mut self, id: u32) -> bool {
        if self.recent[..self.recent_len].contains(&id) {
            return true;
        }
        self.recent[self.recent_pos] = id;
        self.recent_pos = (self.recent_pos + 1) % self.recent.len();
        self.recent_len = (self.recent_len + 1).min(self.recent.len());
        false
    }
}

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

/// A query of [`cast`], checked (finite origin and direction, no NaN bound): what both
/// kernels answer.
#[derive(Clone, Copy)]
struct Query<'a> {
    ray: &'a Ray,
    wray: WatertightRay,
    tmin: f64,
    tmax: f64,
    exclude: u32,
    any: bool,
}

impl<'a> Query<'a> {
    /// The query of [`cast`], `None` for one that hits nothing: a non-finite origin or
    /// direction, a zero direction, a NaN bound.
    #[inline]
    fn new(ray: &'a Ray, tmin: f64, tmax: f64, exclude: u32, any: bool) -> Option<Query<'a>> {
        let (o, d) = (ray.origin, ray.direction);
        if !o.is_finite() || !d.is_finite() || d.length_squared() == 0.0 || tmin.is_nan() || tmax.is_nan() {
            return None;
        }
        // The per-ray part of the watertight test, once (a finite, non-zero direction has one).
        let wray = WatertightRay::new(ray)?;
        Some(Query { ray, wray, tmin, tmax, exclude, any })
    }

    /// Tests patch `pid` (corners `v`) against the best hit so far, or against `limit`
    /// when there is none; keeps it when nearer, or as near with a lower id. Returns
    /// whether it was kept.
    #[inline]
    fn test(&self, v: &[DVec3; 3], pid: u32, limit: f64, best: &mut Option<Hit>) -> bool {
        let bound = best.map_or(limit, |b| b.t);
        // Allow equal distance so that ties can go to the lower id.
        let hit = self.wray.intersect(v, self.tmin, bound.next_up_or(bound));
        Self::keep(hit, pid, best)
    }

    /// [`Query::test`] on corners read in place from a record's first 72 bytes (see
    /// [`WatertightRay::intersect_record`]), against `upper`: the bound's
    /// [`NextUp::next_up_or`] (hits below it, so at the bound too, for ties), which the
    /// caller renews when the best hit changes. The same bits as [`Query::test`].
    #[inline(always)]
    fn test_record(&self, record: &[u8; 72], pid: u32, upper: f64, best: &mut Option<Hit>) -> bool {
        let hit = self.wray.intersect_record(record, self.tmin, upper);
        Self::keep(hit, pid, best)
    }

    /// Keeps `hit` of patch `pid` when it is nearer than `best`, or as near with a lower id.
    #[inline(always)]
    fn keep(hit: Option<TriHit>, pid: u32, best: &mut Option<Hit>) -> bool {
        let Some(h) = hit else {
            return false;
        };
        let better = match best {
            None => true,
            Some(b) => h.t < b.t || (h.t == b.t && pid < b.patch),
        };
        if better {
            *best = Some(Hit { t: h.t, patch: pid, bary: h.bary });
        }
        better
    }
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

/// `next_up` for finite values; infinities stay.
pub(crate) trait NextUp {
    fn next_up_or(self, fallback: f64) -> f64;
}
impl NextUp for f64 {
    fn next_up_or(self, fallback: f64) -> f64 {
        if self.is_finite() {
            let bits = self.to_bits();
            let up = if self > 0.0 {
                f64::from_bits(bits + 1)
            } else if self == 0.0 {
                f64::from_bits(1)
            } else {
                f64::from_bits(bits - 1)
            };
            up
        } else {
            fallback
        }
    }
}
