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
//! (a diffuse bounce off a secondary hit) are drawn from the ray's own generator (its
//! place in the trees), whatever the order. So a pair deposits the same bits traced in
//! waves (through a bounded cache) or depth first (every block resident, where waves
//! would only add bookkeeping).

use super::landing::{follow_one, Pending};
use super::result::{LrtTally, RawDeposit};
use crate::blocks::BlockError;
use crate::trace::TraceScratch;
use crate::view::SceneView;

/// Marks a node that deposited nothing.
const NONE: u32 = u32::MAX;

/// One ray of a pair's trees.
#[derive(Clone, Copy)]
struct Node {
    /// Index of what the ray deposited where it arrived in `PairTrees::deposits`, or
    /// [`NONE`].
    deposit: u32,
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

/// The ray trees of a pair. Each primary ray is added as a root ([`PairTrees::root`],
/// in the pair's ray order) after it spawned its secondary rays into
/// [`PairTrees::spawned`]; then [`PairTrees::trace`] follows every secondary ray, a
/// generation at a time, and hands on the deposits in depth-first order. With every
/// block resident (no cache to keep rays together for), a root's tree is instead
/// followed depth first at once, with no bookkeeping: the same deposits in the same
/// order. One value serves pair after pair (its buffers are kept).
#[derive(Default)]
pub(super) struct PairTrees {
    /// Trace in waves (else depth first, each root's tree at once).
    waves: bool,
    nodes: Vec<Node>,
    roots: Vec<u32>,
    /// The deposits, in the order they were made.
    deposits: Vec<RawDeposit>,
    /// The next generation's rays, and the buffers of the one being traced.
    wave: Vec<Queued>,
    spare: Vec<Queued>,
    order: Vec<(u64, u32)>,
    stack: Vec<u32>,
    /// Secondary rays spawned by the ray just traced (`scatter` pushes here).
    pub spawned: Vec<Pending>,
    /// A pair's light rays (ray number, flux, distance to the element's plane), their
    /// occlusion queries and the answers: buffers kept from pair to pair.
    pub shots: Vec<(u32, crate::color::Rgb, f64)>,
    pub bundle: Vec<crate::trace::Bundled>,
    pub occluded: Vec<bool>,
}

impl PairTrees {
    /// Forgets the last pair's trees; the next pair's go in waves, or depth first.
    pub fn clear(&mut self, waves: bool) {
        self.waves = waves;
        self.nodes.clear();
        self.roots.clear();
        self.deposits.clear();
        self.wave.clear();
        self.spawned.clear();
    }

    /// Adds a primary ray that deposited `deposit` (if any) and spawned the rays now in
    /// [`PairTrees::spawned`]. Depth first, its tree is followed now: its deposits go to
    /// `out`.
    pub fn root(
        &mut self,
        view: &mut SceneView,
        scratch: &mut TraceScratch,
        tally: &mut LrtTally,
        deposit: Option<RawDeposit>,
        out: &mut Vec<RawDeposit>,
    ) -> Result<(), BlockError> {
        if !self.waves {
            out.extend(deposit);
            // The spawned rays are the stack: the last spawned first, its own spawned
            // rays on top of its siblings.
            while let Some(s) = self.spawned.pop() {
                out.extend(follow_one(view, scratch, &mut self.spawned, tally, &s)?);
            }
            return Ok(());
        }
        let id = self.node(deposit);
        self.roots.push(id);
        self.adopt(id, 0);
        Ok(())
    }

    fn node(&mut self, deposit: Option<RawDeposit>) -> u32 {
        let deposit = match deposit {
            Some(d) => {
                self.deposits.push(d);
                self.deposits.len() as u32 - 1
            }
            None => NONE,
        };
        self.nodes.push(Node { deposit, first: 0, count: 0 });
        self.nodes.len() as u32 - 1
    }

    /// Makes the rays in [`PairTrees::spawned`] the children of node `parent`, whose
    /// path is `path`, and queues them for the next wave.
    fn adopt(&mut self, parent: u32, path: u64) {
        let (first, count) = (self.nodes.len() as u32, self.spawned.len() as u32);
        let node = &mut self.nodes[parent as usize];
        (node.first, node.count) = (first, count);
        let blank = Node { deposit: NONE, first: 0, count: 0 };
        self.nodes.extend(std::iter::repeat_n(blank, count as usize));
        for (k, ray) in self.spawned.drain(..).enumerate() {
            // The branch taken, one octal digit per generation.
            let path = path.wrapping_mul(8).wrapping_add(ray.branch as u64);
            self.wave.push(Queued { node: first + k as u32, path, ray });
        }
    }

    /// Follows every secondary ray, a generation at a time (rays of one path together,
    /// in the pair's ray order among them), then appends every deposit, the primary
    /// rays' included, raw, to `out` in depth-first order.
    pub fn trace(
        &mut self,
        view: &mut SceneView,
        scratch: &mut TraceScratch,
        tally: &mut LrtTally,
        out: &mut Vec<RawDeposit>,
    ) -> Result<(), BlockError> {
        while !self.wave.is_empty() {
            let spare = std::mem::take(&mut self.spare);
            let wave = std::mem::replace(&mut self.wave, spare);
            // Sorted by path, then by place in the wave (node ids grow with the primary
            // ray: ties keep the pair's ray order); the rays stay where they are.
            let mut order = std::mem::take(&mut self.order);
            order.clear();
            order.extend(wave.iter().enumerate().map(|(i, q)| (q.path, i as u32)));
            if !order.is_sorted() {
                order.sort_unstable();
            }
            for &(_, i) in &order {
                let q = &wave[i as usize];
                let deposit = follow_one(view, scratch, &mut self.spawned, tally, &q.ray)?;
                if let Some(d) = deposit {
                    self.deposits.push(d);
                    self.nodes[q.node as usize].deposit = self.deposits.len() as u32 - 1;
                }
                self.adopt(q.node, q.path);
            }
            self.order = order;
            self.spare = wave;
            self.spare.clear();
        }
        // Depth first, as a stack of the rays to follow would visit them.
        let stack = &mut self.stack;
        stack.clear();
        stack.extend(self.roots.iter().rev());
        while let Some(id) = stack.pop() {
            let node = self.nodes[id as usize];
            if node.deposit != NONE {
                out.push(self.deposits[node.deposit as usize]);
            }
            stack.extend(node.first..node.first + node.count);
        }
        Ok(())
    }
}
