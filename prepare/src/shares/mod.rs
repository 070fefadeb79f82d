//! Preparation by shares: the scene split in space among the forks, each fork preparing
//! its share side by side with the others (the paper's first conclusion: "preprocessing
//! should be executed in parallel ... 5 FPs should be used").
//!
//! The host numbers the patches and their elements in input order as it streams them
//! ([`SharePatch`]), so every id is the same whatever prepares it; the shares then weld
//! their lattice points, asking each point's home ([`space::SpaceSplit::share_of`]) where
//! points of several shares meet, number their vertices from the host's prefix sums, and
//! make their elements. [`weld_in_shares`] runs the steps with every share in this
//! process; a cluster runs the same [`Share`] steps on its forks.

mod share;
mod space;
mod weld;

pub use share::{IdQuery, PartialBlocks, PatchCounts, Share, SharePatch, ShareVertices};
pub use space::SpaceSplit;
pub use weld::{WeldAnswer, WeldPoint};

use glam::DVec3;
use magg_core::geometry::Aabb;
use magg_core::prepared::ElementInfo;
use rayon::prelude::*;

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
fn deliver<T>(out: Vec<Vec<Vec<T>>>, shares: usize) -> Vec<Vec<Vec<T>>> {
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
const UNMADE: ElementInfo = ElementInfo {
    patch: u32::MAX,
    vertices: [u32::MAX; 3],
    area: 0.0,
    centroid: DVec3::ZERO,
    face: magg_core::prepared::Face::Both,
    parent: magg_core::prepared::NO_PARENT,
    child: 0,
};

/// The shares of a scene, all in this process: the steps of [`Share`] run side by side
/// (rayon), the messages between them moved by [`deliver`].
pub struct LocalShares {
    split: SpaceSplit,
    shares: Vec<Share>,
}

impl LocalShares {
    /// `patches` (every patch of the scene, ascending ids) given to the shares of
    /// `split` by their centroids.
    pub fn new(patches: Vec<SharePatch>, split: SpaceSplit) -> LocalShares {
        let n = split.shares();
        let mut by_share: Vec<Vec<SharePatch>> = vec![Vec::new(); n];
        for p in patches {
            by_share[split.share_of(centroid(&p)) as usize].push(p);
        }
        let shares = by_share.into_iter().enumerate().map(|(i, p)| Share::new(i as u32, p)).collect();
        LocalShares { split, shares }
    }

    /// Welds every share's lattice points and makes its elements (steps 1 to 6): every
    /// element (`elements` of them) and welded vertex, by id.
    pub fn weld(&mut self, elements: usize) -> (Vec<ElementInfo>, Vec<DVec3>) {
        let n = self.shares.len();
        let split = &self.split;
        let points = deliver(self.shares.par_iter_mut().map(|s| s.lattice(split)).collect(), n);
        let answers: Vec<Vec<Vec<WeldAnswer>>> = self
            .shares
            .par_iter_mut()
            .zip(points)
            .map(|(s, got)| s.resolve(n, got.into_iter().flatten().collect()))
            .collect();
        let answers = deliver(answers, n);
        let counts: Vec<Vec<PatchCounts>> =
            self.shares.par_iter_mut().zip(answers).map(|(s, a)| s.settle(a.into_iter().flatten())).collect();
        let (bases, _, vertices) = vertex_bases(&counts);
        let asks = deliver(self.shares.par_iter_mut().zip(bases).map(|(s, b)| s.number(n, &b)).collect(), n);
        // asks[owner][asker]: answered by the owner, delivered back to the asker.
        let replies: Vec<Vec<Vec<u32>>> =
            self.shares.par_iter().zip(&asks).map(|(s, per)| per.iter().map(|q| s.answer(q)).collect()).collect();
        let replies = deliver(replies, n);
        let made: Vec<ShareVertices> = self.shares.par_iter_mut().zip(replies).map(|(s, r)| s.elements(r)).collect();
        let mut out_elements = vec![UNMADE; elements];
        let mut out_vertices = vec![DVec3::ZERO; vertices as usize];
        for (share, vertices) in self.shares.iter().zip(made) {
            for (id, info) in share.made() {
                if let Some(slot) = out_elements.get_mut(id as usize) {
                    *slot = *info;
                }
            }
            for (id, at) in vertices {
                if let Some(slot) = out_vertices.get_mut(id as usize) {
                    *slot = at;
                }
            }
        }
        (out_elements, out_vertices)
    }

    /// Each share's BVH, built side by side, every box padded by `pad`.
    pub fn subtrees(&self, pad: f64) -> Vec<crate::bvh::SubTree> {
        self.shares
            .par_iter()
            .map(|s| {
                let corners: Vec<(u32, [DVec3; 3])> = s.patches().iter().map(|p| (p.id, p.v)).collect();
                crate::bvh::build_subtree(&corners, pad)
            })
            .collect()
    }

    /// Every share's records written where `layout` puts them.
    pub fn pack(&self, layout: &magg_core::blocks::BlockLayout) -> Vec<share::PartialBlocks> {
        self.shares.par_iter().map(|s| s.pack(layout)).collect()
    }
}

#[cfg(test)]
mod oracle;
#[cfg(test)]
mod tests;
