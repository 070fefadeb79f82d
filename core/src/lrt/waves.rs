//! A pair's secondary light rays traced a generation at a time (a wave), the rays of
//! one kind of path side by side, their deposits handed on in the depth-first order of
//! the pair's ray trees.
//!
//! Why waves: a pair's rays all leave one light towards one element, so the rays that
//! took the same branches (reflected off the target, refracted into it and out again,
//! ...) travel together and read the same blocks: BVH nodes, leaf triangles, patch,
//! shading and element records. Traced one primary ray's tree after another (depth
//! first), a pair cycles through every branch's blocks once per primary ray; when they
//! add up to more than a bounded node cache holds, LRU evicts each block just before it
//! is wanted again and nearly every read misses. Traced a generation at a time, sorted
//! by the branches taken, the rays of one branch read their blocks back to back.
//!
//! What the pair deposits is unchanged: each ray's tree is kept (a node per ray, its
//! children in the order they were spawned), and the deposits come out in the order the
//! depth-first stack made them (pre-order, the last child spawned first),
//! so the merged sums see the same terms in the same order, bit for bit. Random choices
//! (a diffuse bounce off a secondary hit) draw from the pair's generator in wave order:
//! deterministic, but not the depth-first draws of before.

use super::{follow_one, LrtTally, Pending, RawDeposit};
use crate::blocks::BlockError;
use crate::rng::Rng;
use crate::trace::TraceScratch;
use crate::view::SceneView;

/// One ray of a pair's trees.
struct Node {
    /// What the ray deposited where it arrived, if anything.
    deposit: Option<RawDeposit>,
    /// Its children: node ids `first..first + count`, in the order they were spawned.
    first: u32,
    count: u32,
}

/// A ray waiting for its wave: its node, the branches its path took (rays of equal
/// `path` are traced side by side), and the ray.
struct Queued {
    node: u32,
    path: u64,
    ray: Pending,
}

/// The ray trees of one pair. Each primary ray is added as a root ([`PairTrees::root`],
/// in the pair's ray order) after it spawned its secondary rays into
/// [`PairTrees::spawned`]; then [`PairTrees::trace`] follows every secondary ray, a
/// generation at a time, and returns the deposits in depth-first order.
#[derive(Default)]
pub(super) struct PairTrees {
    nodes: Vec<Node>,
    roots: Vec<u32>,
    /// The next generation's rays.
    wave: Vec<Queued>,
    /// Secondary rays spawned by the ray just traced (`scatter` pushes here).
    pub spawned: Vec<Pending>,
}

impl PairTrees {
    /// Adds a primary ray that deposited `deposit` (if any) and spawned the rays now in
    /// [`PairTrees::spawned`].
    pub fn root(&mut self, deposit: Option<RawDeposit>) {
        let id = self.node(deposit);
        self.roots.push(id);
        self.adopt(id, 0);
    }

    fn node(&mut self, deposit: Option<RawDeposit>) -> u32 {
        self.nodes.push(Node { deposit, first: 0, count: 0 });
        self.nodes.len() as u32 - 1
    }

    /// Makes the rays in [`PairTrees::spawned`] the children of node `parent`, whose
    /// path is `path`, and queues them for the next wave.
    fn adopt(&mut self, parent: u32, path: u64) {
        let first = self.nodes.len() as u32;
        let node = &mut self.nodes[parent as usize];
        (node.first, node.count) = (first, self.spawned.len() as u32);
        let mut spawned = std::mem::take(&mut self.spawned);
        for (k, ray) in spawned.drain(..).enumerate() {
            let node = self.node(None);
            // The branch taken, one octal digit per generation (children past the
            // eighth, a primary ray's diffuse bounces, go every which way: they share
            // a digit).
            let path = path.wrapping_mul(8).wrapping_add(k.min(7) as u64);
            self.wave.push(Queued { node, path, ray });
        }
        self.spawned = spawned;
    }

    /// Follows every secondary ray, a generation at a time (rays of one path together,
    /// in the pair's ray order among them), then returns every deposit, the primary
    /// rays' included, raw, in depth-first order.
    pub fn trace(
        mut self,
        view: &mut SceneView,
        scratch: &mut TraceScratch,
        rng: &mut Rng,
        tally: &mut LrtTally,
    ) -> Result<Vec<RawDeposit>, BlockError> {
        while !self.wave.is_empty() {
            let mut wave = std::mem::take(&mut self.wave);
            // Node ids grow with the primary ray: ties keep the pair's ray order.
            wave.sort_unstable_by_key(|q| (q.path, q.node));
            for q in wave {
                let deposit = follow_one(view, scratch, rng, &mut self.spawned, tally, q.ray)?;
                self.nodes[q.node as usize].deposit = deposit;
                self.adopt(q.node, q.path);
            }
        }
        // Depth first, as a stack of the rays to follow would visit them.
        let mut deposits = Vec::new();
        let mut stack: Vec<u32> = self.roots.iter().rev().copied().collect();
        while let Some(id) = stack.pop() {
            let node = &self.nodes[id as usize];
            deposits.extend(node.deposit);
            stack.extend(node.first..node.first + node.count);
        }
        Ok(deposits)
    }
}
