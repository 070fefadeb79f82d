//! Preparation by shares: the scene split in space among the forks, each fork preparing
//! its share side by side with the others (the paper's first conclusion: "preprocessing
//! should be executed in parallel ... 5 FPs should be used").
//!
//! The host numbers the patches and their elements in input order as it streams them
//! ([`SharePatch`]), so every id is the same whatever prepares it; the shares then weld
//! their lattice points, asking each point's home ([`space::SpaceSplit::share_of`]) where
//! points of several shares meet, number their vertices from the host's prefix sums, and
//! make their elements. A [`ShareSet`] runs the steps ([`steps::serve`]): every share in
//! this process ([`LocalShareSet`]), or each on the fork that holds it (magg-cluster).

mod set;
mod share;
mod space;
pub mod steps;
mod weld;
pub mod wire;

pub use set::{end, pack, subtrees, weld, LocalShareSet, ShareError, ShareSet};
pub use share::{IdQuery, PartialBlocks, PatchCounts, Share, SharePatch, ShareVertices};
pub use space::SpaceSplit;
pub use weld::{WeldAnswer, WeldPoint};

use glam::DVec3;
use magg_core::geometry::Aabb;
use magg_core::prepared::ElementInfo;

/// By default a share holds at least this many patches: a smaller scene is prepared as
/// one share (welding across shares and a tree over their BVHs cost more than they save
/// there).
pub const MIN_SHARE_PATCHES: usize = 65_536;

/// How a scene is split into shares: at most one per fork, each of at least
/// `min_patches` patches. Whatever the split, every id and every bit of the image are the
/// same; only who prepares what, and the BVH's shape, change.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shares {
    /// Forks that prepare the scene.
    pub forks: usize,
    /// Fewest patches of a share.
    pub min_patches: usize,
}

impl Default for Shares {
    /// The paper's five forks, shares of [`MIN_SHARE_PATCHES`].
    fn default() -> Self {
        Shares { forks: 5, min_patches: MIN_SHARE_PATCHES }
    }
}

impl Shares {
    /// Shares of a scene of `patches` patches.
    pub fn count(&self, patches: usize) -> usize {
        self.forks.clamp(1, patches.div_ceil(self.min_patches.max(1)).max(1))
    }
}

/// The host's prefix sums over every share's [`PatchCounts`]: each patch's (front base,
/// back base), per share in the order its counts came; the number of front vertices and
/// of all vertices.
pub fn vertex_bases(counts: &[Vec<PatchCounts>]) -> (Vec<Vec<(u32, u32)>>, u32, u32) {
    let mut all: Vec<(u32, u32, u32, usize, usize)> = counts
        .iter()
        .enumerate()
        .flat_map(|(s, c)| c.iter().enumerate().map(move |(k, &(p, roots, backs))| (p, roots, backs, s, k)))
        .collect();
    all.sort_unstable_by_key(|c| c.0);
    let fronts: u64 = all.iter().map(|c| c.1 as u64).sum();
    let backs: u64 = all.iter().map(|c| c.2 as u64).sum();
    let mut bases: Vec<Vec<(u32, u32)>> = counts.iter().map(|c| vec![(0, 0); c.len()]).collect();
    let (mut front, mut back) = (0u64, fronts);
    for (_, roots, b, s, k) in all {
        bases[s][k] = (front as u32, back as u32);
        front += roots as u64;
        back += b as u64;
    }
    (bases, fronts as u32, (fronts + backs) as u32)
}

/// Splits `patches` (every patch of the scene, ascending ids) among `shares` shares by
/// the positions of their centroids, weighted by their elements.
pub fn split_space(patches: &[SharePatch], shares: usize) -> SpaceSplit {
    if shares <= 1 {
        return SpaceSplit::single();
    }
    let bounds = patches.iter().fold(Aabb::EMPTY, |b, p| b.union(Aabb::of_triangle(&p.v)));
    SpaceSplit::balanced(bounds, shares, patches.iter().map(|p| (centroid(p), (p.n as f64).powi(2))))
}

/// Where a patch is for the split: its centroid.
pub fn centroid(p: &SharePatch) -> DVec3 {
    (p.v[0] + p.v[1] + p.v[2]) / 3.0
}

/// `out[from][to]` turned into `in[to]`, the lists of each sender in sender order.
pub(crate) fn deliver<T>(out: Vec<Vec<Vec<T>>>, shares: usize) -> Vec<Vec<Vec<T>>> {
    let mut inbox: Vec<Vec<Vec<T>>> = (0..shares).map(|_| Vec::with_capacity(out.len())).collect();
    for lists in out {
        for (to, list) in lists.into_iter().enumerate() {
            inbox[to].push(list);
        }
    }
    inbox
}

/// What an element id no share made would hold (none is left so: every id is made by the
/// share of its patch).
pub(crate) const UNMADE: ElementInfo = ElementInfo {
    patch: u32::MAX,
    vertices: [u32::MAX; 3],
    area: 0.0,
    centroid: DVec3::ZERO,
    face: magg_core::prepared::Face::Both,
    parent: magg_core::prepared::NO_PARENT,
    child: 0,
};

/// `patches` (every patch of the scene, ascending ids) dealt to the shares of `split` by
/// their centroids.
pub fn by_share(patches: Vec<SharePatch>, split: &SpaceSplit) -> Vec<Vec<SharePatch>> {
    let mut by_share: Vec<Vec<SharePatch>> = vec![Vec::new(); split.shares()];
    for p in patches {
        by_share[split.share_of(centroid(&p)) as usize].push(p);
    }
    by_share
}

#[cfg(test)]
mod oracle;
#[cfg(test)]
mod tests;
