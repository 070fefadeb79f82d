//! What a ray cast asks and answers, shared by both acceleration structures: the
//! checked query with its watertight ray and the rule that keeps the nearest hit (ties
//! to the lower patch id), the hit, and the scratch buffers reused from ray to ray.

use crate::geometry::{Ray, TriHit, WatertightRay};
use glam::DVec3;

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
    pub(super) ids: Vec<u32>,
    /// BVH traversal stack: (node index or triangle address, leaf count, entry distance).
    pub(super) stack: Vec<(u32, u32, f64)>,
    /// The packet walk's stack: (node index or triangle address, leaf count, nearest
    /// entry distance, rays as a bit mask).
    pub(super) packet_stack: Vec<(u32, u32, f32, u32)>,
    /// [`super::occluded_all`]'s answers before they become booleans.
    pub(super) hits: Vec<Option<Hit>>,
    recent: [u32; 16],
    recent_len: usize,
    recent_pos: usize,
}

impl TraceScratch {
    pub(super) fn reset(&mut self) {
        self.recent_len = 0;
        self.recent_pos = 0;
    }
    pub(super) fn seen(&mut self, id: u32) -> bool {
        if self.recent[..self.recent_len].contains(&id) {
            return true;
        }
        self.recent[self.recent_pos] = id;
        self.recent_pos = (self.recent_pos + 1) % self.recent.len();
        self.recent_len = (self.recent_len + 1).min(self.recent.len());
        false
    }
}

/// A query of [`super::cast`], checked (finite origin and direction, no NaN bound): what both
/// kernels answer.
#[derive(Clone, Copy)]
pub(super) struct Query<'a> {
    pub(super) ray: &'a Ray,
    pub(super) wray: WatertightRay,
    pub(super) tmin: f64,
    pub(super) tmax: f64,
    pub(super) exclude: u32,
    pub(super) any: bool,
}

impl<'a> Query<'a> {
    /// The query of [`super::cast`], `None` for one that hits nothing: a non-finite origin or
    /// direction, a zero direction, a NaN bound.
    #[inline]
    pub(super) fn new(ray: &'a Ray, tmin: f64, tmax: f64, exclude: u32, any: bool) -> Option<Query<'a>> {
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
    pub(super) fn test(&self, v: &[DVec3; 3], pid: u32, limit: f64, best: &mut Option<Hit>) -> bool {
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
    pub(super) fn test_record(&self, record: &[u8; 72], pid: u32, upper: f64, best: &mut Option<Hit>) -> bool {
        let hit = self.wray.intersect_record(record, self.tmin, upper);
        Self::keep(hit, pid, best)
    }

    /// Keeps `hit` of patch `pid` when it is nearer than `best`, or as near with a lower id.
    #[inline(always)]
    pub(super) fn keep(hit: Option<TriHit>, pid: u32, best: &mut Option<Hit>) -> bool {
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
