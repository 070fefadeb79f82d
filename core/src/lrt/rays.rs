//! Who a secondary light ray is: how it left the surface that spawned it, and its place
//! in its pair's ray trees, which seeds its random choices.

use crate::rng::Rng;

/// How a secondary light ray left a surface: rays that took the same branches travel
/// together ([`super::waves`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Branch {
    Mirror = 1,
    Reflected = 2,
    Refracted = 3,
    Diffuse = 4,
}

/// Who a light ray is within its pair: the pair's seed, and the ray's place in the
/// pair's ray trees (its primary ray, then the rays spawned on the way). A ray's random
/// choices (the direction of a diffuse bounce off a secondary hit) are drawn from it,
/// so they do not depend on the order in which the pair's rays are traced.
/// (Its path is hashed only when it is wanted: most rays spawn nothing and draw
/// nothing.)
#[derive(Clone, Copy, Debug)]
pub(super) struct RayId {
    pair: u64,
    /// The path of the ray that spawned it (the primary ray's index for a primary
    /// ray), and its place among the rays spawned there.
    parent: u64,
    j: u64,
}

impl RayId {
    /// The `k`-th primary ray of the pair (`light`, `element`) under scene seed `seed`.
    pub(super) fn primary(seed: u64, light: u32, element: u32, k: u32) -> RayId {
        let pair = crate::rng::seed_of(&[seed, 0x424f554e, light as u64, element as u64]);
        RayId { pair, parent: k as u64, j: u64::MAX }
    }

    /// Its path: a hash of its place in the pair's trees.
    pub(super) fn path(self) -> u64 {
        crate::rng::seed_of(&[self.parent, self.j])
    }

    /// The `j`-th ray spawned by the ray of path `path` (of this pair).
    pub(super) fn child(self, path: u64, j: usize) -> RayId {
        RayId { pair: self.pair, parent: path, j: j as u64 }
    }

    /// Its generator.
    pub(super) fn rng(self) -> Rng {
        Rng::from_words(&[self.pair, self.path()])
    }
}
